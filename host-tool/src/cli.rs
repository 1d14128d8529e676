//! Command-line arguments, and where the connection and the key come from.
//!
//! The connection options, the key, `--timeout-ms` and `--json` are global: they may stand
//! before or after the subcommand. What is not on the command line comes from the environment
//! (`RLG_PORT`, `RLG_TCP`, `RLG_BAUD`, `RLG_KEY`, `RLG_SIM_STATE`; the command line wins), read
//! here by hand rather than by clap's `env` so that `serve-sim` and `sweep`, which run their
//! own board, never pick up a connection from the environment. The baud rate defaults to the
//! board's own ([`SERIAL_BAUD`], the firmware's constant).
//!
//! Size (over 600 lines): every subcommand's flags, with their ranges and help, read together; the
//! ranges are in `ranges.rs`, what each subcommand does in `board_commands.rs`.

use clap::{Args, Parser, Subcommand, ValueEnum};
use firmware::protocol::SERIAL_BAUD;
use host_cli::exit;
use rlg_cal::ranges;
use std::path::PathBuf;

#[cfg(feature = "sim")]
use hal_sim::thermal::{profile_text, ThermalCoefficients};

/// A temperature profile of the simulated gyro block (`--sim-temperature-profile`,
/// `serve-sim --temperature-profile`), parsed by hal-sim's one parser; in a build without the
/// simulated board, the text (the simulated board's subcommands and `--sim` are refused then).
#[cfg(feature = "sim")]
pub type ProfileArg = hal_sim::dither::resonator::TemperatureProfile;
#[cfg(not(feature = "sim"))]
pub type ProfileArg = String;

