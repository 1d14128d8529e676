//! Command-line flags: every physical parameter of the simulated gyro, named with its unit.

use clap::{Args, Parser, Subcommand};
use hal_sim::dither::resonator::TemperatureProfile;
use hal_sim::thermal::{GyroThermal, ThermalCoefficients};
use std::path::PathBuf;

pub use rlg_sim::experiment::PAPER_RANGE_DEG_H;

#[derive(Parser, Debug)]
#[command(
    name = "rlg-sim",
    version,
    propagate_version = true,
    about = "Simulated ring laser gyro with the readout firmware's own signal chain in the loop",
    long_about = "Simulates a mechanically dithered ring laser gyro (the phase equation with lock-in, \
sine dither, photodiodes, counter) and runs the board firmware's signal chain on it: fringe \
counting, turnaround sampling, P1/P2, calibration fit and dynamic lock-in compensation.\n\n\
Exit status: 0 on success, 1 when a run fails (e.g. the calibration fit is refused), 2 on bad \
arguments."
)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// The paper's experiment: calibrate outside the dead band, then sweep the input rate and
    /// record the uncompensated (Fig. 3) and compensated (Fig. 4) output.
    Sweep(SweepArgs),
    /// Measure the simulator's speed: simulated gyro-seconds per wall-second on one core.
    Speed(SpeedArgs),
    /// The dither drive: the firmware's controller starts the driven resonator from rest and
    /// holds it (amplitude, resonance, faults); one CSV row per dither cycle.
    Dither(DitherArgs),
    /// The board's fixed-rate output at a constant input rate: calibrates as `sweep` does,
    /// then writes one CSV row per sync period (the board's increment beside the true one).
    Record(RecordArgs),
    /// Overlapping Allan deviation of a recorded rate (a CSV of `rlg-sim record` or `rlg-cal
    /// record`) with confidence intervals, and the IEEE 952 noise terms fitted to it.
    Allan(AllanArgs),
    /// The IEEE Std 647 procedures on the simulated gyro (scale factor, non-linearity,
    /// asymmetry, bias, threshold / dead band, ARW, bias instability) and their report in
    /// --out; --compare runs compensation off, on and random-noise dither side by side.
    Characterize(CharacterizeArgs),
    /// The shell completion script for bash, elvish, fish, powershell or zsh, on stdout.
    Completions(host_cli::completions::CompletionsArgs),
}

/// How the dither is made.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum DitherDrive {
    /// The prescribed sine of --dither-hz and --dither-amplitude-arcsec (the paper's idealised
    /// experiment).
    Ideal,
    /// A driven resonator at --dither-hz (Q 1000) with the firmware's drive in the loop, started
    /// in its steady state; cycles before the drive locks are discarded with the warm-up.
    ClosedLoop,
}

/// How the turnarounds are latched.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum LatchArg {
    /// At the instants the firmware predicts from the pick-off's edges (a real board).
    Scheduled,
    /// At the simulator's exact turnaround (the paper's idealised case).
    Exact,
}

/// `value` inside `lo..=hi`, or an error naming `flag` and the range.
fn in_range(flag: &str, value: f64, lo: f64, hi: f64) -> Result<(), String> {
    if value.is_finite() && (lo..=hi).contains(&value) {
        Ok(())
    } else {
        Err(format!("{flag} must be in {lo}..={hi}, got {value:?}"))
    }
}

impl GyroArgs {
    /// Every physical parameter against its stated range; the message names the flag.
    pub fn validate(&self) -> Result<(), String> {
        in_range("--scale-factor-arcsec", self.scale_factor_arcsec, 0.1, 20.0)?;
        in_range("--dither-hz", self.dither_hz, 200.0, 1500.0)?;
        in_range(
            "--dither-amplitude-arcsec",
            self.dither_amplitude_arcsec,
            50.0,
            800.0,
        )?;
        in_range("--lock-in-deg-h", self.lock_in_deg_h, 0.0, 5000.0)?;
        use std::f64::consts::PI;
        in_range("--eps-rad", self.eps_rad, -PI, PI)?;
        in_range("--arw-deg-rt-h", self.arw_deg_rt_h, 0.0, 1.0)?;
        in_range("--amplitude-jitter", self.amplitude_jitter, 0.0, 0.1)?;
        self.thermal.validate()
    }
}

