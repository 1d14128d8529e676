//! `rlg-sim characterize`: the IEEE Std 647 test procedures on the simulated gyro, with the
//! firmware in the loop, and their report.
//!
//! One file per step:
//! - here: the plan (which input rates, how long) and the configurations compared;
//! - [`procedure`]: the runs (the board of [`crate::experiment`], each input rate measured
//!   from the board's fixed-rate output as `sweep` does; the static record through
//!   [`crate::record_run`]), independent runs in parallel (rayon), stoppable;
//! - [`figures`]: the figures from the points (scale factor, non-linearity, asymmetry,
//!   threshold and dead band, bias stability), sans-IO;
//! - [`noise`]: the static record's noise terms through the Allan estimator and fit
//!   ([`crate::allan`]);
//! - [`summary`]: the figures side by side and the conclusions, sentences chosen by the numbers;
//! - [`charts`]: the SVG figures; [`report`]: `report.md` and the CSVs, written to `--out`;
//! - [`thermal`]: with `--thermal`, bias and scale factor over temperature
//!   ([`crate::thermal::procedure`]), its CSV, figure and section.
//!
//! The input rates: the **linear range**, `range_points` log-spaced magnitudes per sign from
//! ten times the dead-band envelope to the maximum rate; and the **dense points**,
//! `dense_points` magnitudes per sign from 2 % to 2.5 times the envelope, closer together
//! near the band's edge (fractions `2.5 (i / n)^1.5`). The envelope is the largest dynamic dead
//! band a gyro of this lock-in and nearly this dither amplitude can have: Chow's band is
//! `Omega_L |J0(A)|` (docs/physics.md, Eq. 8) and `|J0(A)| <= sqrt(2 / (pi A))` for large A;
//! the band itself swings by several deg/h per arcsec of amplitude, and the firmware's drive
//! holds the amplitude its pick-off measures, so the envelope, not the nominal band, places
//! the points (3.36 deg/h nominal, 4.10 deg/h envelope for the default set). Nothing about the
//! band is assumed in the figures: the threshold is measured at those points.

pub mod charts;
pub mod figures;
pub mod noise;
pub mod procedure;
pub mod report;
pub mod summary;
pub mod thermal;

use crate::experiment::{BoardSetup, WARMUP_SECONDS};
use firmware::calibration::validation::chow_dead_band_rad_per_s;
use firmware::signal::compensation::CompensationSettings;
use hal_sim::params::GyroParams;
use host_cli::range::Range;

/// One configuration of the board characterised.
#[derive(Clone, Debug, PartialEq)]
pub struct Configuration {
    /// Its name in the report ("compensation on", ...).
    pub name: String,
    /// Its name in file names (`comp_on`, ...).
    pub slug: String,
    /// The simulated board (dither drive, latch, sync, noise dither).
    pub setup: BoardSetup,
    /// The compensation settings (calibrated coefficients, enabled or not).
    pub settings: CompensationSettings,
}

/// What is run for each configuration.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plan {
    /// Largest input rate magnitude, deg/s ([`MAX_RATE_DEG_S`]).
    pub max_rate_deg_s: f64,
    /// Log-spaced linear-range magnitudes per sign ([`RANGE_POINTS`]).
    pub range_points: usize,
    /// Magnitudes near zero per sign ([`DENSE_POINTS`]).
    pub dense_points: usize,
    /// Simulated seconds recorded per input rate ([`SECONDS_PER_POINT`]).
    pub seconds_per_point: f64,
    /// Simulated seconds discarded before each recording ([`WARMUP_SECONDS`]).
    pub warmup_s: f64,
    /// Simulated seconds of the static (zero-input) record ([`STATIC_SECONDS`]).
    pub static_s: f64,
    /// Two-sided confidence of the noise terms' intervals ([`crate::allan::CONFIDENCE`]).
    pub confidence: f64,
}

/// Valid `--max-rate-deg-s`: up to 300 deg/s (the default set's dither peaks at 305 deg/s).
/// The beat turns where the dither rate equals minus the input, so a large input splits each
/// dither period into unequal halves, `180 deg -+ 2 asin(rate / peak dither rate)`; the
/// firmware's cycle assembly holds the period (+-20 %) and lets the halves split (up to
/// 0.1..1.9 of nominal, `CycleConfig::HALF_SPLIT`). (Its earlier half-period window of
/// +-20 % refused every cycle from about 94 deg/s, which this command found.)
pub const MAX_RATE_DEG_S: Range<f64> = Range::closed("--max-rate-deg-s", 0.1, 300.0, "deg/s");
/// Valid log-spaced linear-range points per sign.
pub const RANGE_POINTS: Range<usize> = Range::closed("--range-points", 2, 50, "");
/// Valid near-zero points per sign: as many as [`RANGE_POINTS`].
pub const DENSE_POINTS: Range<usize> = RANGE_POINTS.for_flag("--dense-points");
/// Valid seconds per point.
pub const SECONDS_PER_POINT: Range<f64> = Range::closed("--seconds-per-point", 0.5, 3600.0, "s");
/// Valid static record lengths (up to 100 h).
pub const STATIC_SECONDS: Range<f64> = Range::closed("--static-seconds", 10.0, 360_000.0, "s");