const AFTER_HELP: &str = "\
Connections (one of, before or after the subcommand):
  --port /dev/ttyUSB0                  a serial port (default 460800 Bd, the board's), or a pty
                                       served by `rlg-cal serve-sim --pty`
  --tcp 127.0.0.1:7878                 the simulated board served by `rlg-cal serve-sim --tcp`
  --sim                                a simulated board inside this process; with
                                       --sim-state FILE it lasts from one call to the next
                                       (its key: $RLG_SIM_BOARD_KEY, else the key given)

Environment (used when the command line does not say):
  RLG_PORT, RLG_TCP, RLG_BAUD          the connection
  RLG_KEY                              the unlock key, 32 hex digits (or --key-file FILE; no
                                       key is taken on the command line, where the process
                                       list and the shell history would show it)
  RLG_SIM_STATE                        the --sim board's state file
  RLG_SIM_BOARD_KEY                    the key of a simulated board (--sim, serve-sim; or
                                       serve-sim --board-key-file FILE)

Examples:
  rlg-cal --tcp 127.0.0.1:7878 status
  RLG_TCP=127.0.0.1:7878 RLG_KEY=$KEY rlg-cal set a 344.25
  rlg-cal console --tcp 127.0.0.1:7878
  rlg-cal --port /dev/ttyUSB0 --key-file key.txt calibrate --cycles 4000 --warmup 400 --accept --store
  rlg-cal --port /dev/ttyUSB0 --key-file key.txt key-provision   (production, once per board)
  rlg-cal serve-sim --tcp 127.0.0.1:7878 --board-key-file key.txt
  rlg-cal --port /dev/ttyUSB0 stream --seconds 10 --csv run.csv --svg run.svg
  rlg-cal --port /dev/ttyUSB0 record --seconds 600 --csv output.csv
  rlg-cal --port /dev/ttyUSB0 --key-file key.txt thermal --seconds 14400 --input-rate-deg-h 13.888 \
      --table-rate-deg-h 36000 --csv chamber.csv --apply --store
  rlg-cal --sim --sim-state board.state --key-file key.txt store
  rlg-cal sweep --calibrate --svg sweep.svg
  rlg-cal serve-sim --pty

Long runs (stream, calibrate, record, thermal, sweep) check their output files, the key and the
board (`id`) before they start. Ctrl-C (or SIGTERM) stops them cleanly: a stream keeps every frame received
in its CSV and draws its SVG, a calibration is aborted on the board (`cal abort`), a sweep keeps
the azimuths done; the summary is printed (exit status below).";

/// The exit statuses `rlg-cal` gives (`host_cli::exit`), in its words.
const EXIT_STATUSES: [(u8, &str); 5] = [
    (
        exit::SUCCESS,
        "success, also when the reader of stdout goes away (`| head`)",
    ),
    (
        exit::FAILED,
        "the board answered ERR, or a run failed (fit refused, calibration made no progress)",
    ),
    (
        exit::USAGE,
        "usage error (bad arguments, an output file that cannot be created, no key for a \
         protected step)",
    ),
    (
        exit::CONNECTION,
        "connection failed, no answer within the timeout, a corrupted answer (bad CRC), or the \
         board received a garbled command (ERR 6/7/8)",
    ),
    (exit::INTERRUPTED, "stopped by Ctrl-C or SIGTERM"),
];

/// The text after the options in `rlg-cal --help`.
fn after_help() -> String {
    format!("{AFTER_HELP}\n\n{}", exit::help(&EXIT_STATUSES))
}

/// Host tool for the ring-laser-gyro readout board's calibration protocol.
///
/// Every command goes out with its CRC suffix and gets exactly one checked answer. Results go
/// to stdout (`key=value` lines, or one JSON object per command with `--json`), progress and
/// errors to stderr.
#[derive(Debug, Parser)]
#[command(name = "rlg-cal", version, propagate_version = true, after_help = after_help())]
pub struct Cli {
    #[command(flatten)]
    pub connection: ConnectionArgs,
    /// Refused: a key on the command line shows in the process list and the shell history.
    #[arg(long, value_name = "KEY", global = true, hide = true)]
    pub key: Option<String>,
    /// A file holding the unlock key, 32 hex digits on its first line (or RLG_KEY). The key is
    /// sent before protected commands (set, comp, track, store, reload, defaults, calibrate).
    #[arg(long, value_name = "PATH", global = true)]
    pub key_file: Option<PathBuf>,
    #[arg(
        long,
        default_value_t = 2000,
        value_name = "MS",
        global = true,
        value_parser = ranges::TIMEOUT_MS.parser(),
        allow_negative_numbers = true,
        help = ranges::TIMEOUT_MS.help("How long to wait for an answer")
    )]
    pub timeout_ms: u64,
    /// Results as one JSON object per command (for scripts) instead of `key=value` lines.
    #[arg(long, global = true)]
    pub json: bool,
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Debug, Args)]
pub struct ConnectionArgs {
    /// Serial port or pty (or RLG_PORT).
    #[arg(long, value_name = "PATH", global = true)]
    pub port: Option<String>,
    #[arg(
        long,
        value_name = "N",
        global = true,
        value_parser = ranges::BAUD.parser(),
        allow_negative_numbers = true,
        help = ranges::BAUD.help_why("Baud rate of --port, or RLG_BAUD",
            &format!("default: the board's, {SERIAL_BAUD}"))
    )]
    pub baud: Option<u32>,
    /// A board served on TCP (or RLG_TCP); for `serve-sim`, the address to listen on.
    #[arg(long, value_name = "HOST:PORT", global = true)]
    pub tcp: Option<String>,
    /// A simulated board in this process. Without --sim-state it lasts for this call only.
    #[arg(long, global = true)]
    #[cfg_attr(not(feature = "sim"), arg(hide = true))]
    pub sim: bool,
    #[arg(
        long,
        default_value_t = 13.888,
        value_name = "DEG_H",
        value_parser = ranges::SIM_RATE_DEG_H.parser(),
        allow_negative_numbers = true,
        global = true,
        help = ranges::SIM_RATE_DEG_H.help("Input rate of the --sim board")
    )]
    #[cfg_attr(not(feature = "sim"), arg(hide = true))]
    pub sim_rate: f64,
    #[arg(long, value_name = "PROFILE", global = true)]
    #[cfg_attr(feature = "sim", arg(
        value_parser = |s: &str| profile_text::parse_flag("--sim-temperature-profile", s),
        help = profile_text::help(&format!("The --sim board's block temperature, from its \
            power-up (each call powers it up; default: {} C, where no thermal effect acts)",
            ThermalCoefficients::DEFAULT.reference_c))))]
    #[cfg_attr(not(feature = "sim"), arg(hide = true))]
    pub sim_temperature_profile: Option<ProfileArg>,
    /// The --sim board's state file (or RLG_SIM_STATE): read at start, written at exit. What
    /// lasts: the flash (stored calibrations, boot count) and the settings in force (a, b,
    /// compensation on/off, dither amplitude and noise). What does not: the unlock, a
    /// calibration run, tracking and the stream (each call is a reset of the board).
    #[arg(long, value_name = "PATH", global = true)]
    #[cfg_attr(not(feature = "sim"), arg(hide = true))]
    pub sim_state: Option<PathBuf>,
}

