//! The paper's experiment on the simulated gyro, with the firmware's signal chain in the loop.
//!
//! A run is hal-sim's [`Harness`](hal_sim::harness::Harness): the simulated board's
//! half-cycles (Lissajous samples, then the turnaround latch) go to the firmware's `Readout`,
//! exactly as the ADC and turnaround interrupts would, and the per-cycle records come back. On
//! top of runs:
//!
//! - [`calibrate`]: the paper's Step 2, runs at rates outside the dead band with compensation off,
//!   fed to the firmware's own [`CalibrationSession`] (the one behind `cal start` / `cal result`
//!   on the board): pooled into the least-squares fit of a and b (one intercept per run) and
//!   judged by the board's validity checks, so a fit the board would refuse is refused here with
//!   the same [`Refusal`] (reason code and text). The cycles of a run are buffered (about
//!   100 bytes each: 0.8 MB for the default 20 s) so the session can be told the run's length,
//!   which the board knows from `cal start <cycles>`;
//! - [`measure_rate`]: one input rate with the compensation on, giving the uncompensated and the
//!   compensated output of the same cycles, each averaged over whole output periods.

use firmware::calibration::fit::FitResult;
use firmware::calibration::session::{CalibrationSession, SessionState};
use firmware::calibration::validation::{AcceptanceLimits, Refusal};
use firmware::dither::DitherState;
use firmware::readout::ReadoutConfig;
use firmware::signal::compensation::{CoefficientError, Coefficients, CompensationSettings};
use firmware::signal::lockin::{CycleOutput, CycleRecord};
use firmware::signal::output::record::OutputRecord;
use firmware::signal::output::{AveragerConfig, AveragingMode, RateAverager};
use firmware::units::PhaseDelta;
use hal_sim::board::{LatchTiming, OutputLatch};
use hal_sim::dither::resonator::{ResonatorParams, TemperatureDrift};
use hal_sim::gyro::Speed;
use hal_sim::harness::{DriveSource, Harness, HarnessOptions};
use hal_sim::input::InputProfile;
use hal_sim::params::GyroParams;
use host_cli::range::Range;

/// Earth rate projected on the paper's horizontal axis: 15 deg/h x cos(22.2 deg).
pub const PAPER_RANGE_DEG_H: f64 = 13.888;

/// Valid warm-up before a recording (`--warmup-seconds` of `sweep`, `record`, `characterize`).
pub const WARMUP_SECONDS: Range<f64> = Range::closed("--warmup-seconds", 0.0, 60.0, "s");

/// A run's timing: warm-up (discarded) and recording, simulated seconds.
#[derive(Clone, Copy, Debug)]
pub struct RunLength {
    /// Simulated time before recording, s; the cycles closed in it are discarded.
    pub warmup_s: f64,
    /// Simulated time recorded after the warm-up, s.
    pub record_s: f64,
}

/// Why an experiment failed.
#[derive(Debug)]
pub enum ExperimentError {
    /// The simulated board refused its parameters (the text says why), or a run closed no
    /// dither cycle.
    Simulator(String),
    /// The board's calibration checks refused the fit (the reason `cal result` answers with
    /// `ERR 12` on the board).
    Refused(Refusal),
    /// The fitted a or b is not finite or out of the coefficients' range.
    Coefficients(CoefficientError),
}

impl std::fmt::Display for ExperimentError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Simulator(e) => write!(f, "simulator: {e}"),
            Self::Refused(r) => write!(
                f,
                "calibration refused by the board's checks: reason={} ({})",
                r.code(),
                r.text()
            ),
            Self::Coefficients(e) => write!(f, "fitted coefficients not representable: {e:?}"),
        }
    }
}

impl std::error::Error for ExperimentError {}

