//! The dither pick-off on the board: its voltage model (gain error, offset, lag as a pure
//! delay, cubic non-linearity), its ADC channel (noise, clipping, seeded), the `lost` fault,
//! the comparator that follows it, and the driven dither through the whole firmware-in-the-loop
//! harness with the scheduled latch.

use firmware::sample::AdcCode;
use hal_sim::board::{BoardConfig, BoardError, LatchTiming, SimBoard};
use hal_sim::dither::resonator::ResonatorParams;
use hal_sim::gyro::Gyro;
use hal_sim::harness::HarnessOptions;
use hal_sim::input::InputProfile;
use hal_sim::params::GyroParams;
use hal_sim::pickoff::PickoffConfig;
use hal_sim::units::beat_rad_to_arcsec;

fn board(params: GyroParams, pickoff: PickoffConfig) -> SimBoard {
    let config = BoardConfig {
        pickoff,
        ..BoardConfig::for_gyro(&params)
    };
    let gyro = Gyro::new(params, InputProfile::constant(5.0)).unwrap();
    SimBoard::new(gyro, config).unwrap()
}

/// The first `t > t0` where `f` changes sign (bisected to the last bit).
fn crossing(f: impl Fn(f64) -> f64, t0: f64, step: f64) -> f64 {
    let (mut a, mut b) = (t0, t0 + step);
    while (f(a) >= 0.0) == (f(b) >= 0.0) {
        a = b;
        b += step;
    }
    loop {
        let m = 0.5 * (a + b);
        if m <= a || m >= b {
            return b;
        }
        if (f(m) >= 0.0) == (f(a) >= 0.0) {
            a = m;
        } else {
            b = m;
        }
    }
}

/// Gain error, offset, cubic term and lag as specified: at an extreme of the angle the
/// pick-off reads `offset + k (1 + e) (A + c A^3)` (to rounding, 1e-12 V), and its zero
/// crossings trail the angle's by exactly the lag (a pure delay: to 1e-12 s, the bisection).
#[test]
fn the_voltage_follows_the_angle_with_its_errors() {
    let pickoff = PickoffConfig {
        offset_v: 1.6,
        gain_error: 0.02,
        cubic_per_arcsec2: 1e-7,
        lag_s: 5e-6,
        ..PickoffConfig::ideal()
    };
    let mut b = board(GyroParams::default(), pickoff);
    let gyro = Gyro::new(GyroParams::default(), InputProfile::constant(5.0)).unwrap();
    let dither = gyro.free_phase().dither();
    let (t_ext, _) = dither.pickoff_turnaround_after(0.01).unwrap();
    let a = dither.pickoff_angle_arcsec(t_ext);
    let k = pickoff.sensitivity_v_per_arcsec;
    let expect = 1.6 + k * 1.02 * (a + 1e-7 * a * a * a);
    let v = b.pickoff_v(t_ext + 5e-6);
    assert!((v - expect).abs() < 1e-12, "{v} vs {expect}");
    let angle_zero = crossing(|t| dither.pickoff_angle_arcsec(t), 0.01, 1e-5);
    let volt_zero = crossing(|t| b.pickoff().clean_v(b.gyro(), t) - 1.6, 0.01, 1e-5);
    assert!(
        (volt_zero - angle_zero - 5e-6).abs() < 1e-12,
        "{}",
        volt_zero - angle_zero
    );
}

