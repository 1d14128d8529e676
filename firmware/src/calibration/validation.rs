//! Validity checks a calibration fit must pass before it may be accepted.
//!
//! The paper fits a and b outside the dead band; inside it the gyro output does not follow the
//! input, the per-cycle output carries no rate information and the fit is meaningless. Each
//! refusal has its own reason code, so the host can tell a technician what to change (the
//! protocol reports `ERR <code> <text>`).
//!
//! The dead-band check needs the band's half-width, which the device computes itself from the
//! fit and the measured dither: Omega_L0 = Omega_L |J0(A)| (Chow), A the dither amplitude in
//! rad of beat phase (`libm::j0f`: single precision, relative error ~1e-6 away from J0's
//! zeros, far below the margin; the f64 `j0` cost 6.4 KiB of the board image with the f64
//! argument reduction it pulls in). The mean input rate must clear it by a margin.

use super::fit::FitResult;

/// Why a fit was refused. The discriminant is the protocol's reason code.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[repr(u8)]
pub enum Refusal {
    /// The mean rate was inside (or too near) the dynamic dead band.
    InsideDeadBand = 1,
    /// Fewer usable cycles than required.
    TooFewCycles = 2,
    /// Signal lost, counter glitches or missed turnarounds during the run.
    SignalProblems = 3,
    /// P1 and P2 too correlated to separate a and b.
    IllConditioned = 4,
    /// The model explains too little of the per-cycle output variance.
    LittleVarianceExplained = 5,
    /// Omega_L outside the plausible range.
    ImplausibleLockIn = 6,
    /// The normal equations could not be solved at all.
    Singular = 7,
    /// No valid dither amplitude was measured.
    NoDither = 8,
}

impl Refusal {
    /// The numeric reason code.
    pub const fn code(self) -> u8 {
        self as u8
    }

    /// A short human-readable reason.
    pub const fn text(self) -> &'static str {
        match self {
            Self::InsideDeadBand => "mean rate inside the dynamic dead band",
            Self::TooFewCycles => "too few cycles",
            Self::SignalProblems => "signal lost or counter glitches during the run",
            Self::IllConditioned => "P1 and P2 not separable (ill-conditioned)",
            Self::LittleVarianceExplained => "too little variance explained",
            Self::ImplausibleLockIn => "implausible lock-in threshold",
            Self::Singular => "singular normal equations",
            Self::NoDither => "no valid dither amplitude",
        }
    }
}

/// Acceptance limits (immutable; defaults below).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AcceptanceLimits {
    /// Fewest usable cycles, all runs pooled (else [`Refusal::TooFewCycles`]).
    pub min_cycles: u64,
    /// Flagged cycles tolerated per run pool (they are excluded from the fit either way).
    pub max_flagged_cycles: u32,
    /// The mean rate must exceed `dead_band_margin` x Omega_L0.
    pub dead_band_margin: f64,
    /// Largest condition number of the P1/P2 covariance, >= 1 (else [`Refusal::IllConditioned`]).
    pub max_condition_number: f64,
    /// Smallest fraction of the output variance the fit must explain, 0..1.
    pub min_variance_reduction: f64,
    /// Smallest plausible Omega_L, rad/s of beat phase.
    pub min_lock_in_rad_per_s: f64,
    /// Largest plausible Omega_L, rad/s of beat phase.
    pub max_lock_in_rad_per_s: f64,
}

impl AcceptanceLimits {
    /// 2000 cycles (5 s at 389 Hz); no flagged cycle; 1.3 x the dead band; condition number 10;
    /// 30 % of the variance explained; Omega_L between 1 and 30000 rad/s (0.3 to 9000 deg/h at
    /// SF 1.8655).
    pub const DEFAULT: Self = Self {
        min_cycles: 2000,
        max_flagged_cycles: 0,
        dead_band_margin: 1.3,
        max_condition_number: 10.0,
        min_variance_reduction: 0.3,
        min_lock_in_rad_per_s: 1.0,
        max_lock_in_rad_per_s: 30_000.0,
    };
}

impl Default for AcceptanceLimits {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// The Chow dead band half-width Omega_L |J0(A)|, rad/s, for a dither amplitude A in rad of
/// beat phase.
pub fn chow_dead_band_rad_per_s(lock_in_rad_per_s: f64, dither_amplitude_rad: f64) -> f64 {
    lock_in_rad_per_s * libm::fabs(libm::j0f(dither_amplitude_rad as f32) as f64)
}

/// What the run looked like, besides the fit itself.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RunSummary {
    /// Cycles that carried a flag (excluded from the fit).
    pub flagged_cycles: u32,
    /// Mean measured dither amplitude, beat-phase rad (0 if never measured).
    pub dither_amplitude_rad: f64,
    /// Smallest |mean rate| among the pooled runs, rad/s (each run must be outside the band).
    pub min_abs_run_rate_rad_per_s: f64,
}