/// Where the commands go, resolved from the command line and the environment.
#[derive(Clone, Debug, PartialEq)]
pub enum Target {
    /// A serial port or pty at this baud rate.
    Port { path: String, baud: u32 },
    /// TCP.
    Tcp(String),
    /// The simulated board in this process, with its state file if any.
    Sim { state: Option<PathBuf> },
}

impl ConnectionArgs {
    /// Whether a connection was given on the command line.
    pub fn given(&self) -> bool {
        self.port.is_some() || self.tcp.is_some() || self.sim
    }

    /// The connection: the command line's, else the environment's (`env` looks a variable
    /// up); exactly one. The error is a usage message.
    pub fn resolve(&self, env: &dyn Fn(&str) -> Option<String>) -> Result<Target, String> {
        let from_line = self.given();
        let port = if from_line {
            self.port.clone()
        } else {
            env("RLG_PORT")
        };
        let tcp = if from_line {
            self.tcp.clone()
        } else {
            env("RLG_TCP")
        };
        let chosen = port.is_some() as u8 + tcp.is_some() as u8 + self.sim as u8;
        if chosen != 1 {
            return Err(format!(
                "give exactly one connection: --port PATH, --tcp HOST:PORT or --sim \
                 (or RLG_PORT / RLG_TCP){}",
                if chosen > 1 {
                    "; got more than one"
                } else {
                    ""
                }
            ));
        }
        if let Some(path) = port {
            let baud = match (self.baud, env("RLG_BAUD")) {
                (Some(baud), _) => baud,
                (None, Some(text)) => ranges::BAUD
                    .parse(&text)
                    .map_err(|e| format!("RLG_BAUD: {e}"))?,
                (None, None) => SERIAL_BAUD,
            };
            return Ok(Target::Port { path, baud });
        }
        if let Some(address) = tcp {
            return Ok(Target::Tcp(address));
        }
        let state = self
            .sim_state
            .clone()
            .or_else(|| env("RLG_SIM_STATE").map(PathBuf::from));
        Ok(Target::Sim { state })
    }
}

/// The usage error for a key given on the command line (`flag`); the key is not repeated.
pub fn key_on_command_line(flag: &str, instead: &str) -> String {
    format!(
        "{flag} takes no key: a key on the command line shows in the process list and the \
         shell history; give it with {instead}"
    )
}

/// The key on the first line of the file at `path` (surrounding blanks dropped).
pub fn read_key_file(path: &std::path::Path) -> Result<String, String> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| format!("cannot read the key file {}: {e}", path.display()))?;
    let key = text.lines().next().unwrap_or("").trim();
    if key.is_empty() {
        return Err(format!("the key file {} is empty", path.display()));
    }
    Ok(key.to_owned())
}