/// Valid range of the sync rate, Hz.
pub const SYNC_HZ_RANGE: std::ops::RangeInclusive<f64> = 100.0..=2000.0;

#[derive(Args, Debug, Clone)]
pub struct DitherArgs {
    /// Simulated seconds.
    #[arg(long, default_value_t = 5.0, allow_negative_numbers = true)]
    pub seconds: f64,
    /// Resonance f0 at the start, Hz (300..=600).
    #[arg(long, default_value_t = 389.0, allow_negative_numbers = true)]
    pub dither_hz: f64,
    /// Quality factor of the dither resonator (100..=100000).
    #[arg(long, default_value_t = 1000.0, allow_negative_numbers = true)]
    pub q_factor: f64,
    /// The drive's amplitude setpoint, arcsec (50..=650).
    #[arg(long, default_value_t = 450.0, allow_negative_numbers = true)]
    pub dither_amplitude_arcsec: f64,
    /// Linear drift of the resonance over the run, Hz (-10..=10).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub resonance_drift_hz: f64,
    /// The pick-off signal disappears at this time, s.
    #[arg(long, allow_negative_numbers = true)]
    pub pickoff_lost_at_s: Option<f64>,
    /// Random-noise dither: the drive's amplitude randomised every half cycle by this depth,
    /// percent (0..=50).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub dither_noise_percent: f64,
    /// Random seed (pick-off noise, noise dither).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Write one row per dither cycle as CSV (t_s,amplitude_arcsec,resonance_hz,drive_hz,state).
    #[arg(long)]
    pub csv: Option<PathBuf>,
    /// Write amplitude, frequency and state against time as SVG.
    #[arg(long)]
    pub svg: Option<PathBuf>,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
}

/// The gyro and its dither (defaults: the docs/physics.md parameter set, after the paper).
#[derive(Args, Debug, Clone)]
pub struct GyroArgs {
    /// Scale factor, arcsec of input angle per counter pulse (fringe) (0.1..=20).
    #[arg(long, default_value_t = 1.8655, allow_negative_numbers = true)]
    pub scale_factor_arcsec: f64,
    /// Dither frequency, Hz (200..=1500: the board's scheduler range).
    #[arg(long, default_value_t = 389.0, allow_negative_numbers = true)]
    pub dither_hz: f64,
    /// Dither peak amplitude, arcsec (50..=800: the pick-off saturates at 819).
    #[arg(long, default_value_t = 450.0, allow_negative_numbers = true)]
    pub dither_amplitude_arcsec: f64,
    /// Lock-in threshold Omega_L, deg/h (0..=5000).
    #[arg(long, default_value_t = 200.0, allow_negative_numbers = true)]
    pub lock_in_deg_h: f64,
    /// Photodiode phase offset eps, rad (-pi..=pi).
    #[arg(long, default_value_t = 0.3, allow_negative_numbers = true)]
    pub eps_rad: f64,
    /// Angle random walk, deg/sqrt(h) (0..=1; 0 = no noise).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub arw_deg_rt_h: f64,
    /// Relative rms of smooth dither amplitude jitter, 0.1-2 Hz (0..=0.1; 0 = steady dither):
    /// of the prescribed sine's amplitude, or with --dither-drive closed-loop of the drive's
    /// gain, which the firmware's amplitude loop then holds the amplitude against.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub amplitude_jitter: f64,
    /// Random seed (same seed, same output).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    #[command(flatten)]
    pub thermal: ThermalArgs,
}