/// The ADC channel: 12-bit codes of the noisy voltage, seeded (same seed, same codes), the
/// noise's RMS as configured (20 000 draws: 1 % standard error; 4 % tolerance), and codes
/// clipped at 0 and 4095 when the pick-off is driven past the rails (5 mV/arcsec: 450 arcsec
/// is 2.25 V from mid-scale).
#[test]
fn the_adc_channel_is_noisy_seeded_and_clips() {
    let p = GyroParams::default();
    let pickoff = PickoffConfig {
        noise_rms_v: 2e-3,
        ..PickoffConfig::default()
    };
    let (mut b1, mut b2) = (board(p, pickoff), board(p, pickoff));
    let t = 0.0123;
    let clean = b1.pickoff().clean_v(b1.gyro(), t);
    let n = 20_000;
    let mut s2 = 0.0;
    for _ in 0..n {
        let v = b1.pickoff_v(t);
        s2 += (v - clean).powi(2);
        assert_eq!(v.to_bits(), b2.pickoff_v(t).to_bits(), "seeded");
        assert_eq!(b1.pickoff_code(t), b2.pickoff_code(t), "seeded");
    }
    let rms = (s2 / n as f64).sqrt();
    assert!((rms / 2e-3 - 1.0).abs() < 0.04, "{rms}");

    let mut hot = board(
        p,
        PickoffConfig {
            sensitivity_v_per_arcsec: 0.005,
            ..PickoffConfig::ideal()
        },
    );
    let gyro = hot.gyro().clone();
    let d = gyro.free_phase().dither();
    let (t1, _) = d.pickoff_turnaround_after(0.01).unwrap();
    let (t2, _) = d.pickoff_turnaround_after(t1).unwrap();
    let codes = [hot.pickoff_code(t1), hot.pickoff_code(t2)];
    assert!(
        codes.contains(&AdcCode::ZERO) && codes.contains(&AdcCode::FULL_SCALE),
        "{codes:?}"
    );
}

/// Lost: the ADC reads the offset plus noise, and the comparator has no edges, so every
/// scheduled latch falls back to the exact turnaround (and none is scheduled) until it comes
/// back.
#[test]
fn a_lost_pickoff_reads_its_offset_and_has_no_edges() {
    let mut h = HarnessOptions::new(GyroParams::default(), InputProfile::constant(5.0))
        .latch(LatchTiming::scheduled(0.0))
        .build()
        .unwrap();
    h.run_until(0.05, |_, _| {});
    let before = h.board().latch_stats();
    assert!(before.scheduled > 30, "{before:?}");
    h.board_mut().pickoff_mut().set_lost(true);
    let t = h.time_s() + 1e-3;
    let codes: Vec<u16> = (0..100)
        .map(|i| h.board_mut().pickoff_code(t + i as f64 * 1e-5).to_bits())
        .collect();
    // 1.65 V = code 2048; 1 mV of noise is 1.2 LSB: within +-8 codes (6.5 sigma).
    assert!(codes.iter().all(|c| c.abs_diff(2048) <= 8), "{codes:?}");
    h.run_until(0.1, |_, _| {});
    let lost = h.board().latch_stats();
    assert_eq!(lost.scheduled, before.scheduled, "{lost:?}");
    assert!(lost.fallbacks > before.fallbacks + 30, "{lost:?}");
    h.board_mut().pickoff_mut().set_lost(false);
    h.run_until(0.15, |_, _| {});
    assert!(h.board().latch_stats().scheduled > lost.scheduled + 30);
}

/// Every field's range is checked when the board is built.
#[test]
fn invalid_pickoffs_are_refused() {
    let ok = PickoffConfig::default();
    for bad in [
        PickoffConfig {
            sensitivity_v_per_arcsec: 0.0,
            ..ok
        },
        PickoffConfig {
            offset_v: 3.5,
            ..ok
        },
        PickoffConfig {
            gain_error: 0.6,
            ..ok
        },
        PickoffConfig { lag_s: -1e-6, ..ok },
        PickoffConfig {
            noise_rms_v: f64::NAN,
            ..ok
        },
        // Folds back inside the ADC's range (550 arcsec): not monotonic.
        PickoffConfig {
            cubic_per_arcsec2: -2e-6,
            ..ok
        },
    ] {
        let p = GyroParams::default();
        let config = BoardConfig {
            pickoff: bad,
            ..BoardConfig::for_gyro(&p)
        };
        let gyro = Gyro::new(p, InputProfile::constant(0.0)).unwrap();
        assert!(
            matches!(SimBoard::new(gyro, config), Err(BoardError::Pickoff(_))),
            "{bad:?}"
        );
    }
}

