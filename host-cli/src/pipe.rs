//! Results on stdout, and a reader that goes away.
//!
//! Rust ignores SIGPIPE, so a write to a pipe whose reader has exited (`rlg-sim record --csv
//! /dev/stdout | head -2`) returns `EPIPE` instead of killing the process; `println!` then
//! panics. The CLIs print their results with [`outln!`](crate::outln) and
//! [`out!`](crate::out) instead, which return the error, and map every write error with
//! [`Failure::io`]: a broken pipe ends the run as a success (exit 0) with nothing on stderr,
//! as ripgrep does. Restoring SIGPIPE's default action would end the process as quietly, but
//! with status 141, which `set -o pipefail` reports as a failure.
//!
//! The runs that write rows as they come stop at the first failed write rather than compute
//! what nobody reads (`rlg-sim record`, `rlg-cal record` and `stream`: their row callbacks
//! return `ControlFlow::Break`); the others (`rlg-sim dither`, `sweep`) finish their run and
//! then end quietly the same way.

use crate::Failure;
use std::fmt;
use std::io::{self, Write};

/// Whether `error` says the reader of a pipe has gone.
pub fn is_broken_pipe(error: &io::Error) -> bool {
    error.kind() == io::ErrorKind::BrokenPipe
}

/// Writes `text` to stdout; see [`out!`](crate::out).
pub fn print(text: fmt::Arguments) -> Result<(), Failure> {
    io::stdout()
        .lock()
        .write_fmt(text)
        .map_err(|e| Failure::io("stdout", e))
}

/// Writes `bytes` to stdout and flushes.
pub fn print_bytes(bytes: &[u8]) -> Result<(), Failure> {
    let mut out = io::stdout().lock();
    out.write_all(bytes)
        .and_then(|()| out.flush())
        .map_err(|e| Failure::io("stdout", e))
}

/// `print!` that returns `Result<(), Failure>`: [`Failure::BrokenPipe`] when the reader has
/// gone.
#[macro_export]
macro_rules! out {
    ($($arg:tt)*) => {
        $crate::pipe::print(format_args!($($arg)*))
    };
}

/// `println!` that returns `Result<(), Failure>`: [`Failure::BrokenPipe`] when the reader has
/// gone.
#[macro_export]
macro_rules! outln {
    ($($arg:tt)*) => {
        $crate::pipe::print(format_args!("{}\n", format_args!($($arg)*)))
    };
}