/// The gyro block's temperature and what it does (docs/physics.md section 13; the defaults
/// are the published figures it cites). Without --temperature-profile the block stays at
/// --thermal-reference-c, where none of them acts.
#[derive(Args, Debug, Clone)]
pub struct ThermalArgs {
    /// The block's temperature over the run: constant:<C> | ramp:<from C>:<to C>:<C per min>
    /// | steps:<C>,<C>,...:<hold s> | warmup:<from C>:<to C>:<tau s> | knots:<t s>/<C>,...
    /// (temperatures -55..=150 C, ramps 0.01..=600 C/min, holds and tau 1..=360000 s; times
    /// from the start of the simulation).
    #[arg(long, value_parser = rlg_sim::thermal::profile_arg::parse)]
    pub temperature_profile: Option<hal_sim::dither::resonator::TemperatureProfile>,
    /// T_ref: the temperature at which every thermal effect is zero, C (-150..=150).
    #[arg(long, default_value_t = ThermalCoefficients::DEFAULT.reference_c, allow_negative_numbers = true)]
    pub thermal_reference_c: f64,
    /// Bias b1, deg/h per C (-1..=1).
    #[arg(long, default_value_t = ThermalCoefficients::DEFAULT.bias_deg_h_per_c, allow_negative_numbers = true)]
    pub thermal_bias_deg_h_per_c: f64,
    /// Bias b2, deg/h per C^2 (-0.01..=0.01).
    #[arg(long, default_value_t = ThermalCoefficients::DEFAULT.bias_deg_h_per_c2, allow_negative_numbers = true)]
    pub thermal_bias_deg_h_per_c2: f64,
    /// Bias rate term, deg/h per C/min of dT/dt (-1..=1).
    #[arg(long, default_value_t = ThermalCoefficients::DEFAULT.bias_deg_h_per_c_per_min, allow_negative_numbers = true)]
    pub thermal_bias_deg_h_per_c_per_min: f64,
    /// Scale-factor error s1, ppm per C (-100..=100).
    #[arg(long, default_value_t = ThermalCoefficients::DEFAULT.scale_factor_ppm_per_c, allow_negative_numbers = true)]
    pub thermal_sf_ppm_per_c: f64,
    /// Scale-factor error s2, ppm per C^2 (-1..=1).
    #[arg(long, default_value_t = ThermalCoefficients::DEFAULT.scale_factor_ppm_per_c2, allow_negative_numbers = true)]
    pub thermal_sf_ppm_per_c2: f64,
    /// Lock-in threshold Omega_L, relative change per C (-0.01..=0.01).
    #[arg(long, default_value_t = ThermalCoefficients::DEFAULT.lock_in_per_c, allow_negative_numbers = true)]
    pub thermal_lock_in_per_c: f64,
    /// Photodiode phase eps, rad per C (-0.05..=0.05).
    #[arg(long, default_value_t = ThermalCoefficients::DEFAULT.eps_rad_per_c, allow_negative_numbers = true)]
    pub thermal_eps_rad_per_c: f64,
    /// Pick-off gain, relative change per C (-0.01..=0.01).
    #[arg(long, default_value_t = ThermalCoefficients::DEFAULT.pickoff_gain_per_c, allow_negative_numbers = true)]
    pub thermal_pickoff_gain_per_c: f64,
    /// Dither resonance f0 (with --dither-drive closed-loop), Hz per C (-1..=1).
    #[arg(long, default_value_t = ThermalCoefficients::DEFAULT.dither_hz_per_c, allow_negative_numbers = true)]
    pub thermal_dither_hz_per_c: f64,
    /// Dither resonator Q (with --dither-drive closed-loop), relative change per C
    /// (-0.1..=0.1).
    #[arg(long, default_value_t = ThermalCoefficients::DEFAULT.dither_q_per_c, allow_negative_numbers = true)]
    pub thermal_dither_q_per_c: f64,
}

