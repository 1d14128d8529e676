//! The command executor: a parsed [`Command`] and the device's state in, exactly one answer out.
//!
//! Sans-IO: what the protocol needs from the rest of the firmware is the [`DeviceLink`] trait
//! (a status snapshot, staging settings into the readout, storing and loading the calibration),
//! implemented by the board code (critical sections around the readout's staging slot) and by
//! hal-sim's simulated board. The executor owns the slow state, one value per command group
//! ([`super::commands`]): access control, the calibration (session and tracking loop), where
//! the coefficients came from, and the stream settings. It enforces the rules that cut across
//! the groups and dispatches each command to its group's function:
//!
//! - reads (`id`, `status`, `get`, `cal status`, `cal result`, `help`) never need an unlock;
//! - `key provision` needs none either: it is accepted only while the board has no key
//!   ([`super::key`]), and there is nothing to unlock with before;
//! - everything that changes coefficients, compensation, the dither drive or flash (`set`,
//!   `comp`, `track`, `cal accept`, `store`, `reload`, `defaults`, `dither on|off|amp|noise`)
//!   needs one, and extends it when it succeeds;
//! - so do the calibration commands that take the board's time or discard work: `cal start`,
//!   `cal abort`, and `cal result` while it would close pooled runs; so a locked client can
//!   neither start an hour-long run nor end someone else's;
//! - while a calibration run collects cycles, those commands answer `ERR 10` (busy): the run's
//!   data would no longer match the coefficients;
//! - while online tracking runs, `set`, `comp`, `defaults`, `cal accept` and `reload` answer
//!   `ERR 17`: the loop owns the coefficients and would overwrite theirs within a second;
//! - `cal start` answers `ERR 11` while the dither drive is not locked (its cycles would all be
//!   flagged invalid);
//! - a refused command changes nothing, with one deliberate exception: `cal result` on a
//!   completed run solves the fit, and a fit that fails its checks is answered `ERR 12` while
//!   the session moves to "refused" (the refusal *is* the result; `cal status` reports it).
//!
//! Size (over 600 lines): the dispatch of every command and the access rule it is under stay in one
//! match, so a command cannot be added without its rule; the commands' bodies live in `commands/`.

use super::commands::access::AccessState;
use super::commands::calibration::CalibrationState;
use super::commands::info::{self, StatusFlags};
use super::commands::provenance::Provenance;
use super::commands::stream::{StreamState, StreamedOutput};
use super::commands::thermal::{self, ThermalEdit};
use super::commands::{dither, settings, storage, Answer};
use super::confirm::{needs_confirmation, Canonical};
use super::parse::{Command, DitherCommand};
use super::respond::Response;
use super::stream::StreamRecord;
use super::ErrorCode;
use crate::calibration::validation::AcceptanceLimits;
use crate::dither::DitherState;
use crate::signal::compensation::CompensationSettings;
use crate::signal::lockin::CycleRecord;
use crate::signal::output::record::{OutputRecord, OutputStatus};
use crate::storage::{FitSummary, LoadReport};

pub use super::commands::provenance::Source;
pub use super::link::{DeviceLink, DeviceStatus, Identity};

/// The executor's state, one value per command group.
#[derive(Clone, Debug)]
pub struct Executor {
    access: AccessState,
    calibration: CalibrationState,
    provenance: Provenance,
    stream: StreamState,
    /// The thermal model being edited (`thermal range|bias|sf`).
    thermal_edit: ThermalEdit,
    /// A state-changing command typed without a CRC, echoed, waiting for `yes`.
    pending: Option<Command>,
}

/// What a dither cycle asks of the serial task.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CycleActions {
    /// A stream frame to send.
    pub frame: Option<StreamRecord>,
    /// Coefficients the tracking loop wants staged (compensation on).
    pub stage: Option<CompensationSettings>,
}

impl Executor {
    /// The state after boot: locked, coefficients as `load` found them.
    pub fn new(
        report: &LoadReport,
        fit: Option<FitSummary>,
        boot_count: u32,
        limits: AcceptanceLimits,
    ) -> Self {
        Self {
            access: AccessState::new(),
            calibration: CalibrationState::new(limits),
            provenance: Provenance::new(report, fit, boot_count),
            stream: StreamState::default(),
            thermal_edit: ThermalEdit::default(),
            pending: None,
        }
    }