impl Cli {
    /// The unlock key: the first line of `--key-file`, else `RLG_KEY`; `--key` is refused.
    /// The error is a usage message.
    pub fn resolve_key(
        &self,
        env: &dyn Fn(&str) -> Option<String>,
    ) -> Result<Option<String>, String> {
        if self.key.is_some() {
            return Err(key_on_command_line("--key", "--key-file PATH or RLG_KEY"));
        }
        if let Some(path) = &self.key_file {
            return read_key_file(path).map(Some);
        }
        Ok(env("RLG_KEY")
            .filter(|k| !k.trim().is_empty())
            .map(|k| k.trim().to_owned()))
    }
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
    /// Unlocks protected commands with the key of --key-file or RLG_KEY (the board locks
    /// again after 5 minutes idle, at reset, and when a served board gets a new client).
    Unlock {
        /// Refused: a key on the command line shows in the process list.
        #[arg(hide = true)]
        key: Option<String>,
    },
    /// Production, once per board: writes the key of --key-file or RLG_KEY to the board's
    /// one-time-programmable memory (`key provision`; refused on a board that has a key).
    KeyProvision,
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
    /// Record the board's fixed-rate output (`stream output`): one CSV row per output period,
    /// lost records marked; rows go to disk as they come, Ctrl-C keeps them.
    Record(RecordArgs),
    /// Thermal calibration: records the fixed-rate output with the block's temperature while
    /// the chamber runs its ramps or steps, fits the thermal model (bias; the scale factor too
    /// with --table-rate-deg-h) with its checks and prints it; --apply puts it in force,
    /// --store writes it to flash. Protected with --apply.
    Thermal(ThermalArgs),
    /// An interactive console: line editing, history, completion of command names (Tab); the
    /// CRC is added to each line and every answer shown, an error with its code in words.
    Console,
    /// Sends any protocol line (e.g. `cal abort`, `help`) and prints the answer; not `unlock`
    /// or `key provision`, whose key would stand on the command line (`rlg-cal unlock`,
    /// `rlg-cal key-provision` take it from --key-file or RLG_KEY).
    Send {
        #[arg(required = true, num_args = 1.., allow_hyphen_values = true)]
        words: Vec<String>,
    },
    /// Rotary-table sweep on a simulated board in this process (no connection needed).
    #[cfg_attr(not(feature = "sim"), command(hide = true))]
    Sweep(SweepArgs),
    /// Serves a simulated board on TCP or a pty, in (scaled) real time.
    #[cfg_attr(not(feature = "sim"), command(hide = true))]
    ServeSim(Box<ServeArgs>),
    /// The shell completion script for bash, elvish, fish, powershell or zsh, on stdout.
    Completions(host_cli::completions::CompletionsArgs),
}

#[derive(Debug, Args)]
pub struct CalibrateArgs {
    #[arg(long, default_value_t = 4000, allow_negative_numbers = true,
        value_parser = ranges::CAL_CYCLES.parser(),
        help = ranges::CAL_CYCLES.help("Dither cycles in the fit"))]
    pub cycles: u32,
    #[arg(long, default_value_t = 400, allow_negative_numbers = true,
        value_parser = ranges::WARMUP_CYCLES.parser(),
        help = ranges::WARMUP_CYCLES.help("Cycles discarded first"))]
    pub warmup: u32,
    /// Apply the fit (`cal accept`) when it passes.
    #[arg(long)]
    pub accept: bool,
    /// Then write it to flash (`store`).
    #[arg(long, requires = "accept")]
    pub store: bool,
    #[arg(long, default_value_t = 250, value_name = "MS", allow_negative_numbers = true,
        value_parser = ranges::POLL_MS.parser(),
        help = ranges::POLL_MS.help("Between two `cal status` polls"))]
    pub poll_ms: u64,
}

#[derive(Debug, Args)]
pub struct StreamArgs {
    #[arg(long, allow_negative_numbers = true, value_parser = ranges::SECONDS.parser(),
        help = ranges::SECONDS.help("How long to stream"))]
    pub seconds: f64,
    /// One row per streamed cycle.
    #[arg(long, value_name = "PATH")]
    pub csv: PathBuf,
    /// Plot of the rate averaged per second.
    #[arg(long, value_name = "PATH")]
    pub svg: Option<PathBuf>,
    #[arg(long, default_value_t = 1, allow_negative_numbers = true,
        value_parser = ranges::DIVIDER.parser(),
        help = ranges::DIVIDER.help_why("Stream every n-th cycle",
            "1 = every cycle, needs about 18 kB/s at 389 Hz"))]
    pub divider: u16,
    #[arg(long, allow_negative_numbers = true, value_parser = ranges::TIMER_HZ.parser(),
        help = ranges::TIMER_HZ.help("Override the capture-timer frequency the board reports in `id`"))]
    pub timer_hz: Option<f64>,
}