impl ThermalArgs {
    /// The coefficients the flags give.
    pub fn coefficients(&self) -> ThermalCoefficients {
        ThermalCoefficients {
            reference_c: self.thermal_reference_c,
            bias_deg_h_per_c: self.thermal_bias_deg_h_per_c,
            bias_deg_h_per_c2: self.thermal_bias_deg_h_per_c2,
            bias_deg_h_per_c_per_min: self.thermal_bias_deg_h_per_c_per_min,
            scale_factor_ppm_per_c: self.thermal_sf_ppm_per_c,
            scale_factor_ppm_per_c2: self.thermal_sf_ppm_per_c2,
            lock_in_per_c: self.thermal_lock_in_per_c,
            eps_rad_per_c: self.thermal_eps_rad_per_c,
            pickoff_gain_per_c: self.thermal_pickoff_gain_per_c,
            dither_hz_per_c: self.thermal_dither_hz_per_c,
            dither_q_per_c: self.thermal_dither_q_per_c,
        }
    }

    /// The block: the profile (or T_ref throughout) and the coefficients.
    pub fn gyro_thermal(&self) -> GyroThermal {
        let coefficients = self.coefficients();
        GyroThermal {
            profile: self
                .temperature_profile
                .unwrap_or(TemperatureProfile::constant(coefficients.reference_c)),
            coefficients,
        }
    }

    /// Every coefficient in its range; the message names the flag.
    pub fn validate(&self) -> Result<(), String> {
        let limit = hal_sim::thermal::LIMITS.reference_c;
        in_range(
            "--thermal-reference-c",
            self.thermal_reference_c,
            -limit,
            limit,
        )?;
        for (name, value, limit) in self.coefficients().each() {
            in_range(&format!("--thermal-{name}"), value, -limit, limit)?;
        }
        Ok(())
    }
}

#[derive(Args, Debug, Clone)]
pub struct SweepArgs {
    #[command(flatten)]
    pub gyro: GyroArgs,
    /// Lowest input rate, deg/h (-1e6..=1e6).
    #[arg(long, default_value_t = -PAPER_RANGE_DEG_H, allow_negative_numbers = true)]
    pub rate_min_deg_h: f64,
    /// Highest input rate, deg/h (-1e6..=1e6).
    #[arg(long, default_value_t = PAPER_RANGE_DEG_H, allow_negative_numbers = true)]
    pub rate_max_deg_h: f64,
    /// Number of input rates, evenly spaced from min to max (1..=10000).
    #[arg(long, default_value_t = 41)]
    pub points: usize,
    /// Simulated seconds recorded per input rate, after the warm-up (0.001..=36000).
    #[arg(long, default_value_t = 10.0, allow_negative_numbers = true)]
    pub seconds_per_point: f64,
    /// Simulated seconds discarded before recording, lets the Lissajous fit settle (0..=60).
    #[arg(long, default_value_t = 0.5, allow_negative_numbers = true)]
    pub warmup_seconds: f64,
    #[command(flatten)]
    pub calibration: CalibrationArgs,
    /// Write the table as CSV (input_deg_h,ideal_hz,uncompensated_hz,compensated_hz).
    #[arg(long)]
    pub csv: Option<PathBuf>,
    /// Write the figure (both curves and the residuals) as SVG.
    #[arg(long)]
    pub svg: Option<PathBuf>,
    #[command(flatten)]
    pub board: BoardArgs,
    /// Worker threads (default: all cores).
    #[arg(long)]
    pub jobs: Option<usize>,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
}

impl SweepArgs {
    /// The input rates of the sweep.
    pub fn rates_deg_h(&self) -> Vec<f64> {
        if self.points <= 1 {
            return vec![0.5 * (self.rate_min_deg_h + self.rate_max_deg_h)];
        }
        let step = (self.rate_max_deg_h - self.rate_min_deg_h) / (self.points - 1) as f64;
        (0..self.points)
            .map(|i| self.rate_min_deg_h + step * i as f64)
            .collect()
    }