impl Plan {
    /// The defaults of `rlg-sim characterize`: 100 deg/s, 8 + 16 points per sign of 5 s, a
    /// 600 s static record (about 2 900 gyro-seconds for `--compare`). The static record is
    /// 600 s because the board's readout floor (white angle noise) hides an ARW of a few
    /// 1e-3 deg/sqrt(h) below tau of about 20 s: the ARW shows, or is bounded, only at the
    /// longer taus.
    pub const DEFAULT: Self = Self {
        max_rate_deg_s: 100.0,
        range_points: 8,
        dense_points: 16,
        seconds_per_point: 5.0,
        warmup_s: 0.5,
        static_s: 600.0,
        confidence: 0.95,
    };

    /// Every field against its range; the message names the flag.
    pub fn validate(&self) -> Result<(), String> {
        MAX_RATE_DEG_S.check(self.max_rate_deg_s)?;
        SECONDS_PER_POINT.check(self.seconds_per_point)?;
        WARMUP_SECONDS.check(self.warmup_s)?;
        STATIC_SECONDS.check(self.static_s)?;
        crate::allan::CONFIDENCE.check(self.confidence)?;
        RANGE_POINTS.check(self.range_points)?;
        DENSE_POINTS.check(self.dense_points)?;
        Ok(())
    }
}

/// The dead band of a gyro in theory, deg/h.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DeadBandTheory {
    /// Chow's band `Omega_L |J0(A)|` at the nominal amplitude (the firmware's function).
    pub chow_deg_h: f64,
    /// The envelope `Omega_L sqrt(2 / (pi A))`: the largest band near this amplitude.
    pub envelope_deg_h: f64,
}

/// Chow's band and its envelope for `params`; `None` if the parameters are invalid.
pub fn dead_band_theory(params: &GyroParams) -> Option<DeadBandTheory> {
    let d = params.derive().ok()?;
    let to_deg_h = params.scale_factor_arcsec / std::f64::consts::TAU;
    let a = d.dither_amp_rad;
    Some(DeadBandTheory {
        chow_deg_h: chow_dead_band_rad_per_s(d.omega_l_rad_per_s, a) * to_deg_h,
        envelope_deg_h: d.omega_l_rad_per_s * (2.0 / (std::f64::consts::PI * a)).sqrt() * to_deg_h,
    })
}

/// One input rate of the plan.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlannedRate {
    /// Input rate, deg/h.
    pub rate_deg_h: f64,
    /// A linear-range point (else a dense point near zero).
    pub linear_range: bool,
}

/// The input rates of `plan` for a gyro whose dead-band envelope is `envelope_deg_h`: dense
/// points first, then the linear range, each magnitude with both signs.
pub fn planned_rates(plan: &Plan, envelope_deg_h: f64) -> Vec<PlannedRate> {
    let n = plan.dense_points as f64;
    let dense = (1..=plan.dense_points).map(|i| 2.5 * (i as f64 / n).powf(1.5) * envelope_deg_h);
    let low = 10.0 * envelope_deg_h;
    let high = plan.max_rate_deg_s * 3600.0;
    let steps = (plan.range_points - 1) as f64;
    let range = (0..plan.range_points).map(|i| low * (high / low).powf(i as f64 / steps));
    dense
        .map(|m| (m, false))
        .chain(range.map(|m| (m, true)))
        .flat_map(|(m, linear_range)| {
            [m, -m].map(|rate_deg_h| PlannedRate {
                rate_deg_h,
                linear_range,
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The default set: Chow's band 3.358 deg/h (docs/physics.md, section 9), the envelope
    /// above it; the plan's rates span the band and reach the maximum, both signs.
    #[test]
    fn the_plan_spans_the_band_and_the_range() {
        let theory = dead_band_theory(&GyroParams::default()).unwrap();
        assert!((theory.chow_deg_h - 3.358).abs() < 0.002, "{theory:?}");
        assert!(theory.envelope_deg_h > theory.chow_deg_h && theory.envelope_deg_h < 4.2);
        let rates = planned_rates(&Plan::DEFAULT, theory.envelope_deg_h);
        assert_eq!(rates.len(), 2 * (8 + 16));
        let dense: Vec<f64> = rates
            .iter()
            .filter(|r| !r.linear_range && r.rate_deg_h > 0.0)
            .map(|r| r.rate_deg_h)
            .collect();
        assert!(dense[0] < 0.1 * theory.chow_deg_h && dense[15] > 2.0 * theory.chow_deg_h);
        // Inside and just outside the band, at most 1 deg/h apart there.
        let near: Vec<&f64> = dense
            .iter()
            .filter(|&&r| (2.5..=5.0).contains(&r))
            .collect();
        assert!(near.len() >= 3, "{dense:?}");
        let top = rates.iter().map(|r| r.rate_deg_h).fold(0.0, f64::max);
        let bottom = rates.iter().map(|r| r.rate_deg_h).fold(0.0, f64::min);
        assert!((top - 100.0 * 3600.0).abs() < 1e-6 && (bottom + top).abs() < 1e-9);
    }

    #[test]
    fn the_plan_refuses_out_of_range_values_naming_the_flag() {
        let bad = Plan {
            max_rate_deg_s: 301.0,
            ..Plan::DEFAULT
        };
        assert!(bad.validate().unwrap_err().contains("--max-rate-deg-s"));
        let bad = Plan {
            dense_points: 1,
            ..Plan::DEFAULT
        };
        assert!(bad.validate().unwrap_err().contains("--dense-points"));
        let bad = Plan {
            static_s: f64::NAN,
            ..Plan::DEFAULT
        };
        assert!(bad.validate().unwrap_err().contains("--static-seconds"));
        assert!(Plan::DEFAULT.validate().is_ok());
    }
}