/// The seed of one run: the experiment's seed mixed with the run's input rate (splitmix64), so
/// every run draws its own noise, and the same experiment always draws the same.
pub fn run_seed(seed: u64, rate_deg_h: f64) -> u64 {
    let mut z = seed ^ rate_deg_h.to_bits().rotate_left(17);
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// How the dither is made in a run.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum DitherDrive {
    /// The prescribed sine of the parameters (the paper's idealised experiment).
    #[default]
    Ideal,
    /// A driven resonator at the parameters' `dither_hz` (hal-sim's default resonator, Q 1000,
    /// started in its steady state) held by the firmware's drive at `dither_amplitude_arcsec`,
    /// with random-noise dither of `noise_percent` (0 = off).
    ClosedLoop {
        /// Random-noise dither depth, percent (0..=50).
        noise_percent: f64,
    },
}

/// How the turnarounds are latched.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Latch {
    /// At the simulator's exact turnaround (the paper's idealised experiment).
    #[default]
    Exact,
    /// Where the firmware schedules them from the pick-off's edges (what a board does).
    Scheduled,
}

/// The simulated board of a run: the dither, the latch, the sync of the fixed-rate output.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoardSetup {
    /// How the dither is made.
    pub drive: DitherDrive,
    /// How the turnarounds are latched.
    pub latch: Latch,
    /// The sync of the fixed-rate output, Hz (`None`: no output records).
    pub sync_hz: Option<f64>,
    /// The pick-off's gain error against its nominal sensitivity (0 = nominal).
    pub pickoff_gain_error: f64,
    /// The pick-off's lag behind the dither angle, s (0 = in phase).
    pub pickoff_lag_s: f64,
}

impl BoardSetup {
    /// The paper's idealised experiment: the prescribed sine, the exact latch, no sync.
    pub const IDEAL: Self = Self {
        drive: DitherDrive::Ideal,
        latch: Latch::Exact,
        sync_hz: None,
        pickoff_gain_error: 0.0,
        pickoff_lag_s: 0.0,
    };

    /// What a board does: the firmware's drive (random-noise dither of `noise_percent`), the
    /// latch scheduled from the pick-off, the output on a sync at `sync_hz`.
    pub fn board(noise_percent: f64, sync_hz: f64) -> Self {
        Self {
            drive: DitherDrive::ClosedLoop { noise_percent },
            latch: Latch::Scheduled,
            sync_hz: Some(sync_hz),
            pickoff_gain_error: 0.0,
            pickoff_lag_s: 0.0,
        }
    }
}

/// A dither drive alone: the exact latch for the prescribed sine, the scheduled one for the
/// firmware's drive, no sync (the runs before the fixed-rate output existed).
impl From<DitherDrive> for BoardSetup {
    fn from(drive: DitherDrive) -> Self {
        let latch = match drive {
            DitherDrive::Ideal => Latch::Exact,
            DitherDrive::ClosedLoop { .. } => Latch::Scheduled,
        };
        Self {
            drive,
            latch,
            ..Self::IDEAL
        }
    }
}

/// With the firmware's drive, recording starts this long after the drive locks (the locked
/// amplitude loop settles its last 0.2 % in about 2 s), and no earlier than the warm-up.
pub const DRIVE_SETTLE_S: f64 = 2.0;
/// A closed-loop run whose drive has not locked after this long fails.
pub const DRIVE_LOCK_TIMEOUT_S: f64 = 10.0;

/// A harness at a constant input rate on the board `setup` describes, run until it may
/// record: returns it and the time recording may start (the warm-up; with the firmware's
/// drive, [`DRIVE_SETTLE_S`] after the drive locked). The run's noise comes from [`run_seed`].
pub fn start_constant_rate(
    params: &GyroParams,
    setup: BoardSetup,
    rate_deg_h: f64,
    warmup_s: f64,
    settings: CompensationSettings,
) -> Result<(Harness, f64), ExperimentError> {
    let params = GyroParams {
        seed: run_seed(params.seed, rate_deg_h),
        ..*params
    };
    start_run(
        &params,
        setup,
        InputProfile::constant(rate_deg_h),
        warmup_s,
        settings,
    )
}

