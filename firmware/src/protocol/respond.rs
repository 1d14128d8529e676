//! Answers: exactly one line per command, `OK <fields>` or `ERR <code> <text>`, with the CRC
//! suffix `*XXXX` when the request carried one, then `\r\n`.
//!
//! Built in a fixed buffer ([`MAX_RESPONSE`] bytes, room for the longest answer, `status`); a field that would overflow it is cut and
//! the answer marked with a trailing `~` rather than dropped, so the host always gets its line.

use super::parse::crc16;
use super::ErrorCode;
use core::fmt::Write;
use heapless::String;

/// Longest answer, bytes (with CRC suffix and terminator).
pub const MAX_RESPONSE: usize = 400;

/// An answer being built.
#[derive(Clone, Debug)]
pub struct Response {
    text: String<MAX_RESPONSE>,
    truncated: bool,
}

/// Room kept for `~*XXXX\r\n`.
const TAIL: usize = 8;

impl Response {
    /// `OK` followed by fields added with [`field`](Self::field).
    pub fn ok() -> Self {
        let mut r = Self {
            text: String::new(),
            truncated: false,
        };
        r.push_str("OK");
        r
    }

    /// `ERR <code> <text>`.
    pub fn err(code: ErrorCode) -> Self {
        let mut r = Self {
            text: String::new(),
            truncated: false,
        };
        r.push_str("ERR");
        r.field(format_args!("{} {}", code.code(), code.text()));
        r
    }

    /// Adds ` <formatted>`.
    pub fn field(&mut self, args: core::fmt::Arguments<'_>) -> &mut Self {
        self.push_str(" ");
        let mut sink = Bounded {
            out: &mut self.text,
            cut: false,
        };
        let _ = sink.write_fmt(args);
        self.truncated |= sink.cut;
        self
    }

    fn push_str(&mut self, s: &str) {
        let mut sink = Bounded {
            out: &mut self.text,
            cut: false,
        };
        let _ = sink.write_str(s);
        self.truncated |= sink.cut;
    }

    /// The finished line: truncation mark, optional CRC suffix over everything before the `*`,
    /// and `\r\n`.
    pub fn finish(mut self, with_checksum: bool) -> String<MAX_RESPONSE> {
        if self.truncated {
            let _ = self.text.push('~');
        }
        if with_checksum {
            let crc = crc16(self.text.as_bytes());
            let _ = write!(self.text, "*{crc:04X}");
        }
        let _ = self.text.push_str("\r\n");
        self.text
    }
}

/// A writer that stops TAIL bytes short of the buffer's end and remembers that it cut.
struct Bounded<'a> {
    out: &'a mut String<MAX_RESPONSE>,
    cut: bool,
}

impl Write for Bounded<'_> {
    fn write_str(&mut self, s: &str) -> core::fmt::Result {
        for c in s.chars() {
            if self.out.len().saturating_add(c.len_utf8()) > MAX_RESPONSE.saturating_sub(TAIL) {
                self.cut = true;
                return Ok(());
            }
            let _ = self.out.push(c);
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ok_and_err_lines() {
        let mut r = Response::ok();
        r.field(format_args!("a={:.6}", 344.25));
        assert_eq!(r.finish(false).as_str(), "OK a=344.250000\r\n");
        assert_eq!(
            Response::err(ErrorCode::Locked).finish(false).as_str(),
            "ERR 9 locked (unlock first)\r\n"
        );
    }

    #[test]
    fn checksum_suffix_covers_the_body() {
        let line = Response::ok().finish(true);
        let body = "OK";
        assert_eq!(
            line.as_str(),
            std::format!("OK*{:04X}\r\n", crc16(body.as_bytes()))
        );
    }

    #[test]
    fn an_overlong_answer_is_cut_and_marked_not_lost() {
        let mut r = Response::ok();
        for i in 0..100 {
            r.field(format_args!("field{i}=123456"));
        }
        let line = r.finish(true);
        assert!(line.len() <= MAX_RESPONSE);
        assert!(line.ends_with("\r\n"));
        assert!(line.contains("~*"));
    }
}