/// `rlg-cal record`: the board's fixed-rate output.
#[derive(Debug, Args)]
pub struct RecordArgs {
    #[arg(long, allow_negative_numbers = true, value_parser = ranges::RECORD_SECONDS.parser(),
        help = ranges::RECORD_SECONDS.help("How long to record"))]
    pub seconds: f64,
    /// One row per output record (t_s,delta_angle_arcsec,valid,sequence,status), lost records
    /// as rows with valid 0 and no angle.
    #[arg(long, value_name = "PATH")]
    pub csv: PathBuf,
    #[arg(long, allow_negative_numbers = true, value_parser = ranges::TIMER_HZ.parser(),
        help = ranges::TIMER_HZ.help("Override the capture-timer frequency the board reports in `id`"))]
    pub timer_hz: Option<f64>,
}

/// `rlg-cal thermal`: the thermal calibration (docs/protocol.md, `rlg_cal::thermal`).
#[derive(Debug, Args)]
pub struct ThermalArgs {
    #[arg(long, allow_negative_numbers = true, value_parser = ranges::THERMAL_SECONDS.parser(),
        help = ranges::THERMAL_SECONDS.help("How long to record: the chamber's whole run"))]
    pub seconds: f64,
    #[arg(long, allow_negative_numbers = true, value_parser = ranges::INPUT_RATE_DEG_H.parser(),
        help = ranges::INPUT_RATE_DEG_H.help_why("The gyro's true input at rest: the Earth \
            rate on its sensitive axis", "it must lie outside the dither's dead band, a few deg/h"))]
    pub input_rate_deg_h: f64,
    #[arg(long, allow_negative_numbers = true, value_parser = ranges::TABLE_RATE_DEG_H.parser(),
        help = ranges::TABLE_RATE_DEG_H.help_why("The rate table's rate when it turns at +R and \
            -R at some temperatures", "without it the scale factor is not calibrated, its \
            terms stay 0"))]
    pub table_rate_deg_h: Option<f64>,
    #[arg(long, default_value_t = 25.0, allow_negative_numbers = true,
        value_parser = ranges::REFERENCE_C.parser(),
        help = ranges::REFERENCE_C.help("T_ref of the model"))]
    pub reference_c: f64,
    /// Put the fitted model in force on the board (`thermal set`, `thermal apply`), checked.
    #[arg(long)]
    pub apply: bool,
    /// Then write it to flash with the calibration (`store`).
    #[arg(long, requires = "apply")]
    pub store: bool,
    /// The log, one row per record (t_s,delta_angle_arcsec,valid,temperature_c,rate_c_min).
    #[arg(long, value_name = "PATH")]
    pub csv: Option<PathBuf>,
}