/// A harness on the board `setup` describes with the input `input` (the seed as `params`
/// gives it), run until it may record, as [`start_constant_rate`]; the gyro's block follows
/// `params.thermal.profile` (a driven resonator's f0 and Q too).
pub fn start_run(
    params: &GyroParams,
    setup: BoardSetup,
    input: InputProfile,
    warmup_s: f64,
    settings: CompensationSettings,
) -> Result<(Harness, f64), ExperimentError> {
    let params = *params;
    let simulator = |e: String| ExperimentError::Simulator(e);
    let (params, source) = match setup.drive {
        DitherDrive::Ideal => (params, None),
        DitherDrive::ClosedLoop { .. } => {
            let c = &params.thermal.coefficients;
            let driven = params
                .with_steady_driven_dither(ResonatorParams {
                    f0_hz: params.dither_hz,
                    temperature: TemperatureDrift {
                        reference_c: c.reference_c,
                        f0_hz_per_c: c.dither_hz_per_c,
                        q_relative_per_c: c.dither_q_per_c,
                        ..TemperatureDrift::NONE
                    },
                    ..ResonatorParams::default()
                })
                .with_temperature(params.thermal.profile);
            let source = DriveSource::firmware(&driven).map_err(|e| simulator(e.to_string()))?;
            (driven, Some(source))
        }
    };
    let mut options = HarnessOptions::new(params, input)
        .compensation(settings)
        .sync_hz(setup.sync_hz);
    if let Some(source) = source {
        options = options.drive(source);
    }
    options.board.pickoff.gain_error = setup.pickoff_gain_error;
    options.board.pickoff.lag_s = setup.pickoff_lag_s;
    if setup.latch == Latch::Scheduled {
        // What a board does: the turnaround instants predicted from the pick-off's edges.
        options = options.latch(LatchTiming::scheduled(0.0));
    }
    let mut harness = options.build().map_err(|e| simulator(e.to_string()))?;
    let mut start_s = warmup_s;
    if let DitherDrive::ClosedLoop { noise_percent } = setup.drive {
        let fw = harness
            .firmware_drive_mut()
            .ok_or_else(|| simulator("no firmware drive".into()))?;
        fw.set_setpoints(
            params.dither_amplitude_arcsec as f32,
            noise_percent as f32,
            params.seed as u32,
        )
        .map_err(|(what, e)| simulator(format!("dither drive {what}: {e:?}")))?;
        while harness
            .firmware_drive()
            .is_some_and(|d| d.controller().state() != DitherState::Locked)
        {
            if harness.time_s() > DRIVE_LOCK_TIMEOUT_S {
                return Err(simulator("the dither drive did not lock".into()));
            }
            harness.step();
        }
        start_s = start_s.max(harness.time_s() + DRIVE_SETTLE_S);
    }
    Ok((harness, start_s))
}

/// Runs the board at a constant input rate (hal-sim's
/// [`Harness`](hal_sim::harness::Harness), firmware in the loop) and hands every cycle closed
/// after the warm-up to `on_cycle` (with the firmware's drive: after the drive has locked and
/// settled, [`DRIVE_SETTLE_S`]), and every output record after it to `on_output`.
pub fn run_constant_rate(
    params: &GyroParams,
    setup: impl Into<BoardSetup>,
    rate_deg_h: f64,
    length: RunLength,
    settings: CompensationSettings,
    mut on_cycle: impl FnMut(&ReadoutConfig, &CycleRecord),
    mut on_output: impl FnMut(&OutputLatch, &OutputRecord),
) -> Result<(), ExperimentError> {
    let (mut harness, start_s) =
        start_constant_rate(params, setup.into(), rate_deg_h, length.warmup_s, settings)?;
    let config = *harness.config();
    let end_s = start_s + length.record_s;
    harness.run_until(end_s, |h, half| {
        for (latch, record) in h.outputs() {
            if latch.t_s > start_s && latch.t_s <= end_s {
                on_output(latch, record);
            }
        }
        let t = half.latch_s();
        if let Some(record) = &half.record {
            if t > start_s && t <= end_s {
                on_cycle(&config, record);
            }
        }
    });
    Ok(())
}

