//! `rlg-cal`: talks the readout board's calibration protocol over a serial port, a pty or TCP,
//! and serves the simulated board. Results to stdout, progress and errors to stderr; exit codes
//! in `--help` (0 ok, 1 the board refused or a run failed, 2 usage, 3 link or timeout).

mod cli;

use clap::Parser;
use cli::{
    CalibrateArgs, Cli, Command, ConnectionArgs, OnOff, RateFrom, ServeArgs, StreamArgs, SweepArgs,
};
use hal_sim::flash::CalibrationFlash;
use indicatif::{ProgressBar, ProgressStyle};
use rlg_cal::client::{Answer, Client, ClientError};
use rlg_cal::link::{self, Link, SimLink};
use rlg_cal::ops::{self, CalibrateOptions};
use rlg_cal::serve::{self, PtyEndpoint, ServeOptions, TcpEndpoint};
use rlg_cal::sim::{self, SimInput};
use rlg_cal::sweep::{self, RateSource, SweepOptions};
use std::io::Write;
use std::net::TcpListener;
use std::path::Path;
use std::process::ExitCode;
use std::sync::atomic::AtomicBool;
use std::time::Duration;

enum Failure {
    /// Exit 2.
    Usage(String),
    /// Exit 3.
    Connect(String),
    /// Exit 1.
    Run(String),
    Client(ClientError),
}

impl From<ClientError> for Failure {
    fn from(e: ClientError) -> Self {
        Self::Client(e)
    }
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(failure) => {
            let (message, code) = match failure {
                Failure::Usage(m) => (format!("error: {m}"), 2),
                Failure::Connect(m) => (m, 3),
                Failure::Run(m) => (m, 1),
                Failure::Client(e) => (e.to_string(), e.exit_code()),
            };
            eprintln!("rlg-cal: {message}");
            ExitCode::from(code)
        }
    }
}

fn run(cli: Cli) -> Result<(), Failure> {
    match &cli.command {
        Command::Sweep(args) => return run_sweep(args, &cli.connection),
        Command::ServeSim(args) => return run_serve(args, &cli.connection),
        _ => {}
    }
    let link = connect(&cli.connection, cli.key.as_deref())?;
    let mut client = Client::new(link).with_timeout(Duration::from_millis(cli.timeout_ms));
    let mut device = Device {
        client: &mut client,
        key: cli.key.as_deref(),
    };
    device.run(&cli.command)
}

/// The link `c` names; `key`: the client's `--key`, which a `--sim` board is provisioned with
/// unless `RLG_SIM_BOARD_KEY` gives it another (the in-process board has no key of its own).
fn connect(c: &ConnectionArgs, key: Option<&str>) -> Result<Box<dyn Link>, Failure> {
    let chosen = c.port.is_some() as u8 + c.tcp.is_some() as u8 + c.sim as u8;
    if chosen != 1 {
        return Err(Failure::Usage(
            "give exactly one connection: --port PATH, --tcp HOST:PORT or --sim".into(),
        ));
    }
    if let Some(path) = &c.port {
        let port = link::serial(path, c.baud)
            .map_err(|e| Failure::Connect(format!("cannot open {path}: {e}")))?;
        return Ok(Box::new(port));
    }
    if let Some(address) = &c.tcp {
        let tcp = link::tcp(address, Duration::from_secs(3))
            .map_err(|e| Failure::Connect(format!("cannot connect to {address}: {e}")))?;
        return Ok(Box::new(tcp));
    }
    let input = SimInput::Constant {
        rate_deg_per_h: c.sim_rate,
    };
    let board_key = match sim::board_key(None).map_err(Failure::Usage)? {
        Some(k) => Some(k),
        None => key.and_then(firmware::protocol::key::Key::parse_hex),
    };
    let device = sim::boot(input, 1, CalibrationFlash::default(), 0, board_key)
        .map_err(|e| Failure::Connect(e.to_string()))?;
    // A board that has been on for a moment: its dither drive locked and settled, the readout
    // with a first rate.
    let mut client = Client::new(SimLink::new(device));
    ops::wait_for_drive_lock(
        &mut client,
        ops::DRIVE_LOCK_TIMEOUT,
        Duration::from_millis(100),
    )
    .map_err(|e| Failure::Connect(e.to_string()))?;
    let mut link = client.into_link();
    link.pause(Duration::from_secs(2));
    Ok(Box::new(link))
}

/// The commands that talk to a board.
struct Device<'a> {
    client: &'a mut Client<Box<dyn Link>>,
    key: Option<&'a str>,
}

