//! Command-line flags: every physical parameter of the simulated gyro, named with its unit.
//!
//! Defaults are read from the library's parameter sets (`GyroParams::DEFAULT`, ...), ranges
//! from the `Range` constants of [`crate::flag_ranges`]: clap's value parser refuses a value
//! outside (exit 2, the range in the message) and the help prints the same constant. The
//! `validate` methods check only what involves two flags.
//!
//! One file for the flags of every subcommand (over 600 lines): the shared groups (`GyroArgs`,
//! `BoardArgs`, `ThermalArgs`) and the subcommands that flatten them are read together.

use clap::{Args, Parser, Subcommand};
use hal_sim::dither::resonator::TemperatureProfile;
use hal_sim::params::GyroParams;
use hal_sim::thermal::{profile_text, GyroThermal, ThermalCoefficients};
use host_cli::exit;
use rlg_sim::characterize::{self, Plan};
use rlg_sim::dither_run::{self, DitherRunOptions};
use rlg_sim::experiment::WARMUP_SECONDS;
use std::path::PathBuf;

use crate::flag_ranges::*;

pub use rlg_sim::experiment::PAPER_RANGE_DEG_H;

/// The exit statuses `rlg-sim` gives (`host_cli::exit`), in its words.
const EXIT_STATUSES: [(u8, &str); 4] = [
    (
        exit::SUCCESS,
        "success, also when the reader of stdout goes away (`| head`)",
    ),
    (
        exit::FAILED,
        "a run failed (e.g. the calibration fit is refused, a file not written)",
    ),
    (
        exit::USAGE,
        "usage error (bad arguments, an output file that cannot be created)",
    ),
    (
        exit::INTERRUPTED,
        "stopped by Ctrl-C or SIGTERM, after what was done is written",
    ),
];

/// `rlg-sim --help`'s description, with the exit statuses.
fn long_about() -> String {
    format!(
        "Simulates a mechanically dithered ring laser gyro (the phase equation with lock-in, \
         sine dither, photodiodes, counter) and runs the board firmware's signal chain on it: \
         fringe counting, turnaround sampling, P1/P2, calibration fit and dynamic lock-in \
         compensation.\n\n{}",
        exit::help(&EXIT_STATUSES)
    )
}

#[derive(Parser, Debug)]
#[command(
    name = "rlg-sim",
    version,
    propagate_version = true,
    about = "Simulated ring laser gyro with the readout firmware's own signal chain in the loop",
    long_about = long_about()
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

