//! Command-line arguments.

use clap::{Args, Parser, Subcommand, ValueEnum};
use rlg_cal::ranges;
use std::path::PathBuf;

const AFTER_HELP: &str = "\
Connections (one of, before the subcommand):
  --port /dev/ttyUSB0 --baud 460800    a serial port, or a pty served by `rlg-cal serve-sim --pty`
  --tcp 127.0.0.1:7878                 the simulated board served by `rlg-cal serve-sim --tcp`
  --sim                                a simulated board inside this process (for trying things;
                                       its key: $RLG_SIM_BOARD_KEY, else the --key given)

Examples:
  rlg-cal --tcp 127.0.0.1:7878 status
  rlg-cal --tcp 127.0.0.1:7878 --key $KEY set a 344.25
  rlg-cal --port /dev/ttyUSB0 --key $KEY calibrate --cycles 4000 --warmup 400 --accept --store
  rlg-cal --port /dev/ttyUSB0 send key provision $KEY   (production, once per board)
  rlg-cal serve-sim --tcp 127.0.0.1:7878 --board-key $KEY
  rlg-cal --port /dev/ttyUSB0 --baud 460800 stream --seconds 10 --csv run.csv --svg run.svg
  rlg-cal sweep --calibrate --svg sweep.svg
  rlg-cal serve-sim --pty

Exit status:
  0  success
  1  the board answered ERR, or a run failed (fit refused, calibration made no progress)
  2  usage error (bad arguments)
  3  connection failed, no answer within the timeout, or a corrupted answer (bad CRC)";

