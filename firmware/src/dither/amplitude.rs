//! The amplitude loop: a PI controller (`idsp::iir::BiquadClamp`, fixed point) from the
//! half-cycle amplitude to the drive amplitude, its gain normalised by the plant gain that the
//! start-up measures, clamped at the drive limit (the guard, and the anti-windup).
//!
//! # The plant
//! Near resonance the dither's envelope obeys `dA/dt = -A / tau + g u` (tau = 2Q / w0, u the
//! drive amplitude). `g` (pick-off codes per second per drive code) is `K / (2 w0)` for a drive
//! torque `K u`: independent of Q, while tau is 0.8 s at Q = 1000 and 4.1 s at Q = 5000. Above
//! 1/tau the plant is an integrator of gain g, so a PI whose proportional gain is `w_c / g`
//! has a crossover at w_c whatever Q is; the integral action takes up the loss `A / (g tau)`.
//! g is not a board constant (it is the gyro's drive efficiency): the start-up measures it from
//! the first half cycles of the ring-up at the drive limit ([`PlantGainProbe`]), and the loop
//! input is normalised by it, so the biquad itself is a fixed unit PI.
//!
//! # The controller: idsp's clamped biquad
//! `y0 = clamp(b0 x0 + b1 x1 + y1, 0, limit)` with `b0 = 1 + w_i T`, `b1 = -1` (Q30): the
//! velocity form of a PI whose state is its clamped output. At the limit the integral stops
//! growing by construction (the anti-windup) and leaving the limit is bumpless. From rest the
//! drive sits at the limit while the amplitude ramps at g * limit, then the proportional path
//! takes it off the limit: no overshoot. Measured on an envelope model (scratch, before this
//! code) and checked by the closed-loop tests (`dither::tests`): with the plant gain estimated
//! 0.33x to 1.4x of the truth, Q 1000 or 5000, the setpoint is reached within 1 % in 0.5-1.6 s
//! without overshoot; 2x over-estimated gives up to 10 % overshoot, so the probe errs low
//! (a drive out of phase while it runs only lowers its reading).
//!
//! The biquad's output is the drive amplitude in Q16 DAC codes (`i32`), its input the
//! proportional correction `w_c / g * (setpoint - A)` in Q16 codes.

use dsp_fixedpoint::Q32;
use dsp_process::SplitProcess;
use idsp::iir::{Biquad, BiquadClamp, DirectForm1Wide};

/// The amplitude loop's settings (immutable).
#[derive(Clone, Debug)]
pub struct AmplitudeLoopConfig {
    /// Crossover w_c, rad/s (the loop's bandwidth; 2 pi 4 Hz).
    pub crossover_rad_s: f32,
    /// The unit PI: `[1 + w_i T, -1, 0, 1, 0]` in Q30, clamped to 0..=drive limit (Q16 codes).
    pub pi: BiquadClamp<Q32<30>, i32>,
    /// The drive limit (the guard), DAC codes in Q16.
    pub drive_limit_q16: u32,
    /// Half cycles at the drive limit over which the start-up measures the plant gain.
    pub probe_half_cycles: u16,
    /// The smallest plausible plant gain, pick-off codes per second per drive code (below it the
    /// drive does not move the dither: a fault).
    pub min_plant_gain_per_s: f32,
}

impl AmplitudeLoopConfig {
    /// A loop of crossover `crossover_hz` and integral corner `crossover_hz / integral_ratio`,
    /// updated every half cycle of `dither_hz`, with the drive limited to `drive_limit_codes`.
    pub fn new(
        crossover_hz: f32,
        integral_ratio: f32,
        dither_hz: f32,
        drive_limit_codes: f32,
    ) -> Self {
        let w_c = core::f32::consts::TAU * crossover_hz;
        let half_cycle_s = 0.5 / dither_hz;
        let b0 = 1.0 + w_c / integral_ratio * half_cycle_s;
        let limit_q16 = (drive_limit_codes * 65_536.0) as u32;
        let coefficients = [b0, -1.0, 0.0, 1.0, 0.0].map(Q32::<30>::from_f32);
        Self {
            crossover_rad_s: w_c,
            pi: BiquadClamp {
                coeff: Biquad { ba: coefficients },
                u: 0,
                min: 0,
                max: limit_q16 as i32,
            },
            drive_limit_q16: limit_q16,
            probe_half_cycles: 8,
            min_plant_gain_per_s: 0.01,
        }
    }

    /// The drive limit in DAC codes.
    pub fn drive_limit_codes(&self) -> f32 {
        self.drive_limit_q16 as f32 / 65_536.0
    }
}

/// The amplitude loop's state.
#[derive(Clone, Debug, Default)]
pub struct AmplitudeLoop {
    pi: DirectForm1Wide,
    plant_gain_per_s: f32,
    drive_q16: i32,
    fresh: bool,
}

impl AmplitudeLoop {
    /// Starts the loop at drive `drive_q16` (bumpless: the PI's state is that output) with the
    /// plant gain `plant_gain_per_s`.
    pub fn start(&mut self, drive_q16: i32, plant_gain_per_s: f32) {
        self.pi = DirectForm1Wide {
            x: [0, 0],
            y: [(drive_q16 as i64) << 32; 2],
        };
        self.plant_gain_per_s = plant_gain_per_s;
        self.drive_q16 = drive_q16;
        self.fresh = true;
    }