#[derive(Args, Debug, Clone)]
pub struct DitherArgs {
    #[arg(long, default_value_t = DitherRunOptions::DEFAULT.seconds, allow_negative_numbers = true,
        value_parser = dither_run::SECONDS.parser(),
        help = dither_run::SECONDS.help("Simulated seconds"))]
    pub seconds: f64,
    #[arg(long, default_value_t = DitherRunOptions::DEFAULT.resonance_hz, allow_negative_numbers = true,
        value_parser = dither_run::RESONANCE_HZ.parser(),
        help = dither_run::RESONANCE_HZ.help_why("Resonance f0 at the start",
            "inside the drive's start-up search"))]
    pub dither_hz: f64,
    #[arg(long, default_value_t = DitherRunOptions::DEFAULT.q_factor, allow_negative_numbers = true,
        value_parser = dither_run::Q_FACTOR.parser(),
        help = dither_run::Q_FACTOR.help("Quality factor of the dither resonator"))]
    pub q_factor: f64,
    #[arg(long, default_value_t = DitherRunOptions::DEFAULT.setpoint_arcsec, allow_negative_numbers = true,
        value_parser = dither_run::setpoint_arcsec_range().parser(),
        help = dither_run::setpoint_arcsec_range().help_why("The drive's amplitude setpoint",
            "the firmware's setpoint range"))]
    pub dither_amplitude_arcsec: f64,
    #[arg(long, default_value_t = DitherRunOptions::DEFAULT.resonance_drift_hz, allow_negative_numbers = true,
        value_parser = dither_run::RESONANCE_DRIFT_HZ.parser(),
        help = dither_run::RESONANCE_DRIFT_HZ.help("Linear drift of the resonance over the run"))]
    pub resonance_drift_hz: f64,
    /// The pick-off signal disappears at this time, s.
    #[arg(long, allow_negative_numbers = true)]
    pub pickoff_lost_at_s: Option<f64>,
    #[arg(long, default_value_t = DitherRunOptions::DEFAULT.noise_percent, allow_negative_numbers = true,
        value_parser = dither_run::NOISE_PERCENT.parser(),
        help = dither_run::NOISE_PERCENT.help("Random-noise dither: the drive's amplitude \
            randomised every half cycle by this depth"))]
    pub dither_noise_percent: f64,
    /// Random seed (pick-off noise, noise dither).
    #[arg(long, default_value_t = DitherRunOptions::DEFAULT.seed)]
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
    #[arg(long, default_value_t = GyroParams::DEFAULT.scale_factor_arcsec, allow_negative_numbers = true,
        value_parser = SCALE_FACTOR_ARCSEC.parser(),
        help = SCALE_FACTOR_ARCSEC.help("Scale factor, arcsec of input angle per counter pulse (fringe)"))]
    pub scale_factor_arcsec: f64,
    #[arg(long, default_value_t = GyroParams::DEFAULT.dither_hz, allow_negative_numbers = true,
        value_parser = DITHER_HZ.parser(),
        help = DITHER_HZ.help_why("Dither frequency", "the board's scheduler range"))]
    pub dither_hz: f64,
    #[arg(long, default_value_t = GyroParams::DEFAULT.dither_amplitude_arcsec, allow_negative_numbers = true,
        value_parser = DITHER_AMPLITUDE_ARCSEC.parser(),
        help = DITHER_AMPLITUDE_ARCSEC.help_why("Dither peak amplitude",
            "the pick-off saturates at 819 arcsec"))]
    pub dither_amplitude_arcsec: f64,
    #[arg(long, default_value_t = GyroParams::DEFAULT.lock_in_deg_per_h, allow_negative_numbers = true,
        value_parser = LOCK_IN_DEG_H.parser(),
        help = LOCK_IN_DEG_H.help("Lock-in threshold Omega_L"))]
    pub lock_in_deg_h: f64,
    #[arg(long, default_value_t = GyroParams::DEFAULT.eps_rad, allow_negative_numbers = true,
        value_parser = EPS_RAD.parser(),
        help = EPS_RAD.help("Photodiode phase offset eps"))]
    pub eps_rad: f64,
    #[arg(long, default_value_t = GyroParams::DEFAULT.arw_deg_per_rt_h, allow_negative_numbers = true,
        value_parser = ARW_DEG_RT_H.parser(),
        help = ARW_DEG_RT_H.help_why("Angle random walk", "0 = no noise"))]
    pub arw_deg_rt_h: f64,
    #[arg(long, default_value_t = GyroParams::DEFAULT.amplitude_jitter.relative_rms, allow_negative_numbers = true,
        value_parser = AMPLITUDE_JITTER.parser(),
        help = AMPLITUDE_JITTER.help_why("Relative rms of smooth dither amplitude jitter, 0.1-2 Hz, \
            of the prescribed sine's amplitude or, with --dither-drive closed-loop, of the drive's \
            gain, which the firmware's amplitude loop then holds the amplitude against",
            "0 = steady dither"))]
    pub amplitude_jitter: f64,
    /// Random seed (same seed, same output).
    #[arg(long, default_value_t = GyroParams::DEFAULT.seed)]
    pub seed: u64,
    #[command(flatten)]
    pub thermal: ThermalArgs,
}