    /// Checks what clap cannot: ranges and finite values. The message names the flag.
    pub fn validate(&self) -> Result<(), String> {
        let finite = [
            ("--rate-min-deg-h", self.rate_min_deg_h),
            ("--rate-max-deg-h", self.rate_max_deg_h),
            ("--seconds-per-point", self.seconds_per_point),
            ("--warmup-seconds", self.warmup_seconds),
        ];
        for (flag, v) in finite {
            if !v.is_finite() {
                return Err(format!("{flag} must be a finite number, got {v}"));
            }
        }
        in_range("--rate-min-deg-h", self.rate_min_deg_h, -1e6, 1e6)?;
        in_range("--rate-max-deg-h", self.rate_max_deg_h, -1e6, 1e6)?;
        in_range(
            "--seconds-per-point",
            self.seconds_per_point,
            1e-3,
            36_000.0,
        )?;
        in_range("--warmup-seconds", self.warmup_seconds, 0.0, 60.0)?;
        if self.points > 10_000 {
            return Err(format!(
                "--points must be in 1..=10000, got {}",
                self.points
            ));
        }
        if self.rate_max_deg_h < self.rate_min_deg_h {
            return Err("--rate-max-deg-h must not be below --rate-min-deg-h".into());
        }
        if self.points == 0 {
            return Err("--points must be at least 1".into());
        }
        if self.seconds_per_point <= 0.0 {
            return Err("--seconds-per-point must be positive".into());
        }
        if self.warmup_seconds < 0.0 {
            return Err("--warmup-seconds must not be negative".into());
        }
        self.calibration.validate()?;
        self.board.validate()
    }
}

/// How the board is calibrated before it measures: the paper's Step 2 (`sweep` and `record`
/// share it).
#[derive(Args, Debug, Clone)]
pub struct CalibrationArgs {
    /// Input rates of the calibration runs, deg/h (repeat the flag; default +-13.888, both ends
    /// of the paper's range, outside the dead band).
    #[arg(long, allow_negative_numbers = true, num_args = 1)]
    pub calibration_rate_deg_h: Vec<f64>,
    /// Simulated seconds per calibration run.
    #[arg(long, default_value_t = 20.0, allow_negative_numbers = true)]
    pub calibration_seconds: f64,
}

impl CalibrationArgs {
    /// The calibration rates, defaulting to both ends of the paper's range.
    pub fn rates_deg_h(&self) -> Vec<f64> {
        if self.calibration_rate_deg_h.is_empty() {
            vec![-PAPER_RANGE_DEG_H, PAPER_RANGE_DEG_H]
        } else {
            self.calibration_rate_deg_h.clone()
        }
    }

    /// Finite rates, a positive duration.
    pub fn validate(&self) -> Result<(), String> {
        if !(self.calibration_seconds.is_finite() && self.calibration_seconds > 0.0) {
            return Err(format!(
                "--calibration-seconds must be positive, got {}",
                self.calibration_seconds
            ));
        }
        if let Some(bad) = self.calibration_rate_deg_h.iter().find(|r| !r.is_finite()) {
            return Err(format!(
                "--calibration-rate-deg-h must be finite, got {bad}"
            ));
        }
        Ok(())
    }
}