/// The driven dither through the firmware in the loop: the harness feeds the open-loop drive
/// (450 arcsec at 389 Hz, from its steady state), the comparator follows the driven pick-off
/// (5 % threshold offset) and the firmware's scheduler latches every turnaround after the
/// first cycles at the scheduled instant, within 0.1 us of the true one (the bound of
/// `board_schedule.rs`: the capture's tick quantisation with a wide margin); the firmware
/// measures the dither at 450 arcsec and 389 Hz.
#[test]
fn the_scheduled_latch_follows_the_driven_dither() {
    let p = GyroParams::default().with_steady_driven_dither(ResonatorParams::default());
    let mut h = HarnessOptions::new(p, InputProfile::constant(13.888))
        .latch(LatchTiming::scheduled(0.05 * 450.0))
        .build()
        .unwrap();
    let mut worst = 0.0f64;
    let mut cycles = 0;
    h.run_until(1.0, |_, half| {
        if half.latch_s() > 0.05 {
            assert!(half.latch.scheduled, "{half:?}");
            worst = worst.max((half.latch_s() - half.latch.turnaround.time_s).abs());
            cycles += usize::from(half.record.is_some());
        }
    });
    let (amp_rad, hz) = h.readout().dither();
    let amp_arcsec = beat_rad_to_arcsec(f64::from(amp_rad), p.scale_factor_arcsec);
    eprintln!(
        "{cycles} cycles, worst latch {:.1} ns, dither {amp_arcsec:.3} arcsec at {hz:.4} Hz, {:?}",
        worst * 1e9,
        h.board().latch_stats()
    );
    assert!(cycles > 350, "{cycles}");
    assert!(worst < 1e-7, "{worst}");
    // f32 in the firmware: a few 1e-6 relative.
    assert!((amp_arcsec / 450.0 - 1.0).abs() < 1e-4, "{amp_arcsec}");
    assert!((f64::from(hz) / 389.0 - 1.0).abs() < 1e-4, "{hz}");
}

/// A driven dither starting from rest under the harness's open-loop drive: the dither builds
/// up (1 - e^{-t/tau}, tau = 0.82 s), the harness feeds the drive until a turnaround is in
/// reach, the turnarounds alternate from the first, and after 1 s the firmware measures the
/// amplitude the resonator has reached (within 1 %: the amplitude changes by 0.2 % per
/// cycle while the firmware averages its half cycles), with the pick-off's ADC reading it.
#[test]
fn a_dither_starting_from_rest_builds_up_under_the_harness() {
    let p = GyroParams {
        dither_model: hal_sim::params::DitherModel::Driven(ResonatorParams::default()),
        ..GyroParams::default()
    };
    let mut h = HarnessOptions::new(p, InputProfile::constant(13.888))
        .build()
        .unwrap();
    let mut last = None;
    h.run_until(1.0, |_, half| {
        if let Some(kind) = last {
            assert_ne!(kind, half.latch.turnaround.kind);
        }
        last = Some(half.latch.turnaround.kind);
    });
    let t = h.time_s();
    let state = h.gyro().dither_state(t).unwrap();
    let w = core::f64::consts::TAU * 389.0;
    let reached = state.angle_arcsec.hypot(state.rate_arcsec_per_s / w);
    let expect = 450.0 * (1.0 - (-t / ResonatorParams::default().ring_down_s(0.0)).exp());
    let (amp_rad, _) = h.readout().dither();
    let measured = beat_rad_to_arcsec(f64::from(amp_rad), p.scale_factor_arcsec);
    eprintln!("after {t:.3} s: {reached:.2} arcsec ({expect:.2} expected), firmware {measured:.2}");
    assert!(
        (reached / expect - 1.0).abs() < 0.01,
        "{reached} vs {expect}"
    );
    assert!(
        (measured / reached - 1.0).abs() < 0.01,
        "{measured} vs {reached}"
    );
    // The pick-off's ADC sees it: the codes swing by 2 x the sensitivity x the amplitude.
    let codes: Vec<u16> = (0..52)
        .map(|i| h.board_mut().pickoff_code(t + i as f64 * 5e-5).to_bits())
        .collect();
    let swing = f64::from(codes.iter().max().unwrap() - codes.iter().min().unwrap());
    let k = hal_sim::pickoff::PickoffConfig::default().sensitivity_v_per_arcsec;
    let expect_swing = 2.0 * k * reached / (3.3 / 4096.0);
    assert!(
        (swing / expect_swing - 1.0).abs() < 0.02,
        "{swing} vs {expect_swing}"
    );
}
