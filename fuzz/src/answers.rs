//! What every line-driven target checks of the board's output, independently of the firmware's
//! own code: the form of an answer, which lines deserve one, and how the serial output splits
//! into answers and frames.

use firmware::protocol::parse::crc16;
use firmware::protocol::respond::MAX_RESPONSE;
use firmware::protocol::ErrorCode;

/// Whether a line ends in a valid `*XXXX` suffix (independently of the firmware's parser).
pub fn has_valid_crc(line: &str) -> bool {
    let Some((body, suffix)) = line.rsplit_once('*') else {
        return false;
    };
    let suffix = suffix.trim_end_matches([' ', '\t']);
    suffix.len() == 4
        && suffix.bytes().all(|b| b.is_ascii_hexdigit())
        && u16::from_str_radix(suffix, 16).ok() == Some(crc16(body.as_bytes()))
}

/// Checks an answer's form; returns its error code (`None` for `OK`). `with_crc`: the request
/// carried a valid CRC, so the answer must carry one; `None`: not known here (either form).
pub fn check_answer(answer: &str, with_crc: Option<bool>) -> Option<u8> {
    assert!(answer.len() <= MAX_RESPONSE, "too long: {answer:?}");
    let line = answer.strip_suffix("\r\n").expect("ends in CRLF");
    assert!(
        line.bytes().all(|b| (0x20..0x7f).contains(&b)),
        "printable: {answer:?}"
    );
    let suffixed = line
        .rsplit_once('*')
        .filter(|(_, crc)| crc.len() == 4 && crc.bytes().all(|b| b.is_ascii_hexdigit()));
    let body = match (with_crc, suffixed) {
        (Some(true) | None, Some((body, crc))) => {
            assert_eq!(crc, format!("{:04X}", crc16(body.as_bytes())), "{answer:?}");
            body
        }
        (Some(true), None) => panic!("CRC suffix expected: {answer:?}"),
        (Some(false), _) => {
            assert!(!line.contains('*'), "no CRC suffix expected: {answer:?}");
            line
        }
        (None, None) => line,
    };
    let body = body.strip_suffix('~').unwrap_or(body);
    if body == "OK" || body.starts_with("OK ") {
        return None;
    }
    let rest = body.strip_prefix("ERR ").expect("OK or ERR");
    let (number, text) = rest.split_once(' ').expect("ERR <code> <text>");
    let code: u8 = number.parse().expect("numeric code");
    let known = ErrorCode::ALL
        .iter()
        .find(|c| c.code() == code)
        .unwrap_or_else(|| panic!("unknown code in {answer:?}"));
    assert!(text.starts_with(known.text()), "{answer:?}");
    Some(code)
}

/// Counts the lines that deserve an answer, byte by byte, by the protocol's rules (not the
/// firmware's assembler): a line ends at `\n`; `\r` before it is dropped, and so is a `\r`
/// right after a `\n`; empty lines get no answer.
#[derive(Clone, Debug, Default)]
pub struct LineCounter {
    /// Non-empty lines completed.
    pub lines: usize,
    line_bytes: usize,
    pending_cr: bool,
    after_lf: bool,
}

impl LineCounter {
    /// One byte sent to the board.
    pub fn push(&mut self, byte: u8) {
        let dropped = core::mem::replace(&mut self.after_lf, byte == b'\n') && byte == b'\r';
        if dropped {
            self.after_lf = false;
        } else if byte == b'\n' {
            self.lines += usize::from(self.line_bytes > 0);
            self.line_bytes = 0;
            self.pending_cr = false;
        } else {
            // A '\r' counts only once something follows it on the line.
            self.line_bytes += usize::from(self.pending_cr);
            self.pending_cr = byte == b'\r';
            self.line_bytes += usize::from(byte != b'\r');
        }
    }

    /// A new session or a reset: the line being typed is gone.
    pub fn restart(&mut self) {
        *self = Self {
            lines: self.lines,
            ..Self::default()
        };
    }
}

/// The serial output split as a host splits it: text answers (`OK`/`ERR` lines, plain or
/// wrapped in 0x00) and binary frames (COBS, each ended by 0x00). A frame never starts with
/// `O` or `E` (its first COBS code is at most 46), so the two cannot be confused.
#[derive(Debug, Default)]
pub struct Output {
    /// The answer lines, each with its `\r\n`, in order.
    pub answers: Vec<String>,
    /// The frames, without their 0x00.
    pub frames: Vec<Vec<u8>>,
}

/// Splits `bytes` (a whole number of answers and frames: the device's output up to now).
pub fn split_output(bytes: &[u8]) -> Output {
    let mut out = Output::default();
    for piece in bytes.split(|&b| b == 0) {
        let mut rest = piece;
        while rest.starts_with(b"OK") || rest.starts_with(b"ERR") {
            let end = rest
                .windows(2)
                .position(|w| w == b"\r\n")
                .unwrap_or_else(|| panic!("an answer without CRLF: {rest:?}"));
            let (line, after) = rest.split_at(end + 2);
            let line = String::from_utf8(line.to_vec()).expect("answers are ASCII");
            out.answers.push(line);
            rest = after;
        }
        if !rest.is_empty() {
            out.frames.push(rest.to_vec());
        }
    }
    out
}