fn on_off(state: OnOff) -> &'static str {
    match state {
        OnOff::On => "on",
        OnOff::Off => "off",
    }
}

fn print(answer: &Answer) {
    println!("{}", answer.display_lines());
}

impl Device<'_> {
    /// Unlocks first when a key was given.
    fn unlocked(&mut self) -> Result<&mut Self, Failure> {
        if let Some(key) = self.key {
            ops::unlock(self.client, key)?;
        }
        Ok(self)
    }

    /// One exchange, answer printed.
    fn ask(&mut self, line: &str) -> Result<(), Failure> {
        print(&self.client.command(line)?);
        Ok(())
    }

    fn run(&mut self, command: &Command) -> Result<(), Failure> {
        match command {
            Command::Id => self.ask("id"),
            Command::Status => self.ask("status"),
            Command::Get { which } => self.ask(&format!("get {}", value_name(which))),
            Command::Set { which, value } => self
                .unlocked()?
                .ask(&format!("set {} {value}", value_name(which))),
            Command::Comp { state } => self.unlocked()?.ask(&format!("comp {}", on_off(*state))),
            Command::Track { state } => self.unlocked()?.ask(&format!("track {}", on_off(*state))),
            Command::Unlock { key } => self.ask(&format!("unlock {key}")),
            Command::Lock => self.ask("lock"),
            Command::Store => self.unlocked()?.ask("store"),
            Command::Reload => self.unlocked()?.ask("reload"),
            Command::Defaults => self.unlocked()?.ask("defaults"),
            Command::Send { words } => self.ask(&words.join(" ")),
            Command::Calibrate(args) => self.calibrate(args),
            Command::Stream(args) => self.stream(args),
            Command::Sweep(_) | Command::ServeSim(_) => unreachable!("handled before connecting"),
        }
    }

    fn calibrate(&mut self, args: &CalibrateArgs) -> Result<(), Failure> {
        // `cal start` takes the board's time: protected like the rest.
        self.unlocked()?;
        let options = CalibrateOptions {
            poll: Duration::from_millis(args.poll_ms.max(10)),
            ..CalibrateOptions::new(args.cycles, args.warmup)
        };
        let bar = ProgressBar::new(args.cycles as u64 + args.warmup as u64).with_style(
            ProgressStyle::with_template("{bar:40} {pos}/{len} cycles, {elapsed} (eta {eta})")
                .expect("valid template"),
        );
        let result = ops::calibrate(self.client, &options, &mut |done, total| {
            bar.set_length(total);
            bar.set_position(done);
        });
        bar.finish_and_clear();
        print(&result?);
        if args.accept {
            self.ask("cal accept")?;
        }
        if args.store {
            self.ask("store")?;
        }
        Ok(())
    }

    fn stream(&mut self, args: &StreamArgs) -> Result<(), Failure> {
        if !(args.seconds > 0.0 && args.seconds.is_finite()) {
            return Err(Failure::Usage("--seconds must be positive".into()));
        }
        let scale = ops::rate_scale(self.client, args.timer_hz)?;
        let bar = ProgressBar::new(1000).with_style(
            ProgressStyle::with_template("{bar:40} streaming {elapsed}").expect("valid template"),
        );
        let capture = ops::stream(
            self.client,
            args.divider,
            Duration::from_secs_f64(args.seconds),
            &mut |fraction| bar.set_position((fraction * 1000.0) as u64),
        );
        bar.finish_and_clear();
        let capture = capture?;
        write_file(&args.csv, |f| capture.write_csv(f, &scale))?;
        if let Some(svg) = &args.svg {
            let plot = capture.svg(&scale, "Streamed rate");
            write_file(svg, |f| f.write_all(plot.as_bytes()))?;
        }
        let (compensated, raw) = capture.mean_rates(&scale);
        println!(
            "frames={} lost={} bad={} mean_compensated_deg_h={compensated:.4} mean_raw_deg_h={raw:.4}",
            capture.records.len(),
            capture.lost(),
            capture.bad_frames
        );
        if capture.lost() > 0 {
            eprintln!(
                "rlg-cal: {} frames lost (sequence gaps): use a faster link or a larger --divider",
                capture.lost()
            );
        }
        Ok(())
    }
}

fn value_name<T: clap::ValueEnum>(v: &T) -> String {
    v.to_possible_value()
        .map(|p| p.get_name().to_owned())
        .unwrap_or_default()
}