/// The simulated board: its dither, its latch, its sync (`sweep` and `record` share it).
#[derive(Args, Debug, Clone)]
pub struct BoardArgs {
    /// How the dither is made: the firmware's drive in the loop (what a board does), or the
    /// prescribed sine (the paper's idealised experiment, with --latch exact).
    #[arg(long, value_enum, default_value_t = DitherDrive::ClosedLoop)]
    pub dither_drive: DitherDrive,
    /// How the turnarounds are latched: where the firmware schedules them from the pick-off
    /// (what a board does), or at the simulator's exact turnaround (the paper's idealised case).
    #[arg(long, value_enum, default_value_t = LatchArg::Scheduled)]
    pub latch: LatchArg,
    /// Rate of the sync pulses that end the board's fixed-rate output periods, Hz
    /// (100..=2000).
    #[arg(long, default_value_t = 1000.0, allow_negative_numbers = true)]
    pub sync_hz: f64,
    /// Random-noise dither depth, percent (0..=50; needs --dither-drive closed-loop: the noise
    /// dither is the firmware drive's).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub dither_noise_percent: f64,
    /// The pick-off's gain error against its nominal 0.4 arcsec per code (-0.2..=0.2): the
    /// stripping fits it.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub pickoff_gain_error: f64,
    /// The pick-off's lag behind the dither angle, us (0..=100): the stripping's second tap
    /// fits it.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub pickoff_lag_us: f64,
}

impl BoardArgs {
    /// Ranges, and the combinations that make sense.
    pub fn validate(&self) -> Result<(), String> {
        if !(0.0..=50.0).contains(&self.dither_noise_percent) {
            return Err("--dither-noise-percent must be in 0..=50".into());
        }
        if !SYNC_HZ_RANGE.contains(&self.sync_hz) {
            return Err(format!(
                "--sync-hz must be in 100..=2000 Hz, got {}",
                self.sync_hz
            ));
        }
        if !(-0.2..=0.2).contains(&self.pickoff_gain_error) {
            return Err(format!(
                "--pickoff-gain-error must be in -0.2..=0.2, got {}",
                self.pickoff_gain_error
            ));
        }
        if !(0.0..=100.0).contains(&self.pickoff_lag_us) {
            return Err(format!(
                "--pickoff-lag-us must be in 0..=100 us, got {}",
                self.pickoff_lag_us
            ));
        }
        if self.dither_noise_percent > 0.0 && self.dither_drive == DitherDrive::Ideal {
            return Err(
                "--dither-noise-percent needs --dither-drive closed-loop (the noise dither is \
                 the firmware drive's)"
                    .into(),
            );
        }
        Ok(())
    }
}

/// `rlg-sim record`: the board's fixed-rate output at a constant rate.
#[derive(Args, Debug, Clone)]
pub struct RecordArgs {
    #[command(flatten)]
    pub gyro: GyroArgs,
    #[command(flatten)]
    pub board: BoardArgs,
    #[command(flatten)]
    pub calibration: CalibrationArgs,
    /// Constant input rate, deg/h (-1e6..=1e6).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub rate_deg_h: f64,
    /// Simulated seconds recorded after the warm-up (0 < s <= 360000: 100 h).
    #[arg(long, default_value_t = 10.0, allow_negative_numbers = true)]
    pub seconds: f64,
    /// Simulated seconds discarded before recording (0..=60).
    #[arg(long, default_value_t = 0.5, allow_negative_numbers = true)]
    pub warmup_seconds: f64,
    /// Output CSV (t_s,delta_angle_arcsec,true_delta_angle_arcsec,valid, and temperature_c
    /// with --temperature-profile: the block's temperature the record carries), one row per
    /// sync period, written as the rows come.
    #[arg(long)]
    pub csv: PathBuf,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
}

impl RecordArgs {
    /// Ranges; the message names the flag.
    pub fn validate(&self) -> Result<(), String> {
        if !(self.rate_deg_h.is_finite() && self.rate_deg_h.abs() <= 1e6) {
            return Err(format!(
                "--rate-deg-h must be in -1e6..=1e6, got {}",
                self.rate_deg_h
            ));
        }
        if !(self.seconds.is_finite() && self.seconds > 0.0 && self.seconds <= 360_000.0) {
            return Err(format!(
                "--seconds must be in (0, 360000], got {}",
                self.seconds
            ));
        }
        if !(self.warmup_seconds.is_finite() && (0.0..=60.0).contains(&self.warmup_seconds)) {
            return Err(format!(
                "--warmup-seconds must be in 0..=60, got {}",
                self.warmup_seconds
            ));
        }
        self.calibration.validate()?;
        self.board.validate()
    }
}

