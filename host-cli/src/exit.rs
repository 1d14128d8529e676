//! How a command ends: one exit status per kind of failure, the same in both CLIs, and the
//! one line on stderr that says why.
//!
//! | status | meaning |
//! |---|---|
//! | 0 | success, or the reader of stdout went away ([`Failure::BrokenPipe`]) |
//! | 1 | the run failed: a fit refused, a file not written, the board answered `ERR` |
//! | 2 | usage: bad arguments, an output file that cannot be created, no key for a protected step |
//! | 3 | the connection: none, no answer within the timeout, a corrupted answer (`rlg-cal`) |
//! | 130 | stopped by Ctrl-C or SIGTERM ([`crate::interrupt`]), after what was done is kept |
//!
//! Each CLI's help lists the statuses it gives, each in its own words, from these constants
//! ([`help`]), so the numbers are written here only.
//!
//! A command returns `Result<(), Failure>`; `main` hands it to [`exit`], which prints the
//! message with the program's name and gives the status. clap's own usage errors exit 2 too.
//! An error type of a library that knows its own status (`rlg-cal`'s client errors) travels
//! whole in [`Failure::Error`], so the CLI can report it its own way as well (`rlg-cal --json`
//! puts a board's refusal on stdout).

use std::fmt;
use std::process::ExitCode;

/// Exit status of a success, and of a run whose reader of stdout went away.
pub const SUCCESS: u8 = 0;
/// Exit status of a run that failed (and of a board that refused a command).
pub const FAILED: u8 = 1;
/// Exit status of a usage error: bad arguments, an unwritable output, a missing key.
pub const USAGE: u8 = 2;
/// Exit status of a failed connection: none, no answer in time, a corrupted answer.
pub const CONNECTION: u8 = 3;
/// Exit status of a run ended by SIGINT or SIGTERM: 128 + SIGINT, what a shell reports for a
/// process killed by Ctrl-C.
pub const INTERRUPTED: u8 = 130;

/// Why a command failed; decides the exit status and the message.
#[derive(Debug)]
pub enum Failure {
    /// Exit 2, before any work: the message says which argument or file.
    Usage(String),
    /// Exit 1: the run failed.
    Run(String),
    /// Exit 3: no connection, no answer, or a corrupted one.
    Connect(String),
    /// Exit 130: stopped by Ctrl-C or SIGTERM; the message says what was kept.
    Interrupted(String),
    /// A library's error that knows its exit status; its `Display` is the message.
    Error {
        /// The exit status.
        status: u8,
        /// The error, kept whole (e.g. for `downcast_ref`).
        error: Box<dyn std::error::Error + Send + Sync>,
    },
    /// The reader of stdout (or of an output file that is a pipe) went away, as `head` does:
    /// a clean end, exit 0, nothing printed.
    BrokenPipe,
}

impl Failure {
    /// The failure of writing to `what` (a path, `stdout`): [`Failure::BrokenPipe`] when the
    /// reader has gone, else [`Failure::Run`] with `what` and the error.
    pub fn io(what: impl fmt::Display, error: std::io::Error) -> Self {
        if crate::pipe::is_broken_pipe(&error) {
            Self::BrokenPipe
        } else {
            Self::Run(format!("{what}: {error}"))
        }
    }

    /// The process exit status.
    pub fn status(&self) -> u8 {
        match self {
            Self::Usage(_) => USAGE,
            Self::Run(_) => FAILED,
            Self::Connect(_) => CONNECTION,
            Self::Interrupted(_) => INTERRUPTED,
            Self::Error { status, .. } => *status,
            Self::BrokenPipe => SUCCESS,
        }
    }

    /// The line for stderr, after `program: ` (none for a broken pipe).
    pub fn message(&self) -> Option<String> {
        match self {
            Self::Usage(m) => Some(format!("error: {m}")),
            Self::Run(m) | Self::Connect(m) => Some(m.clone()),
            Self::Interrupted(m) => Some(format!("interrupted: {m}")),
            Self::Error { error, .. } => Some(error.to_string()),
            Self::BrokenPipe => None,
        }
    }
}

/// Width of the help's exit-status lines: a meaning longer than this goes on under itself.
const HELP_WIDTH: usize = 96;

/// The "Exit status:" section of a CLI's help: one line per `(status, meaning)`, the status
/// from the constants of this module and the meaning in the CLI's words, wrapped under
/// itself at `HELP_WIDTH` columns.
pub fn help(statuses: &[(u8, &str)]) -> String {
    const INDENT: &str = "       ";
    let mut text = String::from("Exit status:");
    for (status, meaning) in statuses {
        let mut line = format!("  {status:<5}");
        let mut first = true;
        for word in meaning.split_whitespace() {
            if !first && line.len() + 1 + word.len() > HELP_WIDTH {
                text.push('\n');
                text.push_str(line.trim_end());
                line = INDENT.to_owned();
                first = true;
            }
            if !first {
                line.push(' ');
            }
            line.push_str(word);
            first = false;
        }
        text.push('\n');
        text.push_str(&line);
    }
    text
}

/// The end of `main`: the message on stderr as `program: message`, and the exit status.
pub fn exit(program: &str, outcome: Result<(), Failure>) -> ExitCode {
    match outcome {
        Ok(()) => ExitCode::SUCCESS,
        Err(failure) => {
            if let Some(message) = failure.message() {
                eprintln!("{program}: {message}");
            }
            ExitCode::from(failure.status())
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::{Error, ErrorKind};

    /// The table of the module docs, and a closed pipe is a quiet success.
    #[test]
    fn each_failure_has_its_status_and_message() {
        let cases = [
            (Failure::Usage("--x".into()), 2, Some("error: --x")),
            (Failure::Run("fit".into()), 1, Some("fit")),
            (Failure::Connect("port".into()), 3, Some("port")),
            (
                Failure::Interrupted("3 rows".into()),
                130,
                Some("interrupted: 3 rows"),
            ),
            (
                Failure::Error {
                    status: 3,
                    error: "no answer".into(),
                },
                3,
                Some("no answer"),
            ),
            (Failure::BrokenPipe, 0, None),
        ];
        for (failure, status, message) in cases {
            assert_eq!(failure.status(), status, "{failure:?}");
            assert_eq!(failure.message().as_deref(), message, "{failure:?}");
        }
    }

    /// The statuses' numbers come from the constants; a long meaning wraps under itself.
    #[test]
    fn the_help_lists_each_status_with_its_meaning() {
        let long = "usage error (bad arguments, an output file that cannot be created, no key \
                    for a protected step, and more words to pass the width)";
        let text = help(&[(SUCCESS, "success"), (USAGE, long), (INTERRUPTED, "Ctrl-C")]);
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(
            lines,
            [
                "Exit status:",
                "  0    success",
                "  2    usage error (bad arguments, an output file that cannot be created, no key for a protected",
                "       step, and more words to pass the width)",
                "  130  Ctrl-C",
            ]
        );
        assert!(lines.iter().all(|l| l.len() <= HELP_WIDTH), "{text}");
    }

    /// Writing fails: a gone reader is the quiet end, anything else a failed run naming what.
    #[test]
    fn io_errors_of_a_gone_reader_are_quiet() {
        let gone = Failure::io("out.csv", Error::from(ErrorKind::BrokenPipe));
        assert!(matches!(gone, Failure::BrokenPipe));
        let full = Failure::io("out.csv", Error::other("disk full"));
        assert_eq!(full.message().as_deref(), Some("out.csv: disk full"));
        assert_eq!(full.status(), 1);
    }
}