#[derive(Debug, Args)]
pub struct SweepArgs {
    #[arg(long, default_value_t = 22.2, allow_negative_numbers = true,
        value_parser = ranges::LATITUDE_DEG.parser(),
        help = ranges::LATITUDE_DEG.help("Latitude of the rotary table"))]
    pub latitude: f64,
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "0,30,60,90,120,150,180,210,240,270,300,330",
        value_parser = ranges::AZIMUTHS_DEG.parser(),
        allow_negative_numbers = true,
        help = ranges::AZIMUTHS_DEG.help("Table azimuths, comma-separated")
    )]
    pub azimuths: Vec<f64>,
    #[arg(long, default_value_t = 3.0, allow_negative_numbers = true,
        value_parser = ranges::SETTLE_S.parser(),
        help = ranges::SETTLE_S.help_why("Settling time after the dither drive has locked, which \
            the board waits for first", "the locked amplitude loop takes about 2 s to settle \
            the last 0.2 %"))]
    pub settle: f64,
    #[arg(long, default_value_t = 5.0, allow_negative_numbers = true,
        value_parser = ranges::SECONDS.parser(),
        help = ranges::SECONDS.help("Measuring time per azimuth"))]
    pub seconds: f64,
    /// Where the rate is read.
    #[arg(long, value_enum, default_value = "stream")]
    pub rate_from: RateFrom,
    #[arg(long, default_value_t = 1, allow_negative_numbers = true,
        value_parser = ranges::DIVIDER.parser(),
        help = ranges::DIVIDER.help("Stream every n-th cycle"))]
    pub divider: u16,
    /// Calibrate first (through the protocol), accept and store.
    #[arg(long)]
    pub calibrate: bool,
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true,
        value_parser = ranges::CAL_AZIMUTH_DEG.parser(),
        help = ranges::CAL_AZIMUTH_DEG.help("Azimuth of the calibration run"))]
    pub cal_azimuth: f64,
    #[arg(long, default_value_t = 3000, allow_negative_numbers = true,
        value_parser = ranges::SWEEP_CAL_CYCLES.parser(),
        help = ranges::SWEEP_CAL_CYCLES.help("Dither cycles in the calibration's fit"))]
    pub cal_cycles: u32,
    #[arg(long, default_value_t = 100, allow_negative_numbers = true,
        value_parser = ranges::SWEEP_CAL_WARMUP_CYCLES.parser(),
        help = ranges::SWEEP_CAL_WARMUP_CYCLES.help("Cycles the calibration discards first"))]
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
    /// Serve on a new pty; its path is printed on stdout. (Or `--tcp HOST:PORT`: listen there;
    /// port 0 takes any free port, and the address is printed.)
    #[arg(long)]
    pub pty: bool,
    #[arg(long, default_value_t = 1.0, allow_negative_numbers = true,
        value_parser = ranges::SPEED.parser(),
        help = ranges::SPEED.help("Simulated seconds per wall-clock second"))]
    pub speed: f64,
    #[arg(long, default_value_t = 13.888, allow_negative_numbers = true,
        value_parser = ranges::SERVE_RATE_DEG_H.parser(),
        help = ranges::SERVE_RATE_DEG_H.help("Constant input rate, unless --azimuth is given"))]
    pub rate: f64,
    #[arg(long, allow_negative_numbers = true, value_parser = ranges::AZIMUTH_DEG.parser(),
        help = ranges::AZIMUTH_DEG.help("Rotary table: Earth rate at this azimuth, with --latitude"))]
    pub azimuth: Option<f64>,
    #[arg(long, default_value_t = 22.2, allow_negative_numbers = true,
        value_parser = ranges::LATITUDE_DEG.parser(),
        help = ranges::LATITUDE_DEG.help("Latitude of the rotary table, with --azimuth"))]
    pub latitude: f64,
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    #[arg(long, value_name = "PROFILE")]
    #[cfg_attr(feature = "sim", arg(
        value_parser = |s: &str| profile_text::parse_flag("--temperature-profile", s),
        help = profile_text::help(&format!("The gyro block's temperature, from the board's \
            power-up, with the simulator's default thermal coefficients (default: {} C, where \
            none acts)", ThermalCoefficients::DEFAULT.reference_c))))]
    pub temperature_profile: Option<ProfileArg>,
    #[arg(long, allow_negative_numbers = true, value_parser = ranges::SECONDS.parser(),
        help = ranges::SECONDS.help_why("Stop after this many wall-clock seconds",
            "default: run until killed"))]
    pub seconds: Option<f64>,
    /// A file holding the simulated board's key, 32 hex digits on its first line (default:
    /// $RLG_SIM_BOARD_KEY; neither: the board starts unprovisioned, as a new board).
    #[arg(long, value_name = "PATH")]
    pub board_key_file: Option<PathBuf>,
    /// Refused: a key on the command line shows in the process list.
    #[arg(long, value_name = "KEY", hide = true)]
    pub board_key: Option<String>,
}