#[derive(Args, Debug, Clone)]
pub struct SpeedArgs {
    #[command(flatten)]
    pub gyro: GyroArgs,
    /// Input rate, deg/h.
    #[arg(long, default_value_t = 5.0, allow_negative_numbers = true)]
    pub rate_deg_h: f64,
    /// Simulated seconds to time.
    #[arg(long, default_value_t = 5.0, allow_negative_numbers = true)]
    pub seconds: f64,
    /// Time the simulated board (firmware in the loop, closed-loop drive, 1 kHz output, as
    /// `record` runs it) instead of the bare gyro; timed once the drive has locked.
    #[arg(long)]
    pub board: bool,
}

/// `rlg-sim allan`: the Allan deviation of a recorded rate.
#[derive(Args, Debug, Clone)]
pub struct AllanArgs {
    /// The record: a CSV with the columns t_s and delta_angle_arcsec, and optionally valid
    /// (rows with valid 0 or no angle are gaps), as `rlg-sim record` and `rlg-cal record`
    /// write it.
    #[arg(long)]
    pub input: PathBuf,
    /// Two-sided confidence of the intervals (0.5..=0.999).
    #[arg(long, default_value_t = 0.95, allow_negative_numbers = true)]
    pub confidence: f64,
    /// Fit the noise terms to the taus from this one on, s (0..=1e6; 0: every tau). A dithered
    /// gyro's output holds what is left of the dither at taus of a few dither periods, which is
    /// none of the IEEE 952 noises: the default, 0.03 s, is ten periods of a 330 Hz dither.
    #[arg(long, default_value_t = 0.03, allow_negative_numbers = true)]
    pub min_fit_tau_s: f64,
    /// Write the deviation as CSV (tau_s,adev_deg_h,ci_low_deg_h,ci_high_deg_h).
    #[arg(long)]
    pub csv: Option<PathBuf>,
    /// Write the log-log plot (deviation, intervals, fitted terms and their slopes) as SVG.
    #[arg(long)]
    pub svg: Option<PathBuf>,
}

impl AllanArgs {
    /// Ranges; the message names the flag.
    pub fn validate(&self) -> Result<(), String> {
        let range = rlg_sim::allan::CONFIDENCE_RANGE;
        in_range(
            "--confidence",
            self.confidence,
            *range.start(),
            *range.end(),
        )?;
        in_range("--min-fit-tau-s", self.min_fit_tau_s, 0.0, 1e6)
    }
}

/// Compensation on or off.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum OnOff {
    /// Calibrated first (the paper's Step 2), then applied.
    On,
    /// Not applied (no calibration).
    Off,
}

