//! Cases for `firmware::dither`: the DDS codes, the half-cycle fit, and the whole controller
//! from a cold start into lock against a small envelope model (f32 basic operations only, so
//! the model itself is bit-identical on both sides). The simulator runs the controller on x86
//! and the board on the Cortex-M4F: these cases show they compute the same drive.
use super::{Outputs, Rng};
use firmware::dither::{cos_sin_q31, DitherConfig, DitherController, DitherState, Drive, Window};
use firmware::profile::BoardProfile;
use firmware::units::Phase;

/// `Drive::dac_code` (idsp::cossin, the Q16 amplitude, rounding and clamping) on random drives.
pub fn dds(out: &mut Outputs) {
    let mut rng = Rng::new(0x5eed_0040);
    for _ in 0..200 {
        let drive = Drive {
            start_tick: rng.u32(),
            phase: Phase::from_bits(rng.u32()),
            step: Phase::from_bits(rng.u32() >> 6),
            amplitude_q16: rng.u32() >> 4,
            mid_code: 2048,
            full_scale: 4095,
        };
        for _ in 0..10 {
            out.u32(drive.dac_code(rng.u32() >> 16) as u32);
        }
    }
}

/// The half-cycle fit (exact integer sums, the f32 solve, libm's sqrtf, idsp::atan2) on random
/// windows.
pub fn half_cycle_fit(out: &mut Outputs) {
    let mut rng = Rng::new(0x5eed_0041);
    for _ in 0..200 {
        let mut w = Window::new();
        let step = rng.i32_in(20_000_000, 70_000_000) as u32;
        let mut phase = Phase::from_bits(rng.u32());
        let amp = rng.f32_in(0.0, 1800.0);
        let lag = Phase::from_bits(rng.u32());
        for _ in 0..rng.i32_in(4, 80) {
            let (c, s) = cos_sin_q31(phase);
            let (pc, _) = cos_sin_q31(phase + lag);
            let x = (amp * (pc as f32 / 2_147_483_648.0)) as i32 + rng.i32_in(-3, 3);
            let code = (2048 + x).clamp(0, 4095) as u16;
            w.push(code, code as i32 - 2048, c >> 16, s >> 16, 4095);
            phase = phase + Phase::from_bits(step);
        }
        let h = w.close();
        out.u32(h.min_code as u32);
        out.u32(h.max_code as u32);
        out.u32(h.rail_samples);
        out.bool(h.fit.is_some());
        if let Some(f) = h.fit {
            out.f32(f.amplitude_codes);
            out.u32(f.phase.to_bits());
            out.f32(f.offset_codes);
        }
    }
}

/// The controller for 1.2 s of ticks from a cold start: the pick-off of an envelope model,
/// 90 degrees behind the drive; every DAC code, every drive change and half-cycle estimate (it
/// locks after 0.85 s).
pub fn controller(out: &mut Outputs) {
    let config = DitherConfig::for_profile(&BoardProfile::F405);
    let mut ctrl = DitherController::new(&config);
    ctrl.enable();
    let limit = config.amplitude.drive_limit_codes();
    let (decay, gain) = (1.0 - 1.0 / (0.818 * 40_000.0), 4125.0 / limit / 40_000.0);
    let mut amplitude = 0.0f32;
    for _ in 0..48_000 {
        let d = ctrl.drive();
        let phase = d.phase_of(ctrl.tick().wrapping_sub(d.start_tick));
        let lag = (d.step.to_bits() as f32 * 0.467) as u32;
        amplitude = amplitude * decay + gain * d.amplitude_codes() as f32;
        let (c, _) = cos_sin_q31(Phase::from_bits(phase.to_bits().wrapping_sub(lag)));
        let code = (2048.0 - amplitude * (c as f32 / 2_147_483_648.0) + 0.5) as u16;
        let code = firmware::sample::AdcCode::new(code).expect("a 12-bit code");
        let t = ctrl.on_tick(&config, code);
        out.u32(t.dac_code as u32);
        if t.drive_changed {
            let d = ctrl.drive();
            out.u32(d.start_tick);
            out.u32(d.phase.to_bits());
            out.u32(d.step.to_bits());
            out.u32(d.amplitude_q16);
        }
        if t.half_cycle {
            let e = ctrl.estimate();
            out.f32(e.amplitude_arcsec);
            out.f32(e.frequency_hz);
            out.u32(e.angle_phase.to_bits());
            out.bool(e.valid);
        }
    }
    out.bool(ctrl.state() == DitherState::Locked);
}