/// How fast the simulated board runs (firmware in the loop: the readout, the dither drive,
/// the fixed-rate output, as `record` runs it, compensation off): `gyro_seconds` at a
/// constant rate timed from the moment the drive has locked and settled (the lock-up itself,
/// a few seconds of gyro time once per run, is not timed).
pub fn measure_board_speed(
    params: &GyroParams,
    setup: BoardSetup,
    rate_deg_h: f64,
    gyro_seconds: f64,
) -> Result<Speed, ExperimentError> {
    let (mut harness, start_s) = start_constant_rate(
        params,
        setup,
        rate_deg_h,
        0.0,
        CompensationSettings::default(),
    )?;
    Ok(Speed::of(gyro_seconds, || {
        harness.run_until(start_s + gyro_seconds, |_, _| {});
    }))
}

/// The paper's Step 2: runs at each calibration rate with compensation off, every cycle after the
/// warm-up fed to the firmware's [`CalibrationSession`] with the board's
/// [`AcceptanceLimits::DEFAULT`] (flagged cycles counted and left out, as on the board); the
/// pooled fit is returned when it passes the board's checks, else [`ExperimentError::Refused`].
pub fn calibrate(
    params: &GyroParams,
    setup: impl Into<BoardSetup>,
    rates_deg_h: &[f64],
    length: RunLength,
) -> Result<FitResult, ExperimentError> {
    let setup = setup.into();
    let mut session = CalibrationSession::new(AcceptanceLimits::DEFAULT);
    for &rate in rates_deg_h {
        let mut cycles = Vec::new();
        run_constant_rate(
            params,
            setup,
            rate,
            length,
            CompensationSettings::default(),
            |config, c| cycles.push((*c, c.duration_s(&config.cycle))),
            |_, _| {},
        )?;
        let count = u32::try_from(cycles.len()).unwrap_or(u32::MAX);
        // A run of no cycle cannot be started on the board either; the fit then has too few.
        if session.start_run(0, count).is_err() {
            return Err(ExperimentError::Refused(Refusal::TooFewCycles));
        }
        for (record, cycle_s) in &cycles[..count as usize] {
            session.on_cycle(record, *cycle_s);
        }
    }
    match session.finish() {
        Ok(SessionState::Ready(fit)) => Ok(fit),
        Ok(SessionState::Refused(reason)) => Err(ExperimentError::Refused(reason)),
        // No run at all (no calibration rate).
        _ => Err(ExperimentError::Refused(Refusal::TooFewCycles)),
    }
}

/// The compensation settings a fit gives (rounded to the Q15.16 format of the flash).
pub fn settings_from_fit(fit: &FitResult) -> Result<CompensationSettings, ExperimentError> {
    let coefficients = Coefficients::from_rad_per_s(fit.a_rad_per_s as f32, fit.b_rad_per_s as f32)
        .map_err(ExperimentError::Coefficients)?;
    Ok(CompensationSettings {
        coefficients,
        enabled: true,
    })
}

/// Output rates of one input rate, fringes/s (= beat frequency, Hz).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MeasuredRate {
    /// Output without the lock-in correction (count plus fractional fringe), fringes/s.
    pub uncompensated_hz: f64,
    /// Output with the lock-in correction subtracted, fringes/s.
    pub compensated_hz: f64,
    /// Dither cycles averaged: every cycle closed after the warm-up.
    pub cycles: u32,
    /// The board's fixed-rate output (stripped and compensated): the least-squares slope of
    /// its integrated angle over the record, fringes/s; `None` without a sync.
    pub output_hz: Option<f64>,
    /// Output records in the window, and how many of them were invalid.
    pub records: u64,
    /// Invalid output records in the window.
    pub invalid_records: u64,
}