    /// After a reset: the wrong-key count the platform kept, its windows counted from `now_ms`.
    pub fn restore_wrong_keys(&mut self, wrong_keys: u32, now_ms: u64) {
        self.access.restore_wrong_keys(wrong_keys, now_ms);
    }

    /// A new client on the link (a new TCP connection to a served board): locked, streaming
    /// off, so nothing of the previous client's session carries over. The calibration, the
    /// coefficients and the wrong-key count are the board's, not the session's: they stay.
    pub fn new_session(&mut self) {
        self.access.lock();
        self.pending = None;
        let _ = self.stream.command(None);
    }

    /// `n` closed cycles were lost before they reached the executor (a full record queue): the
    /// stream leaves a sequence gap for the frames they were due.
    pub fn on_cycles_lost(&mut self, n: u32) {
        self.stream.skip(n);
    }

    /// Wrong keys since the last correct one.
    pub fn wrong_keys(&self) -> u32 {
        self.access.wrong_keys()
    }

    /// Whether online tracking runs.
    pub fn tracking(&self) -> bool {
        self.calibration.tracking()
    }

    /// Where the coefficients in force came from.
    pub fn source(&self) -> Source {
        self.provenance.source
    }

    /// Whether binary streaming is on.
    pub fn streaming(&self) -> bool {
        self.stream.on()
    }

    /// Every dither cycle (from the low-priority cycle task): feeds a running calibration and
    /// the tracking loop; returns a stream frame when one is due and coefficients to stage when
    /// tracking has new ones.
    pub fn on_cycle(&mut self, record: &CycleRecord, cycle_s: f64) -> CycleActions {
        let stage = self.calibration.on_cycle(record, cycle_s);
        if stage.is_some() {
            self.provenance.changed();
        }
        CycleActions {
            frame: self.stream.on_cycle(record),
            stage,
        }
    }

    /// Every output record (from the output latch's context, through the service): the frame
    /// to send when the output is streamed, with the tracking bit set while the tracker runs
    /// (the readout does not know it).
    pub fn on_output(&mut self, record: &OutputRecord) -> Option<StreamedOutput> {
        let tracking = self.tracking();
        let mut out = self.stream.on_output(record)?;
        if tracking {
            out.record.status = out.record.status.union(OutputStatus::TRACKING);
        }
        Some(out)
    }

    /// A thermal frame of the output stream could not be sent: the next record gets one.
    pub fn thermal_frame_lost(&mut self) {
        self.stream.thermal_frame_lost();
    }

    /// Executes one command from a line: a state-changing one without a CRC is not executed
    /// but echoed for confirmation (`ERR 18 ... cmd=<as parsed>`), and `yes` then executes it
    /// ([`super::confirm`]); any other line drops a pending one.
    pub fn execute_line<D: DeviceLink>(
        &mut self,
        id: &Identity,
        device: &mut D,
        command: Command,
        with_crc: bool,
    ) -> Response {
        let pending = self.pending.take();
        if command == Command::Confirm {
            return match pending {
                Some(pending) => self.execute(id, device, pending),
                None => Response::err(ErrorCode::WrongState),
            };
        }
        // `cal result` is a read once solved, a state change while it would close the runs.
        let solving = command == Command::CalResult && self.calibration.run_done();
        if !with_crc && (needs_confirmation(&command) || solving) {
            self.pending = Some(command);
            let mut r = Response::err(ErrorCode::Confirm);
            r.field(format_args!("cmd={}", Canonical(&command)));
            return r;
        }
        self.execute(id, device, command)
    }

    /// A line that was no command (bad CRC, parse error, garbage): a pending confirmation ends.
    pub fn drop_pending(&mut self) {
        self.pending = None;
    }

    /// The command echoed for confirmation, waiting for `yes`.
    pub fn pending(&self) -> Option<Command> {
        self.pending
    }