fn write_file(
    path: &Path,
    write: impl FnOnce(&mut std::io::BufWriter<std::fs::File>) -> std::io::Result<()>,
) -> Result<(), Failure> {
    let fail = |e: std::io::Error| Failure::Run(format!("cannot write {}: {e}", path.display()));
    let file = std::fs::File::create(path).map_err(fail)?;
    let mut out = std::io::BufWriter::new(file);
    write(&mut out).map_err(fail)?;
    out.flush().map_err(fail)
}

fn no_connection(c: &ConnectionArgs, what: &str) -> Result<(), Failure> {
    if c.port.is_some() || c.tcp.is_some() || c.sim {
        return Err(Failure::Usage(format!(
            "{what} runs its own simulated board: --port, --tcp and --sim do not apply"
        )));
    }
    Ok(())
}

fn run_sweep(args: &SweepArgs, connection: &ConnectionArgs) -> Result<(), Failure> {
    no_connection(connection, "sweep")?;
    let seconds = |s: f64, name: &str| {
        if s >= 0.0 && s.is_finite() {
            Ok(Duration::from_secs_f64(s))
        } else {
            Err(Failure::Usage(format!("{name} must be a time >= 0")))
        }
    };
    let options = SweepOptions {
        latitude_deg: args.latitude,
        azimuths_deg: args.azimuths.clone(),
        settle: seconds(args.settle, "--settle")?,
        measure: seconds(args.seconds, "--seconds")?,
        rate_from: match args.rate_from {
            RateFrom::Stream => RateSource::Stream,
            RateFrom::Status => RateSource::Status,
        },
        divider: args.divider,
        calibrate: args.calibrate.then(|| {
            (
                CalibrateOptions::new(args.cal_cycles, args.cal_warmup),
                args.cal_azimuth,
            )
        }),
        seed: args.seed,
    };
    let report = sweep::sweep(&options, &mut |line| eprintln!("{line}"))?;
    if let Some(fit) = &report.calibration {
        println!("# calibration: {}", fit.text);
    }
    report
        .write_csv(std::io::stdout().lock())
        .map_err(|e| Failure::Run(format!("stdout: {e}")))?;
    if let Some(path) = &args.csv {
        write_file(path, |f| report.write_csv(f))?;
    }
    if let Some(path) = &args.svg {
        write_file(path, |f| f.write_all(report.svg().as_bytes()))?;
    }
    Ok(())
}

fn run_serve(args: &ServeArgs, connection: &ConnectionArgs) -> Result<(), Failure> {
    no_connection(connection, "serve-sim")?;
    if !(args.speed > 0.0 && args.speed.is_finite()) {
        return Err(Failure::Usage("--speed must be positive".into()));
    }
    let input = match args.azimuth {
        Some(azimuth_deg) => SimInput::RotaryTable {
            latitude_deg: args.latitude,
            azimuth_deg,
        },
        None => SimInput::Constant {
            rate_deg_per_h: args.rate,
        },
    };
    let board_key = sim::board_key(args.board_key.as_deref()).map_err(Failure::Usage)?;
    let device = sim::boot(input, args.seed, CalibrationFlash::default(), 0, board_key)
        .map_err(|e| Failure::Run(e.to_string()))?;
    let options = ServeOptions {
        speed: args.speed,
        max_duration: args.seconds.map(Duration::from_secs_f64),
    };
    let stop = AtomicBool::new(false);
    let announce = |where_: &str| {
        println!("{where_}");
        let _ = std::io::stdout().flush();
        eprintln!(
            "rlg-cal: simulated board on {where_} (input {input:?}, speed {}x, key {}); Ctrl-C stops",
            args.speed,
            if board_key.is_some() {
                "provisioned"
            } else {
                "unprovisioned: `key provision <32 hex digits>` first"
            }
        );
    };
    let served = if let Some(address) = &args.tcp {
        let listener = TcpListener::bind(address)
            .map_err(|e| Failure::Connect(format!("cannot listen on {address}: {e}")))?;
        let local = listener
            .local_addr()
            .map_err(|e| Failure::Connect(e.to_string()))?;
        let mut endpoint =
            TcpEndpoint::new(listener).map_err(|e| Failure::Connect(e.to_string()))?;
        announce(&local.to_string());
        serve::serve(device, &mut endpoint, &options, &stop)
    } else {
        let mut endpoint =
            PtyEndpoint::open().map_err(|e| Failure::Connect(format!("pty: {e}")))?;
        announce(&endpoint.path().display().to_string());
        serve::serve(device, &mut endpoint, &options, &stop)
    };
    served
        .map(|_| ())
        .map_err(|e| Failure::Connect(format!("serving: {e}")))
}
