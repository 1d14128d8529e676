//! The defence against a corrupted command: state-changing commands need the CRC, or a
//! person's confirmation of the command as the board understood it.
//!
//! Over a noisy link a dropped byte can turn one valid command into another (`set a 12.5`
//! into `set a 2.5`, `cal start 4000` into `cal start 400`). The CRC suffix catches that, and
//! the host tool always sends it. A person at a terminal does not type CRCs, so a
//! state-changing line without one ([`needs_confirmation`]) is not executed: the board answers
//! `ERR 18 confirm (send yes) cmd=<the command as parsed>` and keeps it pending. The person
//! reads the echo and sends `yes` to execute exactly that command; any other line drops it. A
//! corrupted line is thus either refused by the parser, or shown to the person before it acts.
//!
//! Reads, `stream`, `unlock` and `lock` need neither: a corrupted read changes nothing, and a
//! corrupted `unlock` fails (a wrong key) or locks.

use core::fmt;

use super::parse::{Coefficient, Command, DitherCommand, ThermalCommand};

/// Commands that change the board's state, its work or its flash: without a CRC they wait for
/// `yes`. `cal result` is listed as a read: the executor adds it while it would close pooled
/// runs (solving ends pooling), when it changes the session.
pub fn needs_confirmation(command: &Command) -> bool {
    if let Command::Thermal(thermal) = command {
        return !thermal.is_read();
    }
    !matches!(
        command,
        Command::Help
            | Command::Identify
            | Command::Status
            | Command::SelfTest
            | Command::OutputStatus
            | Command::Get(_)
            | Command::CalStatus
            | Command::CalResult
            | Command::Stream(_)
            | Command::StreamOutput
            | Command::Unlock(_)
            | Command::Lock
            | Command::Confirm
            | Command::Dither(DitherCommand::Status)
    )
}

/// A command as the board parsed it, in the protocol's own words (numbers as the parser read
/// them), for the echo.
pub struct Canonical<'a>(pub &'a Command);

fn on_off(on: bool) -> &'static str {
    if on {
        "on"
    } else {
        "off"
    }
}

impl fmt::Display for Canonical<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self.0 {
            Command::Help => f.write_str("help"),
            Command::Identify => f.write_str("id"),
            Command::Status => f.write_str("status"),
            Command::OutputStatus => f.write_str("output status"),
            Command::SelfTest => f.write_str("selftest"),
            Command::Thermal(thermal) => thermal_words(f, &thermal),
            Command::Get(None) => f.write_str("get coeffs"),
            Command::Get(Some(Coefficient::A)) => f.write_str("get a"),
            Command::Get(Some(Coefficient::B)) => f.write_str("get b"),
            Command::Set(Coefficient::A, v) => write!(f, "set a {v}"),
            Command::Set(Coefficient::B, v) => write!(f, "set b {v}"),
            Command::Compensation(on) => write!(f, "comp {}", on_off(on)),
            Command::Tracking(on) => write!(f, "track {}", on_off(on)),
            Command::CalStart {
                cycles,
                warmup_cycles,
            } => write!(f, "cal start {cycles} {warmup_cycles}"),
            Command::CalStatus => f.write_str("cal status"),
            Command::CalAbort => f.write_str("cal abort"),
            Command::CalResult => f.write_str("cal result"),
            Command::CalAccept => f.write_str("cal accept"),
            Command::Store => f.write_str("store"),
            Command::Reload => f.write_str("reload"),
            Command::Defaults => f.write_str("defaults"),
            Command::Stream(None) => f.write_str("stream off"),
            Command::Stream(Some(n)) => write!(f, "stream on {n}"),
            Command::StreamOutput => f.write_str("stream output"),
            Command::Unlock(_) => f.write_str("unlock <key>"),
            Command::KeyProvision(key) => write!(f, "key provision {}", key.hex()),
            Command::Lock => f.write_str("lock"),
            Command::Confirm => f.write_str("yes"),
            Command::Dither(DitherCommand::Enable(on)) => write!(f, "dither {}", on_off(on)),
            Command::Dither(DitherCommand::Amplitude(v)) => write!(f, "dither amp {v}"),
            Command::Dither(DitherCommand::Noise(v)) => write!(f, "dither noise {v}"),
            Command::Dither(DitherCommand::Status) => f.write_str("dither status"),
        }
    }
}

fn thermal_words(f: &mut fmt::Formatter<'_>, command: &ThermalCommand) -> fmt::Result {
    use crate::thermal::model::ThermalModel;
    match *command {
        ThermalCommand::Read => f.write_str("thermal"),
        ThermalCommand::Model => f.write_str("thermal model"),
        ThermalCommand::Set(index, v) => {
            let name = ThermalModel::NAMES.get(usize::from(index)).unwrap_or(&"?");
            write!(f, "thermal set {name} {v}")
        }
        ThermalCommand::Apply => f.write_str("thermal apply"),
        ThermalCommand::Enable(on) => write!(f, "thermal {}", on_off(on)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::protocol::parse::parse;

    /// The echo parses back to the same command (so what the person confirms is what runs).
    #[test]
    fn the_echo_reads_back_as_the_same_command() {
        for line in [
            "set a 2.5",
            "SET B -1e2",
            "comp off",
            "track on",
            "cal start 4000 400",
            "cal start 400",
            "cal abort",
            "cal accept",
            "store",
            "reload",
            "defaults",
            "dither amp 420.5",
            "dither noise 3",
            "dither off",
            "thermal set t_min -20",
            "thermal set B3 -1.25e-7",
            "thermal set s2 0.005",
            "thermal apply",
            "thermal off",
            "key provision 00112233445566778899AABBCCDDEEFF",
        ] {
            let command = parse(line).unwrap();
            assert!(needs_confirmation(&command), "{line}");
            let echo = format!("{}", Canonical(&command));
            assert_eq!(parse(&echo), Ok(command), "{line} -> {echo}");
        }
        for line in [
            "status",
            "get a",
            "cal status",
            "stream on 2",
            "lock",
            "help",
            "thermal",
            "thermal model",
        ] {
            assert!(!needs_confirmation(&parse(line).unwrap()), "{line}");
        }
    }
}