    /// Executes one command.
    pub fn execute<D: DeviceLink>(
        &mut self,
        id: &Identity,
        device: &mut D,
        command: Command,
    ) -> Response {
        let now_ms = device.now_ms();
        let needs_unlock = match unlock_rule(&command) {
            UnlockRule::Never => false,
            UnlockRule::Always => true,
            UnlockRule::WhileItWouldSolve => self.calibration.run_done(),
        };
        if needs_unlock && !self.access.is_unlocked(now_ms) {
            return Response::err(ErrorCode::Locked);
        }
        if protected(&command) && self.calibration.running() {
            return Response::err(ErrorCode::Busy);
        }
        if self.calibration.tracking() && overridden_by_tracking(&command) {
            return Response::err(ErrorCode::Tracking);
        }
        let answer = self.dispatch(id, device, now_ms, command);
        if needs_unlock && answer.is_ok() {
            self.access.touch(now_ms);
        }
        answer.unwrap_or_else(Response::err)
    }

    /// One command to its group.
    fn dispatch<D: DeviceLink>(
        &mut self,
        id: &Identity,
        device: &mut D,
        now_ms: u64,
        command: Command,
    ) -> Answer {
        let p = &mut self.provenance;
        match command {
            Command::Help => Ok(info::help()),
            Command::Identify => Ok(info::identify(id)),
            Command::Status => {
                let flags = StatusFlags {
                    tracking: self.calibration.tracking(),
                    source: p.source,
                    unlocked: self.access.is_unlocked(now_ms),
                    key_provisioned: self.access.provisioned(id),
                };
                Ok(info::status(id, device, flags))
            }
            Command::SelfTest => Ok(info::selftest(device)),
            Command::OutputStatus => Ok(info::output_status(device)),
            Command::Thermal(c) => thermal::command(&mut self.thermal_edit, device, p, c),
            Command::Get(which) => Ok(info::get(id, device, which)),
            Command::Set(which, value) => settings::set(device, p, which, value),
            Command::Compensation(on) => Ok(settings::compensation(device, p, on)),
            Command::Tracking(on) => Ok(settings::tracking(device, &mut self.calibration, on)),
            Command::Defaults => Ok(settings::defaults(device, p)),
            Command::CalStart {
                cycles,
                warmup_cycles,
            } => {
                // A run needs the dither the board holds: while the drive starts (or is off, or
                // in a fault) every cycle is flagged and the run could only be refused at the end.
                if device.dither_status().state != DitherState::Locked {
                    return Err(ErrorCode::WrongState);
                }
                self.calibration.start(cycles, warmup_cycles)
            }
            Command::CalStatus => Ok(self.calibration.status()),
            Command::CalAbort => Ok(self.calibration.abort()),
            Command::CalResult => self.calibration.result(id),
            Command::CalAccept => self.calibration.accept(device, p),
            Command::Store => storage::store(device, p, id),
            Command::Reload => Ok(storage::reload(device, p)),
            Command::Stream(divider) => Ok(self.stream.command(divider)),
            Command::StreamOutput => Ok(self.stream.command_output()),
            Command::Unlock(given) => self.access.unlock(id, now_ms, &given),
            Command::KeyProvision(key) => self.access.provision(id, device, key),
            Command::Lock => Ok(self.access.lock()),
            Command::Dither(command) => dither::command(device, id, command),
            // Confirmation is a line-level matter (`execute_line`); alone it confirms nothing.
            Command::Confirm => Err(ErrorCode::WrongState),
        }
    }
}

/// Commands whose coefficients or compensation switch the tracking loop would overwrite at its
/// next update (it stages its own estimate, compensation on, about once a second): refused
/// while tracking runs, so that no `OK` is silently undone.
fn overridden_by_tracking(command: &Command) -> bool {
    matches!(
        command,
        Command::Set(..)
            | Command::Compensation(_)
            | Command::Defaults
            | Command::CalAccept
            | Command::Reload
    )
}

/// When a command needs an unlock ([`unlock_rule`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum UnlockRule {
    /// A read, `stream`, `unlock`, `lock`, `yes`, `key provision`.
    Never,
    /// It changes coefficients, compensation, the dither drive or flash, or it takes the
    /// board's time or discards work (`cal start`: a run of up to an hour, discarding a
    /// finished fit; `cal abort`: drops the runs).
    Always,
    /// `cal result`: while it would close the pooled runs (solving ends pooling); reading a
    /// solved result is a read.
    WhileItWouldSolve,
}