/// The gyro block's temperature and what it does (docs/physics.md section 13; the defaults
/// are the published figures it cites). Without --temperature-profile the block stays at
/// --thermal-reference-c, where none of them acts.
#[derive(Args, Debug, Clone)]
pub struct ThermalArgs {
    #[arg(long, value_parser = |s: &str| profile_text::parse_flag("--temperature-profile", s),
        help = profile_text::help("The block's temperature over the run"))]
    pub temperature_profile: Option<hal_sim::dither::resonator::TemperatureProfile>,
    #[arg(long, default_value_t = ThermalCoefficients::DEFAULT.reference_c, allow_negative_numbers = true,
        value_parser = THERMAL_REFERENCE_C.parser(), help = THERMAL_REFERENCE_C.help("T_ref: the temperature at which every thermal effect is zero"))]
    pub thermal_reference_c: f64,
    #[arg(long, default_value_t = ThermalCoefficients::DEFAULT.bias_deg_h_per_c, allow_negative_numbers = true,
        value_parser = THERMAL_BIAS_DEG_H_PER_C.parser(), help = THERMAL_BIAS_DEG_H_PER_C.help("Bias b1"))]
    pub thermal_bias_deg_h_per_c: f64,
    #[arg(long, default_value_t = ThermalCoefficients::DEFAULT.bias_deg_h_per_c2, allow_negative_numbers = true,
        value_parser = THERMAL_BIAS_DEG_H_PER_C2.parser(), help = THERMAL_BIAS_DEG_H_PER_C2.help("Bias b2"))]
    pub thermal_bias_deg_h_per_c2: f64,
    #[arg(long, default_value_t = ThermalCoefficients::DEFAULT.bias_deg_h_per_c_per_min, allow_negative_numbers = true,
        value_parser = THERMAL_BIAS_DEG_H_PER_C_PER_MIN.parser(), help = THERMAL_BIAS_DEG_H_PER_C_PER_MIN.help("Bias rate term, of dT/dt"))]
    pub thermal_bias_deg_h_per_c_per_min: f64,
    #[arg(long, default_value_t = ThermalCoefficients::DEFAULT.scale_factor_ppm_per_c, allow_negative_numbers = true,
        value_parser = THERMAL_SF_PPM_PER_C.parser(), help = THERMAL_SF_PPM_PER_C.help("Scale-factor error s1"))]
    pub thermal_sf_ppm_per_c: f64,
    #[arg(long, default_value_t = ThermalCoefficients::DEFAULT.scale_factor_ppm_per_c2, allow_negative_numbers = true,
        value_parser = THERMAL_SF_PPM_PER_C2.parser(), help = THERMAL_SF_PPM_PER_C2.help("Scale-factor error s2"))]
    pub thermal_sf_ppm_per_c2: f64,
    #[arg(long, default_value_t = ThermalCoefficients::DEFAULT.lock_in_per_c, allow_negative_numbers = true,
        value_parser = THERMAL_LOCK_IN_PER_C.parser(), help = THERMAL_LOCK_IN_PER_C.help("Lock-in threshold Omega_L, relative change"))]
    pub thermal_lock_in_per_c: f64,
    #[arg(long, default_value_t = ThermalCoefficients::DEFAULT.eps_rad_per_c, allow_negative_numbers = true,
        value_parser = THERMAL_EPS_RAD_PER_C.parser(), help = THERMAL_EPS_RAD_PER_C.help("Photodiode phase eps"))]
    pub thermal_eps_rad_per_c: f64,
    #[arg(long, default_value_t = ThermalCoefficients::DEFAULT.pickoff_gain_per_c, allow_negative_numbers = true,
        value_parser = THERMAL_PICKOFF_GAIN_PER_C.parser(), help = THERMAL_PICKOFF_GAIN_PER_C.help("Pick-off gain, relative change"))]
    pub thermal_pickoff_gain_per_c: f64,
    #[arg(long, default_value_t = ThermalCoefficients::DEFAULT.dither_hz_per_c, allow_negative_numbers = true,
        value_parser = THERMAL_DITHER_HZ_PER_C.parser(), help = THERMAL_DITHER_HZ_PER_C.help("Dither resonance f0, with --dither-drive closed-loop"))]
    pub thermal_dither_hz_per_c: f64,
    #[arg(long, default_value_t = ThermalCoefficients::DEFAULT.dither_q_per_c, allow_negative_numbers = true,
        value_parser = THERMAL_DITHER_Q_PER_C.parser(), help = THERMAL_DITHER_Q_PER_C.help("Dither resonator Q, with --dither-drive closed-loop, relative change"))]
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
}