/// Checks a fit in a fixed order (the first failing check is reported).
pub fn check(fit: &FitResult, run: &RunSummary, limits: &AcceptanceLimits) -> Result<(), Refusal> {
    if fit.cycles < limits.min_cycles {
        return Err(Refusal::TooFewCycles);
    }
    if run.flagged_cycles > limits.max_flagged_cycles {
        return Err(Refusal::SignalProblems);
    }
    if !(run.dither_amplitude_rad.is_finite() && run.dither_amplitude_rad > 0.0) {
        return Err(Refusal::NoDither);
    }
    let lock_in = fit.lock_in_rad_per_s;
    if !(lock_in.is_finite()
        && lock_in >= limits.min_lock_in_rad_per_s
        && lock_in <= limits.max_lock_in_rad_per_s)
    {
        return Err(Refusal::ImplausibleLockIn);
    }
    let band = chow_dead_band_rad_per_s(lock_in, run.dither_amplitude_rad);
    if run.min_abs_run_rate_rad_per_s.is_nan()
        || run.min_abs_run_rate_rad_per_s <= limits.dead_band_margin * band
    {
        return Err(Refusal::InsideDeadBand);
    }
    if fit.condition_number.is_nan() || fit.condition_number > limits.max_condition_number {
        return Err(Refusal::IllConditioned);
    }
    if fit.variance_reduction.is_nan() || fit.variance_reduction < limits.min_variance_reduction {
        return Err(Refusal::LittleVarianceExplained);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    const TAU: f64 = core::f64::consts::TAU;

    fn good_fit() -> FitResult {
        FitResult {
            a_rad_per_s: 344.0,
            b_rad_per_s: 579.0,
            a_std_rad_per_s: 0.1,
            b_std_rad_per_s: 0.1,
            lock_in_rad_per_s: 673.6,
            eps_rad: 0.3,
            variance_reduction: 0.99,
            condition_number: 1.2,
            residual_std_rad: 1e-5,
            mean_rate_rad_per_s: 46.8,
            cycles: 10_000,
            runs: 2,
        }
    }

    fn run() -> RunSummary {
        RunSummary {
            flagged_cycles: 0,
            dither_amplitude_rad: TAU * 450.0 / 1.8655,
            min_abs_run_rate_rad_per_s: 46.8,
        }
    }

    /// docs/physics.md: 200 deg/h, 450 arcsec, SF 1.8655 -> Omega_L0 = 3.358 deg/h. Tolerance: the
    /// table's 4 digits.
    #[test]
    fn chow_band_of_the_paper_set() {
        let to_rad = |deg_h: f64| TAU * deg_h / 1.8655;
        let band = chow_dead_band_rad_per_s(to_rad(200.0), TAU * 450.0 / 1.8655);
        let band_deg_h = band * 1.8655 / TAU;
        assert!((band_deg_h - 3.358).abs() < 1e-3, "{band_deg_h}");
    }

    #[test]
    fn a_good_fit_passes() {
        assert_eq!(
            check(&good_fit(), &run(), &AcceptanceLimits::DEFAULT),
            Ok(())
        );
    }

    /// Each check refuses with its own reason, and only that one.
    #[test]
    fn each_refusal_has_its_reason() {
        let l = AcceptanceLimits::DEFAULT;
        let mut f = good_fit();
        f.cycles = 100;
        assert_eq!(check(&f, &run(), &l), Err(Refusal::TooFewCycles));
        let mut r = run();
        r.flagged_cycles = 3;
        assert_eq!(check(&good_fit(), &r, &l), Err(Refusal::SignalProblems));
        let mut r = run();
        r.dither_amplitude_rad = 0.0;
        assert_eq!(check(&good_fit(), &r, &l), Err(Refusal::NoDither));
        let mut f = good_fit();
        f.lock_in_rad_per_s = 1e6;
        assert_eq!(check(&f, &run(), &l), Err(Refusal::ImplausibleLockIn));
        let mut r = run();
        // 3 deg/h: inside the 3.358 deg/h band.
        r.min_abs_run_rate_rad_per_s = TAU * 3.0 / 1.8655;
        assert_eq!(check(&good_fit(), &r, &l), Err(Refusal::InsideDeadBand));
        let mut f = good_fit();
        f.condition_number = 50.0;
        assert_eq!(check(&f, &run(), &l), Err(Refusal::IllConditioned));
        let mut f = good_fit();
        f.variance_reduction = 0.1;
        assert_eq!(check(&f, &run(), &l), Err(Refusal::LittleVarianceExplained));
        let mut f = good_fit();
        f.lock_in_rad_per_s = f64::NAN;
        assert_eq!(check(&f, &run(), &l), Err(Refusal::ImplausibleLockIn));
    }

    #[test]
    fn codes_are_distinct() {
        let all = [
            Refusal::InsideDeadBand,
            Refusal::TooFewCycles,
            Refusal::SignalProblems,
            Refusal::IllConditioned,
            Refusal::LittleVarianceExplained,
            Refusal::ImplausibleLockIn,
            Refusal::Singular,
            Refusal::NoDither,
        ];
        for (i, a) in all.iter().enumerate() {
            for b in &all[i + 1..] {
                assert_ne!(a.code(), b.code());
            }
        }
    }
}