/// Any number the board's parser may see: the board itself says what it refuses (NaN,
/// infinities, out of range), so only non-numbers are caught here.
fn finite_or_not(s: &str) -> Result<String, String> {
    s.parse::<f32>()
        .map(|_| s.to_owned())
        .map_err(|_| format!("not a number: {s}"))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(args: &[&str]) -> Cli {
        Cli::try_parse_from(std::iter::once("rlg-cal").chain(args.iter().copied())).unwrap()
    }

    fn env_of(vars: &'static [(&'static str, &'static str)]) -> impl Fn(&str) -> Option<String> {
        move |name| {
            vars.iter()
                .find(|(k, _)| *k == name)
                .map(|(_, v)| v.to_string())
        }
    }

    /// `--port` talks at the board's rate unless told otherwise: the firmware's constant.
    /// `RLG_BAUD` has the range of `--baud`.
    #[test]
    fn the_baud_rate_defaults_to_the_boards() {
        let cli = parse(&["--port", "/dev/ttyUSB0", "status"]);
        let target = cli.connection.resolve(&env_of(&[])).unwrap();
        assert_eq!(
            target,
            Target::Port {
                path: "/dev/ttyUSB0".into(),
                baud: SERIAL_BAUD
            }
        );
        let from_env = cli.connection.resolve(&env_of(&[("RLG_BAUD", "115200")]));
        assert!(matches!(from_env, Ok(Target::Port { baud: 115_200, .. })));
        let outside = cli.connection.resolve(&env_of(&[("RLG_BAUD", "0")]));
        assert_eq!(
            outside,
            Err("RLG_BAUD: 0 is outside 1200..=4000000 Bd".into())
        );
        let cli = parse(&["status", "--port", "/dev/x", "--baud", "9600"]);
        let line_wins = cli.connection.resolve(&env_of(&[("RLG_BAUD", "115200")]));
        assert!(matches!(line_wins, Ok(Target::Port { baud: 9600, .. })));
    }

    /// Connection options on either side of the subcommand, or from the environment; the
    /// command line wins; two connections are a usage error.
    #[test]
    fn the_connection_from_anywhere() {
        for args in [&["--tcp", "h:1", "status"][..], &["status", "--tcp", "h:1"]] {
            let target = parse(args).connection.resolve(&env_of(&[])).unwrap();
            assert_eq!(target, Target::Tcp("h:1".into()), "{args:?}");
        }
        let cli = parse(&["status"]);
        assert_eq!(
            cli.connection.resolve(&env_of(&[("RLG_TCP", "e:2")])),
            Ok(Target::Tcp("e:2".into()))
        );
        let cli = parse(&["status", "--sim"]);
        assert_eq!(
            cli.connection
                .resolve(&env_of(&[("RLG_TCP", "e:2"), ("RLG_SIM_STATE", "s")])),
            Ok(Target::Sim {
                state: Some("s".into())
            })
        );
        let cli = parse(&["status"]);
        assert!(cli
            .connection
            .resolve(&env_of(&[("RLG_TCP", "e:2"), ("RLG_PORT", "/dev/x")]))
            .is_err());
        assert!(cli.connection.resolve(&env_of(&[])).is_err());
    }

    /// The key from a file or the environment; one on the command line is refused, and the
    /// refusal does not repeat it.
    #[test]
    fn the_key_from_a_file_or_the_environment_never_the_command_line() {
        let env = env_of(&[("RLG_KEY", " 3a7c5e91b2d4f60819e3c5a7b9d1f2e4 ")]);
        assert_eq!(
            parse(&["status"]).resolve_key(&env),
            Ok(Some("3a7c5e91b2d4f60819e3c5a7b9d1f2e4".into()))
        );
        let refused = parse(&["status", "--key", "ab12"]).resolve_key(&env);
        assert!(
            refused.as_ref().is_err_and(|e| !e.contains("ab12")),
            "{refused:?}"
        );
        assert_eq!(parse(&["status"]).resolve_key(&env_of(&[])), Ok(None));
        assert!(parse(&["status", "--key-file", "/nonexistent"])
            .resolve_key(&env)
            .is_err());
        let file = std::env::temp_dir().join(format!("rlg-cal-key-{}", std::process::id()));
        std::fs::write(&file, "  00112233445566778899aabbccddeeff \nrest\n").unwrap();
        let from_file = parse(&["status", "--key-file", file.to_str().unwrap()]).resolve_key(&env);
        std::fs::remove_file(&file).unwrap();
        assert_eq!(
            from_file,
            Ok(Some("00112233445566778899aabbccddeeff".into()))
        );
    }
}
