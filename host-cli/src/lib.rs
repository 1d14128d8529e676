//! What the two host command-line tools, `rlg-sim` (the simulator) and `rlg-cal` (the board's
//! calibration tool), share: how a command ends and what it prints when it fails, the range of
//! a numeric flag, the checks of output files before a long run, a closed stdout, Ctrl-C,
//! progress bars, shell completions and the SVG figures.
//!
//! The CLIs follow the conventions of ripgrep: results on stdout, progress and errors on
//! stderr with the program's name, one exit status per kind of failure ([`exit`]); every
//! precondition of a long run checked before it starts ([`output_file`]); a reader that goes
//! away (`| head`) ends the run quietly with status 0 ([`pipe`]); Ctrl-C stops a run the way
//! a finished one stops ([`interrupt`]); every numeric flag's range is checked by the parser
//! that also prints it in the help ([`range`]).
//!
//! The crate holds no domain knowledge (no gyro, no protocol): each CLI keeps its own
//! subcommands and reports, and depends on this crate instead of on the other CLI. It
//! depends on clap (the completions' arguments), clap_complete, indicatif, libc (the signal
//! handler) and plotters (SVG backend only).

#![warn(missing_docs)]

pub mod completions;
pub mod exit;
pub mod interrupt;
pub mod output_file;
pub mod pipe;
pub mod plot;
pub mod progress;
pub mod range;

pub use exit::Failure;
