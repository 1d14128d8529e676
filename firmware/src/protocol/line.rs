//! Line assembly: serial bytes in, complete command lines out, in a bounded buffer.
//!
//! A line ends at `\n`; a `\r` right before it is dropped, and so is a `\r` right after it (the
//! LF CR order some terminals send), so neither order leaves a stray `\r` in the next line. Whatever arrives, the assembler
//! never grows, never panics and keeps in step with the line boundaries:
//!
//! - a line longer than [`MAX_LINE`] bytes is discarded up to its `\n` and reported once as
//!   [`LineEvent::TooLong`];
//! - a byte that is neither printable ASCII nor a tab (binary data, line noise, a baud-rate
//!   mismatch, a stray `\r`) marks the line as garbage, reported as [`LineEvent::Garbage`] at
//!   its `\n`;
//! - empty lines produce nothing: they are not commands.
//!
//! So every non-empty line produces exactly one event, and with it exactly one answer.

use heapless::Vec;

/// Longest accepted line, bytes (without the terminator).
pub const MAX_LINE: usize = 96;

/// What a byte completed.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum LineEvent<'a> {
    /// A complete line of printable ASCII, without its terminator.
    Line(&'a str),
    /// A line over [`MAX_LINE`] bytes ended; it was discarded.
    TooLong,
    /// A line with non-printable bytes ended; it was discarded.
    Garbage,
}

/// The assembler's state.
#[derive(Clone, Debug, Default)]
pub struct LineAssembler {
    buffer: Vec<u8, MAX_LINE>,
    overflowed: bool,
    garbage: bool,
    /// A `\r` was the last byte; it is dropped if a `\n` follows, garbage otherwise.
    pending_cr: bool,
    /// The buffer holds the line last returned; clear it before the next byte.
    delivered: bool,
    /// The last byte was a `\n`: a `\r` now is the second half of an LF CR ending.
    after_lf: bool,
}

impl LineAssembler {
    /// Empty, at the start of a line.
    pub const fn new() -> Self {
        Self {
            buffer: Vec::new(),
            overflowed: false,
            garbage: false,
            pending_cr: false,
            delivered: false,
            after_lf: false,
        }
    }

    /// Takes one byte; returns an event when it ends a non-empty line.
    pub fn push(&mut self, byte: u8) -> Option<LineEvent<'_>> {
        if self.delivered {
            self.buffer.clear();
            self.delivered = false;
        }
        if core::mem::take(&mut self.after_lf) && byte == b'\r' {
            return None;
        }
        if byte == b'\n' {
            self.after_lf = true;
            let event = if self.overflowed {
                Some(LineEvent::TooLong)
            } else if self.garbage {
                Some(LineEvent::Garbage)
            } else {
                None
            };
            let empty = self.buffer.is_empty();
            self.overflowed = false;
            self.garbage = false;
            self.pending_cr = false;
            self.delivered = true;
            if event.is_some() || empty {
                return event;
            }
            // Only printable ASCII got in, so the bytes are valid UTF-8.
            return core::str::from_utf8(&self.buffer).ok().map(LineEvent::Line);
        }
        if core::mem::take(&mut self.pending_cr) {
            self.garbage = true;
        }
        if byte == b'\r' {
            self.pending_cr = true;
        } else if !(byte == b'\t' || (0x20..0x7f).contains(&byte)) {
            self.garbage = true;
        } else if self.buffer.push(byte).is_err() {
            self.overflowed = true;
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Feeds bytes, collecting events as owned values.
    fn feed(asm: &mut LineAssembler, bytes: &[u8]) -> std::vec::Vec<std::string::String> {
        let mut out = std::vec::Vec::new();
        for &b in bytes {
            match asm.push(b) {
                Some(LineEvent::Line(l)) => out.push(format!("L:{l}")),
                Some(LineEvent::TooLong) => out.push("TOOLONG".into()),
                Some(LineEvent::Garbage) => out.push("GARBAGE".into()),
                None => {}
            }
        }
        out
    }

    #[test]
    fn lines_with_both_terminators_and_empty_lines() {
        let mut asm = LineAssembler::new();
        let out = feed(&mut asm, b"status\r\nget a\n\n\r\nid\n");
        assert_eq!(out, ["L:status", "L:get a", "L:id"]);
    }

    #[test]
    fn an_overlong_line_is_reported_once_and_the_next_line_is_clean() {
        let mut asm = LineAssembler::new();
        let mut bytes = std::vec![b'x'; 500];
        bytes.extend_from_slice(b"\nstatus\n");
        assert_eq!(feed(&mut asm, &bytes), ["TOOLONG", "L:status"]);
        // Exactly MAX_LINE bytes still fit.
        let mut exact = std::vec![b'y'; MAX_LINE];
        exact.push(b'\n');
        assert_eq!(feed(&mut asm, &exact).len(), 1);
        assert!(feed(&mut asm, &exact)[0].starts_with("L:y"));
    }

    #[test]
    fn binary_garbage_and_stray_carriage_returns() {
        let mut asm = LineAssembler::new();
        assert_eq!(feed(&mut asm, b"ge\x00t a\n"), ["GARBAGE"]);
        assert_eq!(feed(&mut asm, b"get\ra\n"), ["GARBAGE"]);
        assert_eq!(feed(&mut asm, b"\xff\xfe\n"), ["GARBAGE"]);
        assert_eq!(feed(&mut asm, b"get a\n"), ["L:get a"]);
    }

    /// Random bytes: never a panic, one event per non-empty line at most, lines printable.
    #[test]
    fn random_bytes_never_break_it() {
        let mut asm = LineAssembler::new();
        let mut x: u64 = 0x9E37_79B9_7F4A_7C15;
        let mut newlines = 0;
        let mut events = 0;
        for _ in 0..200_000 {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            let b = if x.is_multiple_of(50) {
                b'\n'
            } else {
                (x >> 24) as u8
            };
            newlines += (b == b'\n') as usize;
            if let Some(e) = asm.push(b) {
                events += 1;
                if let LineEvent::Line(l) = e {
                    assert!(l.len() <= MAX_LINE);
                    assert!(l.bytes().all(|c| c == b'\t' || (0x20..0x7f).contains(&c)));
                }
            }
        }
        assert!(events <= newlines && events > 0);
    }

    /// LF CR endings (a terminal's order): the CR after each LF is dropped, so the next
    /// command arrives intact; a CR anywhere else in a line still marks it as garbage.
    #[test]
    fn lf_cr_endings_do_not_break_the_next_line() {
        let mut asm = LineAssembler::new();
        assert_eq!(
            feed(&mut asm, b"get a\n\rset a 1\n\rstatus\n\r"),
            ["L:get a", "L:set a 1", "L:status"]
        );
        assert_eq!(feed(&mut asm, b"get\ra\n"), ["GARBAGE"]);
        assert_eq!(
            feed(&mut asm, b"\n\r\rid\n"),
            ["GARBAGE"],
            "only one CR is dropped"
        );
    }
}
