//! `rlg-cal`: talks the readout board's calibration protocol over a serial port, a pty or TCP,
//! and serves the simulated board (cargo feature `sim`, on by default). Results to stdout
//! (`key=value` lines or `--json`), progress and errors to stderr; exit codes in `--help` and
//! `host_cli::exit` (0 ok, also when the reader of stdout goes away; 1 the board refused or a
//! run failed, 2 usage, 3 link or timeout, 130 stopped by Ctrl-C).
//!
//! Every precondition of a long run is checked before it starts, in this order: arguments and
//! output files (exit 2), the key when a protected step follows (exit 2), the connection and
//! the board answering `id` (exit 3), then the unlock (exit 1 on a wrong key).

mod board_commands;
mod cli;
#[cfg(feature = "sim")]
mod local;
#[cfg(feature = "sim")]
mod sim_board;

use board_commands::{Device, Session};
use clap::Parser;
use cli::{Cli, Command, Target};
use host_cli::Failure;
use rlg_cal::client::{Client, ClientError};
use rlg_cal::link::{self, Link};
use rlg_cal::output::Format;
use std::process::ExitCode;
use std::time::Duration;

fn main() -> ExitCode {
    let cli = Cli::parse();
    let json = cli.json;
    let outcome = run(cli);
    if let (true, Err(Failure::Error { error, .. })) = (json, &outcome) {
        if let Some(ClientError::Device(e)) = error.downcast_ref::<ClientError>() {
            // Scripts get the board's refusal on stdout too, as the command's one object.
            let object = serde_json::json!({
                "command": e.command,
                "error": e.code,
                "error_text": e.text,
            });
            let _ = host_cli::outln!("{object}");
        }
    }
    host_cli::exit::exit("rlg-cal", outcome)
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
        Command::Completions(args) => return host_cli::completions::print::<Cli>(args),
        #[cfg(feature = "sim")]
        Command::Sweep(args) => return local::sweep(args, &cli.connection),
        #[cfg(feature = "sim")]
        Command::ServeSim(args) => return local::serve(args, &cli.connection),
        #[cfg(not(feature = "sim"))]
        Command::Sweep(_) => return Err(without_sim("sweep")),
        #[cfg(not(feature = "sim"))]
        Command::ServeSim(_) => return Err(without_sim("serve-sim")),
        _ => {}
    }
    let key = cli.resolve_key(&env).map_err(Failure::Usage)?;
    let target = cli.connection.resolve(&env).map_err(Failure::Usage)?;
    let outputs = board_commands::prepare(&cli.command, key.is_some())?;
    let timeout = Duration::from_millis(cli.timeout_ms);
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
        #[cfg(not(feature = "sim"))]
        Target::Sim { .. } => Err(without_sim("--sim")),
        #[cfg(feature = "sim")]
        Target::Sim { state } => sim_board::run(&cli, state, timeout, session),
    }
}

/// The usage error of a subcommand or option that needs the simulated board, in a build for
/// real boards only.
#[cfg(not(feature = "sim"))]
fn without_sim(what: &str) -> Failure {
    Failure::Usage(format!(
        "{what} needs the simulated board, and this rlg-cal is built for real boards only \
         (without the cargo feature `sim`; `cargo build -p rlg-cal` includes it)"
    ))
}