/// `rlg-sim characterize`: the IEEE 647 procedures and their report.
#[derive(Args, Debug, Clone)]
pub struct CharacterizeArgs {
    #[command(flatten)]
    pub gyro: GyroArgs,
    #[command(flatten)]
    pub board: BoardArgs,
    #[command(flatten)]
    pub calibration: CalibrationArgs,
    /// The report's folder (created if missing): report.md, scale_factor.csv,
    /// static_<configuration>.csv, allan_<configuration>.csv and the SVG figures.
    #[arg(long)]
    pub out: PathBuf,
    /// Run three configurations side by side: compensation off, compensation on, and
    /// random-noise dither (the firmware drive's, compensation off). Needs --dither-drive
    /// closed-loop and --dither-noise-percent 0.
    #[arg(long)]
    pub compare: bool,
    /// Without --compare: compensation on (calibrated first) or off.
    #[arg(long, value_enum, default_value_t = OnOff::On)]
    pub compensation: OnOff,
    /// Also IEEE 647's bias and scale factor over temperature: the thermal calibration (ramps
    /// -20..+60 C, soaks with the table at +-10 deg/s), then its check on another ramp and
    /// eight soaks with the model off and on (thermal.csv, thermal.svg, a report section;
    /// about 900 gyro-seconds; --temperature-profile does not apply to it; the coefficient
    /// flags do).
    #[arg(long)]
    pub thermal: bool,
    /// With --compare: the random-noise dither's depth, percent of the drive amplitude
    /// (1..=50; at 10 % the resonator smooths it too much to fill the dead band in 5 s).
    #[arg(long, default_value_t = 25.0, allow_negative_numbers = true)]
    pub compare_noise_percent: f64,
    /// Largest input rate magnitude, deg/s (0.1..=300; the default set's dither peaks at
    /// 305 deg/s; a rate at which the board closes no dither cycle is an error).
    #[arg(long, default_value_t = rlg_sim::characterize::Plan::DEFAULT.max_rate_deg_s, allow_negative_numbers = true)]
    pub max_rate_deg_s: f64,
    /// Log-spaced linear-range rates per sign (2..=50).
    #[arg(long, default_value_t = rlg_sim::characterize::Plan::DEFAULT.range_points)]
    pub range_points: usize,
    /// Rates near zero per sign, inside and outside the dead band (2..=50).
    #[arg(long, default_value_t = rlg_sim::characterize::Plan::DEFAULT.dense_points)]
    pub dense_points: usize,
    /// Simulated seconds recorded per input rate (0.5..=3600).
    #[arg(long, default_value_t = rlg_sim::characterize::Plan::DEFAULT.seconds_per_point, allow_negative_numbers = true)]
    pub seconds_per_point: f64,
    /// Simulated seconds discarded before each recording (0..=60).
    #[arg(long, default_value_t = rlg_sim::characterize::Plan::DEFAULT.warmup_s, allow_negative_numbers = true)]
    pub warmup_seconds: f64,
    /// Simulated seconds of the static (zero-input) record (10..=360000).
    #[arg(long, default_value_t = rlg_sim::characterize::Plan::DEFAULT.static_s, allow_negative_numbers = true)]
    pub static_seconds: f64,
    /// Two-sided confidence of the noise terms' intervals (0.5..=0.999).
    #[arg(long, default_value_t = rlg_sim::characterize::Plan::DEFAULT.confidence, allow_negative_numbers = true)]
    pub confidence: f64,
    /// Worker threads (default: all cores).
    #[arg(long)]
    pub jobs: Option<usize>,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
}

impl CharacterizeArgs {
    /// The plan these flags describe.
    pub fn plan(&self) -> rlg_sim::characterize::Plan {
        rlg_sim::characterize::Plan {
            max_rate_deg_s: self.max_rate_deg_s,
            range_points: self.range_points,
            dense_points: self.dense_points,
            seconds_per_point: self.seconds_per_point,
            warmup_s: self.warmup_seconds,
            static_s: self.static_seconds,
            confidence: self.confidence,
        }
    }

    /// Ranges and combinations; the message names the flag.
    pub fn validate(&self) -> Result<(), String> {
        self.plan().validate()?;
        in_range(
            "--compare-noise-percent",
            self.compare_noise_percent,
            1.0,
            50.0,
        )?;
        if self.jobs == Some(0) {
            return Err("--jobs must be at least 1".into());
        }
        if self.compare {
            if self.board.dither_drive != DitherDrive::ClosedLoop {
                return Err(
                    "--compare needs --dither-drive closed-loop (the random-noise \
                            dither is the firmware drive's)"
                        .into(),
                );
            }
            if self.board.dither_noise_percent != 0.0 {
                return Err(
                    "--compare runs its own noise dither (--compare-noise-percent): \
                            --dither-noise-percent must be 0"
                        .into(),
                );
            }
        }
        self.calibration.validate()?;
        self.board.validate()
    }
}
