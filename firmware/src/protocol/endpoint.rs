//! The serial end of the protocol, shared by the board and the simulated board: a completed
//! line in, exactly one answer out, framed for the mode the host is in.
//!
//! The command service (`crate::service`) calls these functions; the board's main loop and
//! hal-sim's `SimDevice` both run that service, so the line handling the simulator tests is the
//! very code the board runs.

use super::execute::{DeviceLink, DeviceStatus, Executor, Identity};
use super::line::LineEvent;
use super::parse::{parse, strip_checksum};
use super::respond::{Response, MAX_RESPONSE};
use super::ErrorCode;
use crate::readout::ReadoutCounters;
use crate::signal::lockin::CycleFlags;
use crate::signal::output::RateReading;
use heapless::String;

/// The answer to one line event: a rejected line (too long, garbage, bad CRC, parse error) is
/// answered without touching the device; a command is executed against it.
pub fn answer<D: DeviceLink>(
    event: LineEvent<'_>,
    executor: &mut Executor,
    identity: &Identity,
    device: &mut D,
) -> String<MAX_RESPONSE> {
    let text = match event {
        LineEvent::TooLong => return refused(executor, ErrorCode::LineTooLong, false),
        LineEvent::Garbage => return refused(executor, ErrorCode::InvalidCharacters, false),
        LineEvent::Line(text) => text,
    };
    let (body, with_crc) = match strip_checksum(text) {
        Ok(split) => split,
        Err(code) => return refused(executor, code, false),
    };
    match parse(body) {
        Ok(command) => executor
            .execute_line(identity, device, command, with_crc)
            .finish(with_crc),
        Err(code) => refused(executor, code, with_crc),
    }
}

/// A line refused before it became a command: it still ends a pending confirmation (only the
/// line right after the echo may confirm).
fn refused(executor: &mut Executor, code: ErrorCode, with_crc: bool) -> String<MAX_RESPONSE> {
    executor.drop_pending();
    Response::err(code).finish(with_crc)
}

/// Sends an answer: as it is in text mode; wrapped in 0x00 delimiters (`wrapped`) when a
/// stream is on before or after its line: an answer sent while streaming, and the answer that
/// starts a stream. So a host that splits at 0x00 from the first byte after its `stream`
/// command sees the answer as one chunk (text has no 0x00), then the frames; and a host in
/// text mode reads every other answer as a plain line.
pub fn send_answer(wrapped: bool, answer: &str, mut send: impl FnMut(&[u8])) {
    if wrapped {
        send(&[0]);
    }
    send(answer.as_bytes());
    if wrapped {
        send(&[0]);
    }
}

impl DeviceStatus {
    /// Copies the readout's counters and measured dither (amplitude in beat-phase rad, Hz).
    pub fn update_from(
        &mut self,
        counters: &ReadoutCounters,
        (amplitude_rad, dither_hz): (f32, f32),
    ) {
        self.dither_amplitude_rad = amplitude_rad;
        self.dither_hz = dither_hz;
        self.turnarounds = counters.turnarounds;
        self.cycles = counters.cycles;
        self.counter_glitches = counters.counter_glitches;
        self.phase_glitches = counters.phase_glitches;
        self.signal_lost = counters.signal_lost;
    }

    /// Folds one dither cycle's flags, and a new averaged rate if one is due, into the status.
    pub fn on_cycle(&mut self, flags: CycleFlags, reading: Option<RateReading>) {
        self.signal_ok = !flags.contains(CycleFlags::SIGNAL_LOST);
        if flags.contains(CycleFlags::TURNAROUND_MISSED) {
            self.missed_turnarounds = self.missed_turnarounds.saturating_add(1);
        }
        if let Some(reading) = reading {
            self.rate_deg_per_h = reading.rate_deg_per_h as f32;
        }
    }
}