    /// One half cycle: the drive amplitude (Q16 codes) for the next half cycle, from the
    /// setpoint and the measured amplitude (pick-off codes).
    pub fn update(
        &mut self,
        config: &AmplitudeLoopConfig,
        setpoint_codes: f32,
        measured_codes: f32,
    ) -> i32 {
        let correction = config.crossover_rad_s / self.plant_gain_per_s
            * (setpoint_codes - measured_codes)
            * 65_536.0;
        let x =
            crate::math::round_f32_to_i32(correction.clamp(-(1 << 28) as f32, (1 << 28) as f32));
        // The first update after `start` has no previous input: this one (no proportional kick).
        if self.fresh {
            self.pi.x = [x, x];
            self.fresh = false;
        }
        self.drive_q16 = config.pi.process(&mut self.pi, x);
        self.drive_q16
    }

    /// Moves the loop from `from` to `to` (another crossover) between two updates, bumplessly:
    /// the PI's state is its output, and its remembered input is rescaled to the new gain, so
    /// the next update changes the drive only by the new loop's own step.
    pub fn retune(&mut self, from: &AmplitudeLoopConfig, to: &AmplitudeLoopConfig) {
        let ratio = to.crossover_rad_s / from.crossover_rad_s;
        for x in &mut self.pi.x {
            *x = crate::math::round_f32_to_i32(*x as f32 * ratio);
        }
    }

    /// The drive amplitude in force, Q16 codes.
    pub fn drive_q16(&self) -> i32 {
        self.drive_q16
    }

    /// The drive is at the guard's limit (the loop has no authority left).
    pub fn at_limit(&self, config: &AmplitudeLoopConfig) -> bool {
        self.drive_q16 >= config.drive_limit_q16 as i32
    }

    /// The plant gain in use, pick-off codes per second per drive code.
    pub fn plant_gain_per_s(&self) -> f32 {
        self.plant_gain_per_s
    }
}

/// Measures the plant gain g: the amplitude's slope at a known drive, over the first half
/// cycles of the ring-up (the amplitude is still far below its steady state, so the loss term
/// is negligible: it biases g low by A / (g u tau), a few per cent).
#[derive(Clone, Copy, Debug, Default)]
pub struct PlantGainProbe {
    start: Option<(u32, f32)>,
    half_cycles: u16,
}

impl PlantGainProbe {
    /// Feeds one half cycle's amplitude (codes) at its end tick; returns g (codes per second per
    /// drive code) once `config.probe_half_cycles` have passed at drive `drive_codes`.
    pub fn push(
        &mut self,
        config: &AmplitudeLoopConfig,
        tick: u32,
        amplitude_codes: f32,
        drive_codes: f32,
        tick_hz: f32,
    ) -> Option<f32> {
        let Some((t0, a0)) = self.start else {
            self.start = Some((tick, amplitude_codes));
            return None;
        };
        self.half_cycles += 1;
        if self.half_cycles < config.probe_half_cycles {
            return None;
        }
        let seconds = tick.wrapping_sub(t0) as f32 / tick_hz;
        Some((amplitude_codes - a0) / (seconds * drive_codes))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn config() -> AmplitudeLoopConfig {
        AmplitudeLoopConfig::new(4.0, 4.0, 389.0, 1900.0)
    }

    /// The PI's steps, the clamp at the limit (guard), and the anti-windup: after a long time
    /// at the limit with a large error the output leaves the limit as soon as the error turns,
    /// because the state is the clamped output (no integral wound up behind it).
    #[test]
    fn pi_steps_clamps_and_does_not_wind_up() {
        let c = config();
        let mut l = AmplitudeLoop::default();
        l.start(500 << 16, 100.0);
        let codes = |q16: i32| q16 as f32 / 65_536.0;
        let kp = c.crossover_rad_s / 100.0; // w_c / g, drive codes per code of error
        let w_i_t = c.crossover_rad_s / 4.0 / 778.0;
        let y0 = codes(l.update(&c, 1000.0, 1000.0));
        assert_eq!(y0, 500.0);
        // An error step of 1 code: the proportional kp at once, plus one step of integral.
        let y1 = codes(l.update(&c, 1001.0, 1000.0));
        assert!((y1 - y0 - kp * (1.0 + w_i_t)).abs() < 1e-3, "{}", y1 - y0);
        // The same error again: only the integral, kp w_i T.
        let y2 = codes(l.update(&c, 1001.0, 1000.0));
        assert!((y2 - y1 - kp * w_i_t).abs() < 1e-4, "{}", y2 - y1);
        // A huge error: clamped at the limit, for a long time.
        for _ in 0..10_000 {
            l.update(&c, 5000.0, 0.0);
        }
        assert!(l.at_limit(&c));
        assert_eq!(l.drive_q16(), c.drive_limit_q16 as i32);
        // The error reverses: the drive leaves the limit at the first update.
        let after = l.update(&c, 900.0, 1000.0);
        assert!(after < c.drive_limit_q16 as i32);
        assert!(!l.at_limit(&c));
        // And a negative drive is impossible.
        for _ in 0..10_000 {
            l.update(&c, 0.0, 5000.0);
        }
        assert_eq!(l.drive_q16(), 0);
    }

    #[test]
    fn probe_measures_the_slope() {
        let c = config();
        let mut p = PlantGainProbe::default();
        let g = 0.8;
        let mut out = None;
        for k in 0..=c.probe_half_cycles as u32 {
            let tick = 1000 + k * 51;
            let a = 40.0 + g * 1900.0 * (tick - 1000) as f32 / 40_000.0;
            out = p.push(&c, tick, a, 1900.0, 40_000.0);
        }
        assert!((out.unwrap() - g).abs() < 1e-3);
    }
}
