//! The valid range of every numeric flag of `rlg-sim`, one [`Range`] constant each: the flag's
//! clap value parser and its help text (`args.rs`) read the same constant. Ranges that are
//! facts elsewhere are read from there (the thermal coefficients from hal-sim's [`LIMITS`],
//! the dither frequency from the board profile's scheduler range).

use firmware::profile::BoardProfile;
use hal_sim::thermal::LIMITS;
use host_cli::range::Range;

pub(crate) const SCALE_FACTOR_ARCSEC: Range<f64> =
    Range::closed("--scale-factor-arcsec", 0.1, 20.0, "arcsec");
/// The board's turnaround scheduler accepts these dither frequencies.
pub(crate) const DITHER_HZ: Range<f64> = Range::closed(
    "--dither-hz",
    BoardProfile::F405.dither_hz_range.0 as f64,
    BoardProfile::F405.dither_hz_range.1 as f64,
    "Hz",
);
pub(crate) const DITHER_AMPLITUDE_ARCSEC: Range<f64> =
    Range::closed("--dither-amplitude-arcsec", 50.0, 800.0, "arcsec");
pub(crate) const LOCK_IN_DEG_H: Range<f64> = Range::closed("--lock-in-deg-h", 0.0, 5000.0, "deg/h");
pub(crate) const EPS_RAD: Range<f64> =
    Range::symmetric("--eps-rad", std::f64::consts::PI, "rad").shown_as("-pi..=pi");
pub(crate) const ARW_DEG_RT_H: Range<f64> =
    Range::closed("--arw-deg-rt-h", 0.0, 1.0, "deg/sqrt(h)");
pub(crate) const AMPLITUDE_JITTER: Range<f64> = Range::closed("--amplitude-jitter", 0.0, 0.1, "");
/// An input rate (`sweep`'s ends, `record`, `speed`).
pub(crate) const RATE_DEG_H: Range<f64> = Range::closed("--rate-deg-h", -1e6, 1e6, "deg/h");
pub(crate) const SWEEP_POINTS: Range<usize> = Range::closed("--points", 1, 10_000, "");
pub(crate) const SWEEP_SECONDS_PER_POINT: Range<f64> =
    Range::closed("--seconds-per-point", 1e-3, 36_000.0, "s");
pub(crate) const SYNC_HZ: Range<f64> = Range::closed("--sync-hz", 100.0, 2000.0, "Hz");
pub(crate) const PICKOFF_GAIN_ERROR: Range<f64> = Range::symmetric("--pickoff-gain-error", 0.2, "");
pub(crate) const PICKOFF_LAG_US: Range<f64> = Range::closed("--pickoff-lag-us", 0.0, 100.0, "us");
pub(crate) const RECORD_SECONDS: Range<f64> = Range::above("--seconds", 0.0, 360_000.0, "s");
pub(crate) const SPEED_SECONDS: Range<f64> = Range::above("--seconds", 0.0, 3600.0, "s");
pub(crate) const MIN_FIT_TAU_S: Range<f64> = Range::closed("--min-fit-tau-s", 0.0, 1e6, "s");
pub(crate) const COMPARE_NOISE_PERCENT: Range<f64> =
    Range::closed("--compare-noise-percent", 1.0, 50.0, "%");
/// The thermal coefficients: within hal-sim's [`LIMITS`], as `ThermalCoefficients::validate`.
pub(crate) const THERMAL_REFERENCE_C: Range<f64> =
    Range::symmetric("--thermal-reference-c", LIMITS.reference_c, "C");
pub(crate) const THERMAL_BIAS_DEG_H_PER_C: Range<f64> = Range::symmetric(
    "--thermal-bias-deg-h-per-c",
    LIMITS.bias_deg_h_per_c,
    "deg/h per C",
);
pub(crate) const THERMAL_BIAS_DEG_H_PER_C2: Range<f64> = Range::symmetric(
    "--thermal-bias-deg-h-per-c2",
    LIMITS.bias_deg_h_per_c2,
    "deg/h per C^2",
);
pub(crate) const THERMAL_BIAS_DEG_H_PER_C_PER_MIN: Range<f64> = Range::symmetric(
    "--thermal-bias-deg-h-per-c-per-min",
    LIMITS.bias_deg_h_per_c_per_min,
    "deg/h per C/min",
);
pub(crate) const THERMAL_SF_PPM_PER_C: Range<f64> = Range::symmetric(
    "--thermal-sf-ppm-per-c",
    LIMITS.scale_factor_ppm_per_c,
    "ppm per C",
);
pub(crate) const THERMAL_SF_PPM_PER_C2: Range<f64> = Range::symmetric(
    "--thermal-sf-ppm-per-c2",
    LIMITS.scale_factor_ppm_per_c2,
    "ppm per C^2",
);
pub(crate) const THERMAL_LOCK_IN_PER_C: Range<f64> =
    Range::symmetric("--thermal-lock-in-per-c", LIMITS.lock_in_per_c, "per C");
pub(crate) const THERMAL_EPS_RAD_PER_C: Range<f64> =
    Range::symmetric("--thermal-eps-rad-per-c", LIMITS.eps_rad_per_c, "rad per C");
pub(crate) const THERMAL_PICKOFF_GAIN_PER_C: Range<f64> = Range::symmetric(
    "--thermal-pickoff-gain-per-c",
    LIMITS.pickoff_gain_per_c,
    "per C",
);
pub(crate) const THERMAL_DITHER_HZ_PER_C: Range<f64> = Range::symmetric(
    "--thermal-dither-hz-per-c",
    LIMITS.dither_hz_per_c,
    "Hz per C",
);
pub(crate) const THERMAL_DITHER_Q_PER_C: Range<f64> =
    Range::symmetric("--thermal-dither-q-per-c", LIMITS.dither_q_per_c, "per C");