#[derive(Args, Debug, Clone)]
pub struct SweepArgs {
    #[command(flatten)]
    pub gyro: GyroArgs,
    #[arg(long, default_value_t = -PAPER_RANGE_DEG_H, allow_negative_numbers = true,
        value_parser = RATE_DEG_H.parser(), help = RATE_DEG_H.help("Lowest input rate"))]
    pub rate_min_deg_h: f64,
    #[arg(long, default_value_t = PAPER_RANGE_DEG_H, allow_negative_numbers = true,
        value_parser = RATE_DEG_H.parser(), help = RATE_DEG_H.help("Highest input rate"))]
    pub rate_max_deg_h: f64,
    #[arg(long, default_value_t = 41, allow_negative_numbers = true,
        value_parser = SWEEP_POINTS.parser(),
        help = SWEEP_POINTS.help("Number of input rates, evenly spaced from min to max"))]
    pub points: usize,
    #[arg(long, default_value_t = 10.0, allow_negative_numbers = true,
        value_parser = SWEEP_SECONDS_PER_POINT.parser(),
        help = SWEEP_SECONDS_PER_POINT.help("Simulated seconds recorded per input rate, after the warm-up"))]
    pub seconds_per_point: f64,
    #[arg(long, default_value_t = 0.5, allow_negative_numbers = true,
        value_parser = WARMUP_SECONDS.parser(),
        help = WARMUP_SECONDS.help("Simulated seconds discarded before recording, lets the Lissajous fit settle"))]
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

    /// Checks what involves two flags (clap's parsers check each one's range). The message
    /// names the flags.
    pub fn validate(&self) -> Result<(), String> {
        if self.rate_max_deg_h < self.rate_min_deg_h {
            return Err("--rate-max-deg-h must not be below --rate-min-deg-h".into());
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
    #[arg(long, default_value_t = 1000.0, allow_negative_numbers = true,
        value_parser = SYNC_HZ.parser(),
        help = SYNC_HZ.help("Rate of the sync pulses that end the board's fixed-rate output periods"))]
    pub sync_hz: f64,
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true,
        value_parser = dither_run::NOISE_PERCENT.parser(),
        help = dither_run::NOISE_PERCENT.help_why("Random-noise dither depth",
            "needs --dither-drive closed-loop: the noise dither is the firmware drive's"))]
    pub dither_noise_percent: f64,
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true,
        value_parser = PICKOFF_GAIN_ERROR.parser(),
        help = PICKOFF_GAIN_ERROR.help_why("The pick-off's relative gain error against its \
            nominal sensitivity", "the stripping fits it"))]
    pub pickoff_gain_error: f64,
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true,
        value_parser = PICKOFF_LAG_US.parser(),
        help = PICKOFF_LAG_US.help_why("The pick-off's lag behind the dither angle",
            "the stripping's second tap fits it"))]
    pub pickoff_lag_us: f64,
}

impl BoardArgs {
    /// The combinations that make sense (clap's parsers check each flag's range).
    pub fn validate(&self) -> Result<(), String> {
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
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true,
        value_parser = RATE_DEG_H.parser(), help = RATE_DEG_H.help("Constant input rate"))]
    pub rate_deg_h: f64,
    #[arg(long, default_value_t = 10.0, allow_negative_numbers = true,
        value_parser = RECORD_SECONDS.parser(),
        help = RECORD_SECONDS.help_why("Simulated seconds recorded after the warm-up", "100 h"))]
    pub seconds: f64,
    #[arg(long, default_value_t = 0.5, allow_negative_numbers = true,
        value_parser = WARMUP_SECONDS.parser(),
        help = WARMUP_SECONDS.help("Simulated seconds discarded before recording"))]
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
    /// The calibration's and the board's checks (clap's parsers check each flag's range).
    pub fn validate(&self) -> Result<(), String> {
        self.calibration.validate()?;
        self.board.validate()
    }
}

