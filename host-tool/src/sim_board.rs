//! The `--sim` board of a board command: a simulated board in this process (cargo feature
//! `sim`), booted on its state file's flash and settings (`--sim-state`), used for the one
//! command, and saved again, so that a series of calls acts as one board.

use crate::board_commands::{Device, Session};
use crate::cli::{Cli, ConnectionArgs};
use hal_sim::flash::CalibrationFlash;
use host_cli::Failure;
use rlg_cal::client::{Client, ClientError};
use rlg_cal::link::SimLink;
use rlg_cal::ops;
use rlg_cal::sim::{self, SimInput};
use rlg_cal::sim_state::{self, SimState};
use std::path::{Path, PathBuf};
use std::time::Duration;

/// Runs `cli`'s command on the `--sim` board whose state file is `state` (if any).
pub fn run(
    cli: &Cli,
    state: Option<PathBuf>,
    timeout: Duration,
    session: Session,
) -> Result<(), Failure> {
    let saved = match &state {
        Some(path) => load_state(path)?,
        None => None,
    };
    let mut client =
        boot_sim(&cli.connection, saved.as_ref(), session.key.as_deref())?.with_timeout(timeout);
    let result = Device::new(&mut client, session).run(&cli.command);
    if let Some(path) = &state {
        save_state(path, client, saved.map_or(0, |s| s.boot_count))?;
    }
    result
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
/// readout with a first rate, the temperature sensor with its first results; at the input rate
/// and block temperature of `connection`'s `--sim-*` flags, booted on the saved flash and given
/// the saved settings. Its key
/// (the in-process board has none of its own): `RLG_SIM_BOARD_KEY`, else the client's key,
/// else a fresh random one (the board then refuses every unlock, as a board would whose key
/// one does not know).
fn boot_sim(
    connection: &ConnectionArgs,
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
    let input = SimInput::Constant {
        rate_deg_per_h: connection.sim_rate,
    };
    let gyro = sim::gyro(1, connection.sim_temperature_profile);
    let device = sim::boot_gyro(gyro, input.profile(), flash, boot_count, Some(board_key))
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