impl MeasuredRate {
    /// The compensated output as a user reads it: the fixed-rate output where there is one,
    /// otherwise the per-cycle compensated increments.
    pub fn board_output_hz(&self) -> f64 {
        self.output_hz.unwrap_or(self.compensated_hz)
    }
}

/// One input rate with compensation on: both outputs from the same cycles, each averaged over
/// whole output periods (falling back to the plain mean where it advances less than a fringe).
pub fn measure_rate(
    params: &GyroParams,
    setup: impl Into<BoardSetup>,
    rate_deg_h: f64,
    length: RunLength,
    settings: CompensationSettings,
) -> Result<MeasuredRate, ExperimentError> {
    let mut raw = RateAverager::new();
    let mut compensated = RateAverager::new();
    let mut averager: Option<AveragerConfig> = None;
    let mut slope = SlopeFit::default();
    let (mut records, mut invalid) = (0u64, 0u64);
    let on_output = |latch: &OutputLatch, r: &OutputRecord| {
        records += 1;
        if r.is_valid() {
            slope.push(latch.t_s, r.angle_q16 as f64 / 65536.0);
        } else {
            invalid += 1;
            slope.break_segment();
        }
    };
    let on_cycle = |config: &ReadoutConfig, c: &CycleRecord| {
        let cfg = averager.get_or_insert(AveragerConfig {
            window_cycles: u32::MAX,
            mode: AveragingMode::WholePeriods,
            timer_hz: config.cycle.timer_hz as f64,
            scale_factor_arcsec: params.scale_factor_arcsec,
        });
        let raw_cycle = CycleOutput {
            increment: c.raw_increment,
            correction: PhaseDelta::ZERO,
            ..c.output
        };
        raw.push(cfg, raw_cycle);
        compensated.push(cfg, c.output);
    };
    run_constant_rate(
        params, setup, rate_deg_h, length, settings, on_cycle, on_output,
    )?;
    let cfg = averager
        .ok_or_else(|| ExperimentError::Simulator("no complete dither cycle recorded".into()))?;
    let (u, c) = (raw.flush(&cfg), compensated.flush(&cfg));
    Ok(MeasuredRate {
        uncompensated_hz: u.rate_fringes_per_s,
        compensated_hz: c.rate_fringes_per_s,
        cycles: c.cycles,
        output_hz: slope.slope(),
        records,
        invalid_records: invalid,
    })
}

/// The least-squares slope of a series in contiguous segments, one intercept per segment
/// (a segment ends at an invalid record: the angle of a lost period is not spliced across).
/// Centred sums per segment (Welford), pooled when a segment closes.
#[derive(Clone, Copy, Debug, Default)]
pub struct SlopeFit {
    n: f64,
    mean_t: f64,
    mean_y: f64,
    stt: f64,
    sty: f64,
    pooled_tt: f64,
    pooled_ty: f64,
}

impl SlopeFit {
    /// Adds a point of the current segment.
    pub fn push(&mut self, t: f64, y: f64) {
        self.n += 1.0;
        let dt = t - self.mean_t;
        let dy = y - self.mean_y;
        self.mean_t += dt / self.n;
        self.mean_y += dy / self.n;
        self.stt += dt * (t - self.mean_t);
        self.sty += dt * (y - self.mean_y);
    }

    /// Closes the current segment.
    pub fn break_segment(&mut self) {
        self.pooled_tt += self.stt;
        self.pooled_ty += self.sty;
        *self = Self {
            pooled_tt: self.pooled_tt,
            pooled_ty: self.pooled_ty,
            ..Self::default()
        };
    }

    /// The pooled slope, if any segment had two points.
    pub fn slope(&self) -> Option<f64> {
        let tt = self.pooled_tt + self.stt;
        (tt > 0.0).then(|| (self.pooled_ty + self.sty) / tt)
    }
}
