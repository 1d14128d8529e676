//! `rlg-cal`: the host side of the readout board's serial calibration protocol.
//!
//! - [`link`]: the byte pipe: a serial port or pty (`serialport` crate), TCP, or the simulated
//!   board in this process (`link::SimLink`, on simulated time).
//! - [`client`]: one command out with its CRC suffix, exactly one checked answer back; `ERR`
//!   answers become typed errors with the code and text; timeouts; stream frames kept apart.
//! - [`ops`]: calibration runs with progress, streaming sessions (both stop when asked).
//! - [`output`]: answers as `key=value` pairs, printed as lines or JSON.
//! - [`console`]: the interactive console (line editing, history, completion, CRC added).
//! - [`capture`]: stream frames to records, lost-frame counts, CSV and SVG.
//! - `sweep`: a rotary-table sweep on the simulated board, through the protocol.
//! - [`thermal`]: the thermal calibration from a log of the output against temperature.
//! - `serve`: the simulated board served on TCP or a pty for any serial client.
//! - `sim`: booting the simulated board; `sim_state`: its state file (`--sim-state`).
//! - [`ranges`]: the valid range of every numeric command-line argument.
//!
//! What the simulated board needs (`link::SimLink`, `sim`, `sim_state`, `serve`, `sweep`)
//! is behind the default cargo feature `sim`: without it the crate talks to real boards only
//! and depends on neither hal-sim nor a random-number generator. What both CLIs share (exit
//! statuses, output files, Ctrl-C, progress bars, figures) is the `host-cli` crate.
//!
//! The protocol itself (commands, answers, error codes, frames, access control) is described
//! in `docs/protocol.md`; its implementation is the firmware's `protocol` module, which this
//! crate reuses for the CRC, the frame decoder and the error codes.

#![warn(missing_docs)]

pub mod capture;
pub mod client;
pub mod console;
pub mod link;
pub mod ops;
pub mod output;
pub mod output_capture;
pub mod ranges;
#[cfg(feature = "sim")]
pub mod serve;
#[cfg(feature = "sim")]
pub mod sim;
#[cfg(feature = "sim")]
pub mod sim_state;
#[cfg(feature = "sim")]
pub mod sweep;
pub mod thermal;