#[derive(Args, Debug, Clone)]
pub struct SpeedArgs {
    #[command(flatten)]
    pub gyro: GyroArgs,
    #[arg(long, default_value_t = 5.0, allow_negative_numbers = true,
        value_parser = RATE_DEG_H.parser(), help = RATE_DEG_H.help("Input rate"))]
    pub rate_deg_h: f64,
    #[arg(long, default_value_t = 5.0, allow_negative_numbers = true,
        value_parser = SPEED_SECONDS.parser(), help = SPEED_SECONDS.help("Simulated seconds to time"))]
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
    #[arg(long, default_value_t = 0.95, allow_negative_numbers = true,
        value_parser = rlg_sim::allan::CONFIDENCE.parser(),
        help = rlg_sim::allan::CONFIDENCE.help("Two-sided confidence of the intervals"))]
    pub confidence: f64,
    #[arg(long, default_value_t = 0.03, allow_negative_numbers = true,
        value_parser = MIN_FIT_TAU_S.parser(),
        help = MIN_FIT_TAU_S.help_why("Fit the noise terms to the taus from this one on. A \
            dithered gyro's output holds what is left of the dither at taus of a few dither \
            periods, which is none of the IEEE 952 noises: the default is ten periods of a \
            330 Hz dither", "0: every tau"))]
    pub min_fit_tau_s: f64,
    /// Write the deviation as CSV (tau_s,adev_deg_h,ci_low_deg_h,ci_high_deg_h).
    #[arg(long)]
    pub csv: Option<PathBuf>,
    /// Write the log-log plot (deviation, intervals, fitted terms and their slopes) as SVG.
    #[arg(long)]
    pub svg: Option<PathBuf>,
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
    #[arg(long, default_value_t = 25.0, allow_negative_numbers = true,
        value_parser = COMPARE_NOISE_PERCENT.parser(),
        help = COMPARE_NOISE_PERCENT.help_why("With --compare: the random-noise dither's depth, \
            percent of the drive amplitude", "at 10 % the resonator smooths it too much to fill \
            the dead band in 5 s"))]
    pub compare_noise_percent: f64,
    #[arg(long, default_value_t = Plan::DEFAULT.max_rate_deg_s, allow_negative_numbers = true,
        value_parser = characterize::MAX_RATE_DEG_S.parser(),
        help = characterize::MAX_RATE_DEG_S.help_why("Largest input rate magnitude",
            "the default set's dither peaks at 305 deg/s; a rate at which the board closes no \
            dither cycle is an error"))]
    pub max_rate_deg_s: f64,
    #[arg(long, default_value_t = Plan::DEFAULT.range_points, allow_negative_numbers = true,
        value_parser = characterize::RANGE_POINTS.parser(),
        help = characterize::RANGE_POINTS.help("Log-spaced linear-range rates per sign"))]
    pub range_points: usize,
    #[arg(long, default_value_t = Plan::DEFAULT.dense_points, allow_negative_numbers = true,
        value_parser = characterize::DENSE_POINTS.parser(),
        help = characterize::DENSE_POINTS.help("Rates near zero per sign, inside and outside the \
            dead band"))]
    pub dense_points: usize,
    #[arg(long, default_value_t = Plan::DEFAULT.seconds_per_point, allow_negative_numbers = true,
        value_parser = characterize::SECONDS_PER_POINT.parser(),
        help = characterize::SECONDS_PER_POINT.help("Simulated seconds recorded per input rate"))]
    pub seconds_per_point: f64,
    #[arg(long, default_value_t = Plan::DEFAULT.warmup_s, allow_negative_numbers = true,
        value_parser = WARMUP_SECONDS.parser(),
        help = WARMUP_SECONDS.help("Simulated seconds discarded before each recording"))]
    pub warmup_seconds: f64,
    #[arg(long, default_value_t = Plan::DEFAULT.static_s, allow_negative_numbers = true,
        value_parser = characterize::STATIC_SECONDS.parser(),
        help = characterize::STATIC_SECONDS.help("Simulated seconds of the static (zero-input) \
            record"))]
    pub static_seconds: f64,
    #[arg(long, default_value_t = Plan::DEFAULT.confidence, allow_negative_numbers = true,
        value_parser = rlg_sim::allan::CONFIDENCE.parser(),
        help = rlg_sim::allan::CONFIDENCE.help("Two-sided confidence of the noise terms' intervals"))]
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
    pub fn plan(&self) -> Plan {
        Plan {
            max_rate_deg_s: self.max_rate_deg_s,
            range_points: self.range_points,
            dense_points: self.dense_points,
            seconds_per_point: self.seconds_per_point,
            warmup_s: self.warmup_seconds,
            static_s: self.static_seconds,
            confidence: self.confidence,
        }
    }

    /// The combinations (clap's parsers check each flag's range); the message names the flag.
    pub fn validate(&self) -> Result<(), String> {
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
