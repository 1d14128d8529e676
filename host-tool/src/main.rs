//! `rlg-cal`: talks the readout board's calibration protocol over a serial port, a pty or TCP,
//! and serves the simulated board. Results to stdout (`key=value` lines or `--json`), progress
//! and errors to stderr; exit codes in `--help` (0 ok, 1 the board refused or a run failed,
//! 2 usage, 3 link or timeout, 130 stopped by Ctrl-C).
//!
//! Every precondition of a long run is checked before it starts, in this order: arguments and
//! output files (exit 2), the key when a protected step follows (exit 2), the connection and
//! the board answering `id` (exit 3), then the unlock (exit 1 on a wrong key).

mod board_commands;
mod cli;
mod local;

use board_commands::{Device, Session};
use clap::Parser;
use cli::{Cli, Command, Target};
use hal_sim::flash::CalibrationFlash;
use rlg_cal::client::{Client, ClientError};
use rlg_cal::link::{self, Link, SimLink};
use rlg_cal::ops;
use rlg_cal::output::Format;
use rlg_cal::sim::{self, SimInput};
use rlg_cal::sim_state::{self, SimState};
use std::path::Path;
use std::process::ExitCode;
use std::time::Duration;

pub enum Failure {
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
    let json = cli.json;
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(failure) => {
            if let (true, Failure::Client(ClientError::Device(e))) = (json, &failure) {
                // Scripts get the board's refusal on stdout too, as the command's one object.
                let object = serde_json::json!({
                    "command": e.command,
                    "error": e.code,
                    "error_text": e.text,
                });
                println!("{object}");
            }
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

fn env(name: &str) -> Option<String> {
    std::env::var(name).ok()
}

fn run(cli: Cli) -> Result<(), Failure> {
    let format = if cli.json {
        Format::Json
    } else {
        Format::KeyValue
    };
    match &cli.command {
        Command::Sweep(args) => return local::sweep(args, &cli.connection),
        Command::ServeSim(args) => return local::serve(args, &cli.connection),
        _ => {}
    }
    let key = cli.resolve_key(&env).map_err(Failure::Usage)?;
    let target = cli.connection.resolve(&env).map_err(Failure::Usage)?;
    let outputs = board_commands::prepare(&cli.command, key.is_some())?;
    let timeout = Duration::from_millis(cli.timeout_ms);
    let session_key = key.clone();
    let session = Session {
        key,
        format,
        outputs,
    };
    match target {
        Target::Port { path, baud } => {
            let port = link::serial(&path, baud)
                .map_err(|e| Failure::Connect(format!("cannot open {path}: {e}")))?;
            let boxed: Box<dyn Link> = Box::new(port);
            Device::new(&mut Client::new(boxed).with_timeout(timeout), session).run(&cli.command)
        }
        Target::Tcp(address) => {
            let tcp = link::tcp(&address, Duration::from_secs(3))
                .map_err(|e| Failure::Connect(format!("cannot connect to {address}: {e}")))?;
            Device::new(&mut Client::new(tcp).with_timeout(timeout), session).run(&cli.command)
        }
        Target::Sim { state } => {
            let saved = match &state {
                Some(path) => load_state(path)?,
                None => None,
            };
            let mut client = boot_sim(
                cli.connection.sim_rate,
                saved.as_ref(),
                session_key.as_deref(),
            )?
            .with_timeout(timeout);
            let result = Device::new(&mut client, session).run(&cli.command);
            if let Some(path) = &state {
                save_state(path, client, saved.map_or(0, |s| s.boot_count))?;
            }
            result
        }
    }
}

fn load_state(path: &Path) -> Result<Option<SimState>, Failure> {
    let state =
        sim_state::load(path).map_err(|e| Failure::Usage(format!("the --sim state file: {e}")))?;
    if let Some(s) = &state {
        if s.flash.len() != CalibrationFlash::default().contents().len() {
            return Err(Failure::Usage(format!(
                "{}: the flash image has {} bytes, not the simulated board's",
                path.display(),
                s.flash.len()
            )));
        }
    }
    Ok(state)
}

/// A simulated board that has been on for a moment: its dither drive locked and settled, the
/// readout with a first rate; booted on the saved flash and given the saved settings. Its key
/// (the in-process board has none of its own): `RLG_SIM_BOARD_KEY`, else the client's key,
/// else a fresh random one (the board then refuses every unlock, as a board would whose key
/// one does not know).
fn boot_sim(
    rate_deg_per_h: f64,
    saved: Option<&SimState>,
    client_key: Option<&str>,
) -> Result<Client<SimLink>, Failure> {
    let mut flash = CalibrationFlash::default();
    if let Some(s) = saved {
        flash.restore(&s.flash);
    }
    let boot_count = saved.map_or(0, |s| s.boot_count);
    let board_key = sim::board_key(None)
        .map_err(Failure::Usage)?
        .or_else(|| client_key.and_then(firmware::protocol::key::Key::parse_hex))
        .unwrap_or_else(sim::fresh_key);
    let input = SimInput::Constant { rate_deg_per_h };
    let device = sim::boot(input, 1, flash, boot_count, Some(board_key))
        .map_err(|e| Failure::Connect(e.to_string()))?;
    let mut client = Client::new(SimLink::new(device));
    let connect = |e: ClientError| Failure::Connect(e.to_string());
    ops::wait_for_drive_lock(
        &mut client,
        ops::DRIVE_LOCK_TIMEOUT,
        Duration::from_millis(100),
    )
    .map_err(connect)?;
    if let Some(s) = saved {
        let key = sim::key_hex(&board_key);
        sim_state::restore_settings(&mut client, &s.settings, &key).map_err(connect)?;
    }
    client.pause(Duration::from_secs(2)).map_err(connect)?;
    Ok(client)
}

fn save_state(path: &Path, mut client: Client<SimLink>, boot_count: u32) -> Result<(), Failure> {
    let fail = |e: String| {
        Failure::Run(format!(
            "cannot save the --sim state to {}: {e}",
            path.display()
        ))
    };
    if client.streaming() {
        client
            .command("stream off")
            .map_err(|e| fail(e.to_string()))?;
    }
    let settings = sim_state::read_settings(&mut client).map_err(|e| fail(e.to_string()))?;
    let flash = client.into_link().into_device().power_off();
    let state = SimState {
        boot_count: sim_state::next_boot(boot_count),
        settings,
        flash: flash.snapshot(),
    };
    sim_state::save(path, &state).map_err(|e| fail(e.to_string()))
}