/// Whether `command` needs an unlock (docs/protocol.md's command table, checked against this
/// by `hal-sim/tests/protocol_doc.rs`).
pub fn unlock_rule(command: &Command) -> UnlockRule {
    match command {
        c if protected(c) => UnlockRule::Always,
        Command::CalStart { .. } | Command::CalAbort => UnlockRule::Always,
        Command::CalResult => UnlockRule::WhileItWouldSolve,
        _ => UnlockRule::Never,
    }
}

/// Commands that change coefficients, compensation, the dither drive or flash: refused while a
/// calibration run collects cycles, besides needing an unlock.
fn protected(command: &Command) -> bool {
    matches!(
        command,
        Command::Set(..)
            | Command::Compensation(_)
            | Command::Tracking(_)
            | Command::CalAccept
            | Command::Store
            | Command::Reload
            | Command::Defaults
    ) || matches!(command, Command::Dither(c) if *c != DitherCommand::Status)
        || matches!(command, Command::Thermal(c) if !c.is_read())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::protocol::commands::testing::{report, MemDevice, ID};
    use crate::protocol::parse::parse;
    use crate::storage::{DefaultsReason, LoadOutcome};

    fn unlock_line() -> std::string::String {
        let hex: std::string::String = ID
            .key
            .unwrap()
            .to_bytes()
            .iter()
            .map(|b| format!("{b:02x}"))
            .collect();
        format!("unlock {hex}")
    }

    fn run(e: &mut Executor, d: &mut MemDevice, line: &str) -> std::string::String {
        let command = parse(line).unwrap();
        e.execute(&ID, d, command)
            .finish(false)
            .as_str()
            .trim_end()
            .to_owned()
    }

    /// `cal start` needs the drive locked (its cycles would all be flagged otherwise); the
    /// dither's setpoint commands are protected, its status is a read.
    #[test]
    fn cal_start_needs_a_locked_drive_and_dither_setpoints_need_the_unlock() {
        let loaded = report(LoadOutcome::Defaults {
            reason: DefaultsReason::Erased,
        });
        let mut e = Executor::new(&loaded, None, 1, AcceptanceLimits::DEFAULT);
        let mut d = MemDevice::default();
        d.drive.controller.disable();
        assert!(run(&mut e, &mut d, &unlock_line()).starts_with("OK"));
        assert!(run(&mut e, &mut d, "cal start 100").starts_with("ERR 11 "));
        assert!(run(&mut e, &mut d, "cal status").starts_with("OK cal=idle"));
        d.drive.controller.enable();
        assert!(run(&mut e, &mut d, "cal start 100").starts_with("OK cal=running"));
        run(&mut e, &mut d, "cal abort");
        run(&mut e, &mut d, "lock");
        for line in [
            "dither on",
            "dither off",
            "dither amp 400",
            "dither noise 5",
        ] {
            assert!(run(&mut e, &mut d, line).starts_with("ERR 9 "), "{line}");
        }
        assert!(run(&mut e, &mut d, "dither status").starts_with("OK state="));
        assert!(run(&mut e, &mut d, &unlock_line()).starts_with("OK"));
        assert!(run(&mut e, &mut d, "dither amp 400").starts_with("OK dither=on amp_arcsec=400"));
    }

    /// A locked client can neither start a run (hours of the board's time), nor abort one, nor
    /// close pooled runs with `cal result`; reading a solved result stays free, and the run
    /// goes on untouched by the refusals.
    #[test]
    fn calibration_commands_that_take_time_or_discard_work_need_the_unlock() {
        use crate::protocol::commands::calibration::tests::cycle;
        let loaded = report(LoadOutcome::Defaults {
            reason: DefaultsReason::Erased,
        });
        let mut e = Executor::new(&loaded, None, 1, AcceptanceLimits::DEFAULT);
        let mut d = MemDevice::default();
        assert!(run(&mut e, &mut d, "cal start 3000").starts_with("ERR 9 "));
        assert_eq!(run(&mut e, &mut d, "cal status"), "OK cal=idle");
        assert!(run(&mut e, &mut d, &unlock_line()).starts_with("OK"));
        assert!(run(&mut e, &mut d, "cal start 3000").starts_with("OK cal=running"));
        run(&mut e, &mut d, "lock");
        assert!(run(&mut e, &mut d, "cal abort").starts_with("ERR 9 "));
        assert!(run(&mut e, &mut d, "cal status").starts_with("OK cal=running"));
        for i in 0..3000 {
            e.on_cycle(
                &cycle(i, core::f64::consts::TAU * 13.888 / 1.8655),
                1.0 / 389.0,
            );
        }
        assert_eq!(
            run(&mut e, &mut d, "cal status"),
            "OK cal=run_done cycles=3000"
        );
        assert!(run(&mut e, &mut d, "cal result").starts_with("ERR 9 "));
        assert!(run(&mut e, &mut d, "cal start 3000").starts_with("ERR 9 "));
        assert_eq!(
            run(&mut e, &mut d, "cal status"),
            "OK cal=run_done cycles=3000"
        );
        assert!(run(&mut e, &mut d, &unlock_line()).starts_with("OK"));
        let solved = run(&mut e, &mut d, "cal result");
        assert!(solved.starts_with("OK a="), "{solved}");
        run(&mut e, &mut d, "lock");
        assert_eq!(
            run(&mut e, &mut d, "cal result"),
            solved,
            "a solved fit is a read"
        );
    }

    /// With tracking on, the commands whose effect the loop would undo at its next update are
    /// refused with the reason (ERR 17) and change nothing; after `track off` they work again.
    #[test]
    fn tracking_refuses_what_it_would_undo() {
        use crate::protocol::commands::calibration::tests::cycle;
        let loaded = report(LoadOutcome::Defaults {
            reason: DefaultsReason::Erased,
        });
        let mut e = Executor::new(&loaded, None, 1, AcceptanceLimits::DEFAULT);
        let mut d = MemDevice::default();
        run(&mut e, &mut d, &unlock_line());
        assert!(run(&mut e, &mut d, "track on").starts_with("OK track=on"));
        let before = d.clone();
        for line in ["set a 5", "comp off", "defaults", "cal accept", "reload"] {
            let answer = run(&mut e, &mut d, line);
            assert!(answer.starts_with("ERR 17 tracking on"), "{line}: {answer}");
        }
        assert_eq!(d, before, "refusals change nothing");
        // What an OK would have meant: the loop stages its own coefficients, compensation on,
        // over a hand-set value within a few hundred cycles.
        let rate = core::f64::consts::TAU * 13.888 / 1.8655;
        let staged = (0..2000).find_map(|i| e.on_cycle(&cycle(i, rate), 1.0 / 389.0).stage);
        assert!(
            staged.is_some_and(|s| s.enabled),
            "the loop overwrites the settings"
        );
        assert!(run(&mut e, &mut d, "track off").starts_with("OK track=off"));
        assert_eq!(run(&mut e, &mut d, "set a 5"), "OK a=5");
    }

    /// Without a CRC a state-changing command is echoed as parsed and waits for `yes`; with
    /// a CRC it runs at once; any other line in between drops it; reads run at once.
    #[test]
    fn state_changes_without_crc_wait_for_a_confirmation_of_the_echo() {
        let loaded = report(LoadOutcome::Defaults {
            reason: DefaultsReason::Erased,
        });
        let mut e = Executor::new(&loaded, None, 1, AcceptanceLimits::DEFAULT);
        let mut d = MemDevice::default();
        let line = |e: &mut Executor, d: &mut MemDevice, text: &str, crc: bool| {
            let command = parse(text).unwrap();
            e.execute_line(&ID, d, command, crc)
                .finish(false)
                .as_str()
                .trim_end()
                .to_owned()
        };
        assert!(line(&mut e, &mut d, &unlock_line(), false).starts_with("OK unlocked"));
        // `set a 12.5` with its "1" dropped on the line: shown before anything happens.
        let before = d.clone();
        assert_eq!(
            line(&mut e, &mut d, "set a 2.5", false),
            "ERR 18 confirm (send yes) cmd=set a 2.5"
        );
        assert_eq!(d, before, "nothing executed");
        assert_eq!(line(&mut e, &mut d, "yes", false), "OK a=2.5");
        assert_eq!(
            line(&mut e, &mut d, "yes", false),
            "ERR 11 not possible now"
        );
        assert!(line(&mut e, &mut d, "store", false).starts_with("ERR 18 "));
        assert!(line(&mut e, &mut d, "get a", false).starts_with("OK a=2.5"));
        assert_eq!(
            line(&mut e, &mut d, "yes", false),
            "ERR 11 not possible now"
        );
        assert!(
            d.stored.is_empty(),
            "the store was dropped by the read in between"
        );
        assert_eq!(
            line(&mut e, &mut d, "set a 3", true),
            "OK a=3",
            "CRC: at once"
        );
        e.execute_line(&ID, &mut d, parse("set b 1").unwrap(), false);
        e.drop_pending();
        assert_eq!(
            line(&mut e, &mut d, "yes", false),
            "ERR 11 not possible now"
        );
    }

    /// `cal result` that would close the pooled runs changes the session (and needs the
    /// unlock), so without a CRC it waits for `yes` like every state change: echoed, nothing
    /// solved, and `cal status` still `run_done`; `yes` solves it. Reading a solved fit is a
    /// read: no confirmation.
    #[test]
    fn cal_result_that_closes_the_runs_waits_for_a_confirmation() {
        use crate::protocol::commands::calibration::tests::cycle;
        let loaded = report(LoadOutcome::Defaults {
            reason: DefaultsReason::Erased,
        });
        let mut e = Executor::new(&loaded, None, 1, AcceptanceLimits::DEFAULT);
        let mut d = MemDevice::default();
        let line = |e: &mut Executor, d: &mut MemDevice, text: &str| {
            e.execute_line(&ID, d, parse(text).unwrap(), false)
                .finish(false)
                .as_str()
                .trim_end()
                .to_owned()
        };
        assert!(line(&mut e, &mut d, &unlock_line()).starts_with("OK unlocked"));
        assert!(line(&mut e, &mut d, "cal start 3000").starts_with("ERR 18 "));
        assert!(line(&mut e, &mut d, "yes").starts_with("OK cal=running"));
        for i in 0..3000 {
            e.on_cycle(
                &cycle(i, core::f64::consts::TAU * 13.888 / 1.8655),
                1.0 / 389.0,
            );
        }
        assert_eq!(
            line(&mut e, &mut d, "cal result"),
            "ERR 18 confirm (send yes) cmd=cal result"
        );
        assert_eq!(
            line(&mut e, &mut d, "cal status"),
            "OK cal=run_done cycles=3000"
        );
        assert_eq!(
            line(&mut e, &mut d, "cal result"),
            "ERR 18 confirm (send yes) cmd=cal result"
        );
        let solved = line(&mut e, &mut d, "yes");
        assert!(solved.starts_with("OK a="), "{solved}");
        assert_eq!(line(&mut e, &mut d, "cal result"), solved, "a read now");
    }

    /// `stream output` hands every record over, with the tracking bit set while the tracker
    /// runs; without it no record goes out.
    #[test]
    fn output_records_carry_the_tracking_bit() {
        let loaded = report(LoadOutcome::Defaults {
            reason: DefaultsReason::Erased,
        });
        let mut e = Executor::new(&loaded, None, 1, AcceptanceLimits::DEFAULT);
        let mut d = MemDevice::default();
        let record = OutputRecord {
            sequence: 1,
            time_ticks: 2,
            period_ticks: 3,
            delta_angle_q16: 4,
            angle_q16: 5,
            rate_deg_per_h: 6.0,
            status: OutputStatus::VALID,
            temperature_q7: crate::thermal::state::NO_VALUE,
            temperature_rate_centi_c_per_min: crate::thermal::state::NO_VALUE,
        };
        assert_eq!(e.on_output(&record), None);
        assert!(run(&mut e, &mut d, "stream output").starts_with("OK stream=output"));
        assert_eq!(e.on_output(&record).map(|o| o.record), Some(record));
        assert!(run(&mut e, &mut d, &unlock_line()).starts_with("OK"));
        assert!(run(&mut e, &mut d, "track on").starts_with("OK"));
        let sent = e.on_output(&record).unwrap();
        assert!(sent
            .record
            .status
            .contains(OutputStatus::TRACKING.union(OutputStatus::VALID)));
    }
}