/// Host tool for the ring-laser-gyro readout board's calibration protocol.
///
/// Every command goes out with its CRC suffix and gets exactly one checked answer. Results go
/// to stdout (`key=value`), progress and errors to stderr.
#[derive(Debug, Parser)]
#[command(name = "rlg-cal", version, after_help = AFTER_HELP)]
pub struct Cli {
    #[command(flatten)]
    pub connection: ConnectionArgs,
    /// Unlock key (32 hex digits) sent before protected commands (set, comp, track, store, reload,
    /// defaults, calibrate).
    #[arg(long, value_name = "KEY")]
    pub key: Option<String>,
    /// How long to wait for an answer, ms.
    #[arg(long, default_value_t = 2000, value_name = "MS", value_parser = ranges::timeout_ms, allow_negative_numbers = true)]
    pub timeout_ms: u64,
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Debug, Args)]
pub struct ConnectionArgs {
    /// Serial port or pty.
    #[arg(long, value_name = "PATH")]
    pub port: Option<String>,
    /// Baud rate of --port.
    #[arg(long, default_value_t = 115_200, value_name = "N", value_parser = ranges::baud, allow_negative_numbers = true)]
    pub baud: u32,
    /// A board served on TCP.
    #[arg(long, value_name = "HOST:PORT")]
    pub tcp: Option<String>,
    /// A simulated board in this process (its state lasts for this invocation).
    #[arg(long)]
    pub sim: bool,
    /// Input rate of the --sim board, deg/h.
    #[arg(
        long,
        default_value_t = 13.888,
        value_name = "DEG_H",
        value_parser = ranges::rate_deg_h,
        allow_negative_numbers = true
    )]
    pub sim_rate: f64,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Which {
    A,
    B,
    Coeffs,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Coefficient {
    A,
    B,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum OnOff {
    On,
    Off,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum RateFrom {
    Stream,
    Status,
}

#[derive(Debug, Subcommand)]
pub enum Command {
    /// Firmware version, build, board, gyro serial number, scale factor.
    Id,
    /// Signal health, dither, rate, glitch counters, compensation, coefficient source, lock.
    Status,
    /// Coefficient a, b (rad/s), or both with lock-in and eps.
    Get {
        #[arg(value_enum, default_value = "coeffs")]
        which: Which,
    },
    /// Sets a or b (rad/s); prints the value applied after fixed-point rounding. Protected.
    Set {
        #[arg(value_enum)]
        which: Coefficient,
        #[arg(allow_negative_numbers = true, value_parser = finite_or_not)]
        value: String,
    },
    /// Lock-in compensation on or off. Protected.
    Comp {
        #[arg(value_enum)]
        state: OnOff,
    },
    /// Online tracking of a and b on or off. Protected.
    Track {
        #[arg(value_enum)]
        state: OnOff,
    },
    /// Unlocks protected commands (the board locks again after 5 minutes idle and at reset).
    Unlock { key: String },
    /// Locks at once.
    Lock,
    /// Writes the coefficients in force to flash (pauses the readout). Protected.
    Store,
    /// Loads the newest valid calibration from flash. Protected.
    Reload,
    /// Back to the default coefficients (unsaved until `store`). Protected.
    Defaults,
    /// Runs a calibration with a progress bar, prints the fit; optionally accepts and stores.
    Calibrate(CalibrateArgs),
    /// Streams per-cycle frames to CSV (and an SVG plot of the rate); reports lost frames.
    Stream(StreamArgs),
    /// Sends any protocol line (e.g. `cal abort`, `help`) and prints the answer.
    Send {
        #[arg(required = true, num_args = 1.., allow_hyphen_values = true)]
        words: Vec<String>,
    },
    /// Rotary-table sweep on a simulated board in this process (no connection needed).
    Sweep(SweepArgs),
    /// Serves a simulated board on TCP or a pty, in (scaled) real time.
    ServeSim(ServeArgs),
}

#[derive(Debug, Args)]
pub struct CalibrateArgs {
    /// Dither cycles in the fit.
    #[arg(long, default_value_t = 4000, value_parser = ranges::cal_cycles, allow_negative_numbers = true)]
    pub cycles: u32,
    /// Cycles discarded first.
    #[arg(long, default_value_t = 400, value_parser = ranges::warmup_cycles, allow_negative_numbers = true)]
    pub warmup: u32,
    /// Apply the fit (`cal accept`) when it passes.
    #[arg(long)]
    pub accept: bool,
    /// Then write it to flash (`store`).
    #[arg(long, requires = "accept")]
    pub store: bool,
    /// Between two `cal status` polls, ms.
    #[arg(long, default_value_t = 250, value_name = "MS", value_parser = ranges::poll_ms, allow_negative_numbers = true)]
    pub poll_ms: u64,
}

#[derive(Debug, Args)]
pub struct StreamArgs {
    /// How long to stream, s.
    #[arg(long, value_parser = ranges::seconds, allow_negative_numbers = true)]
    pub seconds: f64,
    /// One row per streamed cycle.
    #[arg(long, value_name = "PATH")]
    pub csv: PathBuf,
    /// Plot of the rate averaged per second.
    #[arg(long, value_name = "PATH")]
    pub svg: Option<PathBuf>,
    /// Stream every n-th cycle (1 = every cycle; needs about 18 kB/s at 389 Hz).
    #[arg(long, default_value_t = 1, value_parser = ranges::divider, allow_negative_numbers = true)]
    pub divider: u16,
    /// Override the capture-timer frequency the board reports in `id`, Hz.
    #[arg(long, value_parser = ranges::timer_hz, allow_negative_numbers = true)]
    pub timer_hz: Option<f64>,
}

#[derive(Debug, Args)]
pub struct SweepArgs {
    /// Latitude of the rotary table, deg.
    #[arg(long, default_value_t = 22.2, value_parser = ranges::latitude_deg, allow_negative_numbers = true)]
    pub latitude: f64,
    /// Table azimuths, deg (comma-separated).
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "0,30,60,90,120,150,180,210,240,270,300,330",
        value_parser = ranges::azimuth_deg,
        allow_negative_numbers = true
    )]
    pub azimuths: Vec<f64>,
    /// Settling time after the dither drive has locked (the board waits for that first), s:
    /// the locked amplitude loop takes about 2 s to settle the last 0.2 %.
    #[arg(long, default_value_t = 3.0, value_parser = ranges::settle_s, allow_negative_numbers = true)]
    pub settle: f64,
    /// Measuring time per azimuth, s.
    #[arg(long, default_value_t = 5.0, value_parser = ranges::seconds, allow_negative_numbers = true)]
    pub seconds: f64,
    /// Where the rate is read.
    #[arg(long, value_enum, default_value = "stream")]
    pub rate_from: RateFrom,
    /// Stream every n-th cycle.
    #[arg(long, default_value_t = 1, value_parser = ranges::divider, allow_negative_numbers = true)]
    pub divider: u16,
    /// Calibrate first (through the protocol), accept and store.
    #[arg(long)]
    pub calibrate: bool,
    /// Azimuth of the calibration run, deg.
    #[arg(long, default_value_t = 0.0, value_parser = ranges::azimuth_deg, allow_negative_numbers = true)]
    pub cal_azimuth: f64,
    #[arg(long, default_value_t = 3000, value_parser = ranges::cal_cycles, allow_negative_numbers = true)]
    pub cal_cycles: u32,
    #[arg(long, default_value_t = 100, value_parser = ranges::warmup_cycles, allow_negative_numbers = true)]
    pub cal_warmup: u32,
    /// One row per azimuth.
    #[arg(long, value_name = "PATH")]
    pub csv: Option<PathBuf>,
    /// Measured and expected rate over azimuth.
    #[arg(long, value_name = "PATH")]
    pub svg: Option<PathBuf>,
    /// Seed of the simulated gyro.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

#[derive(Debug, Args)]
pub struct ServeArgs {
    /// Listen on this TCP address (port 0: any free port; the address is printed).
    #[arg(
        long,
        value_name = "HOST:PORT",
        required_unless_present = "pty",
        conflicts_with = "pty"
    )]
    pub tcp: Option<String>,
    /// Serve on a new pty; its path is printed on stdout.
    #[arg(long)]
    pub pty: bool,
    /// Simulated seconds per wall-clock second.
    #[arg(long, default_value_t = 1.0, value_parser = ranges::speed, allow_negative_numbers = true)]
    pub speed: f64,
    /// Constant input rate, deg/h (unless --azimuth is given).
    #[arg(long, default_value_t = 13.888, value_parser = ranges::rate_deg_h, allow_negative_numbers = true)]
    pub rate: f64,
    /// Rotary table: Earth rate at this azimuth, deg (with --latitude).
    #[arg(long, value_parser = ranges::azimuth_deg, allow_negative_numbers = true)]
    pub azimuth: Option<f64>,
    #[arg(long, default_value_t = 22.2, value_parser = ranges::latitude_deg, allow_negative_numbers = true)]
    pub latitude: f64,
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Stop after this many wall-clock seconds (default: run until killed).
    #[arg(long, value_parser = ranges::seconds, allow_negative_numbers = true)]
    pub seconds: Option<f64>,
    /// The simulated board's key, 32 hex digits (default: $RLG_SIM_BOARD_KEY; neither: the
    /// board starts unprovisioned, as a new board).
    #[arg(long, value_name = "KEY")]
    pub board_key: Option<String>,
}

/// Any number the board's parser may see: the board itself says what it refuses (NaN,
/// infinities, out of range), so only non-numbers are caught here.
fn finite_or_not(s: &str) -> Result<String, String> {
    s.parse::<f32>()
        .map(|_| s.to_owned())
        .map_err(|_| format!("not a number: {s}"))
}
