//! Gyros nobody tuned for: parameter sets drawn at random (seeded) within what real
//! mechanically dithered ring laser gyros and their pick-offs have, so that a result is shown
//! on more than the docs/physics.md set the code was developed on.
//!
//! | quantity | range | why |
//! | --- | --- | --- |
//! | scale factor | 1.5-3 arcsec per pulse | path lengths of about 28-45 cm (triangular blocks, x4 counting) |
//! | dither frequency | 300-600 Hz | dither spring resonances of small to medium blocks |
//! | dither amplitude | 300-600 arcsec peak | enough to keep the dead band at a few deg/h, within the pick-off's range |
//! | lock-in threshold Omega_L | 100-400 deg/h | mirror back-scatter of navigation-grade to tactical gyros |
//! | eps | -pi..pi | where the photodiodes sit on the fringe pattern: anywhere |
//! | pick-off gain error | +-5 % | the gauge's and the amplifier's tolerance against the nominal sensitivity |
//! | pick-off lag | 0-5 us | the gauge and its preamplifier at the dither frequency |
//!
//! Uniform in each range, independent, from a splitmix64 stream of the seed (no dependency on
//! a random-number crate's algorithm: the same seed draws the same gyro in every version), each
//! rounded to a short decimal so that [`RandomGyro::cli_flags`] reproduces the draw exactly.

use crate::params::GyroParams;

/// One drawn gyro and the errors of its pick-off.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RandomGyro {
    /// The gyro (the drawn quantities; everything else the docs/physics.md set's, seeded with
    /// the draw's seed).
    pub params: GyroParams,
    /// The pick-off's relative gain error against its nominal sensitivity.
    pub pickoff_gain_error: f64,
    /// The pick-off's lag behind the dither angle, us (as `rlg-sim --pickoff-lag-us` takes it).
    pub pickoff_lag_us: f64,
}

impl RandomGyro {
    /// The gyro of `seed`.
    pub fn draw(seed: u64) -> Self {
        let mut state = seed ^ 0x5241_4E44_4759_524F;
        let mut uniform = |lo: f64, hi: f64| {
            state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = state;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            z ^= z >> 31;
            lo + (hi - lo) * ((z >> 11) as f64 / (1u64 << 53) as f64)
        };
        let decimals = |x: f64, n: i32| (x * 10f64.powi(n)).round() / 10f64.powi(n);
        use std::f64::consts::PI;
        let params = GyroParams {
            scale_factor_arcsec: decimals(uniform(1.5, 3.0), 4),
            dither_hz: decimals(uniform(300.0, 600.0), 2),
            dither_amplitude_arcsec: decimals(uniform(300.0, 600.0), 1),
            lock_in_deg_per_h: decimals(uniform(100.0, 400.0), 1),
            eps_rad: decimals(uniform(-PI, PI), 4),
            seed,
            ..GyroParams::default()
        };
        Self {
            pickoff_gain_error: decimals(uniform(-0.05, 0.05), 4),
            pickoff_lag_us: decimals(uniform(0.0, 5.0), 3),
            params,
        }
    }
}

impl RandomGyro {
    /// The `rlg-sim` flags that run this gyro (`sweep`, `record`, `characterize`), so a result
    /// on it can be reproduced from the command line.
    pub fn cli_flags(&self) -> String {
        let p = &self.params;
        format!(
            "--scale-factor-arcsec {} --dither-hz {} --dither-amplitude-arcsec {} \
             --lock-in-deg-h {} --eps-rad {} --pickoff-gain-error {} --pickoff-lag-us {} \
             --seed {}",
            p.scale_factor_arcsec,
            p.dither_hz,
            p.dither_amplitude_arcsec,
            p.lock_in_deg_per_h,
            p.eps_rad,
            self.pickoff_gain_error,
            self.pickoff_lag_us,
            p.seed
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every draw lies in the documented ranges, the draws spread over them, and a seed always
    /// draws the same gyro.
    #[test]
    fn draws_cover_the_ranges_and_repeat() {
        let draws: Vec<RandomGyro> = (0..2000).map(RandomGyro::draw).collect();
        let span = |f: &dyn Fn(&RandomGyro) -> f64, lo: f64, hi: f64| {
            let v: Vec<f64> = draws.iter().map(f).collect();
            let (min, max) = v
                .iter()
                .fold((f64::MAX, f64::MIN), |(a, b), &x| (a.min(x), b.max(x)));
            assert!(min >= lo && max <= hi, "{min} {max} not in {lo}..{hi}");
            let width = hi - lo;
            assert!(
                min < lo + 0.01 * width && max > hi - 0.01 * width,
                "{min} {max}"
            );
        };
        span(&|g| g.params.scale_factor_arcsec, 1.5, 3.0);
        span(&|g| g.params.dither_hz, 300.0, 600.0);
        span(&|g| g.params.dither_amplitude_arcsec, 300.0, 600.0);
        span(&|g| g.params.lock_in_deg_per_h, 100.0, 400.0);
        span(
            &|g| g.params.eps_rad,
            -std::f64::consts::PI,
            std::f64::consts::PI,
        );
        span(&|g| g.pickoff_gain_error, -0.05, 0.05);
        span(&|g| g.pickoff_lag_us, 0.0, 5.0);
        assert_eq!(RandomGyro::draw(7), RandomGyro::draw(7));
        assert_ne!(RandomGyro::draw(7), RandomGyro::draw(8));
        assert!(draws.iter().all(|g| g.params.derive().is_ok()));
        // The flags give back the draw bit for bit (Rust prints the shortest round trip).
        let g = RandomGyro::draw(3);
        let flags = g.cli_flags();
        let value = |flag: &str| -> f64 {
            let at = flags.find(flag).unwrap() + flag.len() + 1;
            flags[at..]
                .split_whitespace()
                .next()
                .unwrap()
                .parse()
                .unwrap()
        };
        assert_eq!(value("--scale-factor-arcsec"), g.params.scale_factor_arcsec);
        assert_eq!(value("--eps-rad"), g.params.eps_rad);
        assert_eq!(value("--pickoff-lag-us"), g.pickoff_lag_us);
        assert!(flags.len() < 200, "{flags}");
    }
}
