//! The protocol client: one command out, always with its CRC suffix, and exactly one checked
//! answer back.
//!
//! - A command goes out as `<text>*XXXX\n` (CRC-16/CCITT-FALSE of `<text>`, the firmware's
//!   [`crc16`]); the board answers a checksummed request with a checksummed answer, and the
//!   client refuses an answer without a valid suffix ([`ClientError::Corrupt`]).
//! - `OK <fields>` becomes an [`Answer`]; `ERR <code> <text>` becomes
//!   [`ClientError::Device`] with the code and text; no complete answer within the timeout is
//!   [`ClientError::Timeout`].
//! - Bytes that arrived before a command are not its answer: in text mode they are dropped,
//!   in stream mode the answers among them are (the frames are kept); after a timeout, the
//!   late answer is awaited for one more timeout and dropped, so no answer passes for the
//!   next command's. An answer is the bytes up to `\r\n`. Leftovers of a binary stream (from an
//!   earlier session) before it are skipped: anything up to a 0x00, and lines that are neither
//!   printable nor start with `OK`/`ERR`; so are notice lines starting with `#` (the board's
//!   start-up banner `# rlg-readout ready`).
//! - Stream mode (after `OK stream=on` or `OK stream=output`, which come wrapped in 0x00 like
//!   every answer while a stream is on): the board interleaves frames (COBS, 0x00-terminated)
//!   with answers wrapped in 0x00 delimiters; the client splits at 0x00 and keeps the frames
//!   for [`Client::take_frames`]. A frame never starts with `O` or `E` (its first COBS code is
//!   at most 46), so the two cannot be confused. `OK stream=off` returns to text mode.
//! - The key is sent, never shown: answers and errors carry the command as [`shown_command`]
//!   gives it (`unlock <key>`), so no message on stderr, no `--json` object and no log holds
//!   the key.
//!
//! Size (over 600 lines): the line framing, the answer checks and the stream handling share the
//! link's buffer and its time-out.

use crate::link::Link;
use firmware::protocol::line::MAX_LINE;
use firmware::protocol::parse::crc16;
use firmware::protocol::ErrorCode;
use host_cli::exit;
use std::fmt;
use std::io;
use std::str::FromStr;
use std::time::Duration;

/// Every error code of the protocol, to name the number in an `ERR` answer.
const CODES: [ErrorCode; 18] = ErrorCode::ALL;

/// The firmware's name for an error number, if it has one.
pub fn error_code(code: u8) -> Option<ErrorCode> {
    CODES.into_iter().find(|c| c.code() == code)
}

/// An `OK` answer: its fields, without `OK`, the truncation mark and the CRC.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Answer {
    /// The command text it answers, as sent (without the CRC suffix).
    pub command: String,
    /// The fields after `OK`, space-separated (mostly `key=value`).
    pub text: String,
    /// The board cut the answer to fit its buffer (`~`).
    pub truncated: bool,
}

impl Answer {
    /// The value of `key=value`, if present.
    pub fn field(&self, key: &str) -> Option<&str> {
        self.text
            .split(' ')
            .find_map(|w| w.strip_prefix(key).and_then(|w| w.strip_prefix('=')))
    }

    /// The value of `key=value`, parsed.
    pub fn parse_field<T: FromStr>(&self, key: &str) -> Result<T, ClientError> {
        self.field(key)
            .and_then(|v| v.parse().ok())
            .ok_or_else(|| ClientError::Unexpected {
                command: self.command.clone(),
                answer: self.text.clone(),
                what: format!("no valid {key}= field"),
            })
    }

    /// The answer as `key=value` pairs ([`crate::output::fields`]).
    pub fn fields(&self) -> Vec<(String, String)> {
        crate::output::fields(&self.text)
    }

    /// The answer as `key=value` lines, one field a line.
    pub fn display_lines(&self) -> String {
        crate::output::key_value_lines(&self.fields())
    }
}

/// An `ERR` answer.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct DeviceError {
    /// The command text it answers, as sent (without the CRC suffix).
    pub command: String,
    /// The number after `ERR` (the firmware's `ErrorCode`, 1..=15).
    pub code: u8,
    /// The firmware's name for the code (`None` for a code this tool does not know).
    pub kind: Option<ErrorCode>,
    /// Everything after the code: the error's text and any detail fields.
    pub text: String,
}

/// Why a command did not get an `OK`.
#[derive(Debug)]
pub enum ClientError {
    /// The board answered `ERR`.
    Device(DeviceError),
    /// No complete answer within the timeout.
    Timeout {
        /// The command text sent.
        command: String,
        /// The timeout that ran out.
        after: Duration,
    },
    /// An answer with a wrong or missing CRC, or not a protocol answer at all.
    Corrupt {
        /// The command text sent.
        command: String,
        /// The line received (lossy UTF-8, with its `\r\n`).
        line: String,
        /// What is wrong with it (from [`check_answer`]).
        reason: &'static str,
    },
    /// The link failed (closed, I/O error).
    Link(io::Error),
    /// The command cannot be sent (too long, line break or `*` in it).
    BadCommand(String),
    /// The run was stopped by SIGINT or SIGTERM (the board was told: `cal abort`, `stream
    /// off`).
    Interrupted {
        /// What was running.
        what: String,
    },
    /// An answer without a field this tool needs, or a run that did not go as it should.
    Unexpected {
        /// The command text sent.
        command: String,
        /// The `OK` answer's fields.
        answer: String,
        /// What was missing or went wrong.
        what: String,
    },
}

impl ClientError {
    /// The process exit code (see `rlg-cal --help`): 1 the board refused or the run failed,
    /// 3 the link failed (timeout, corrupted answer, I/O, or the board got a garbled command).
    pub fn exit_code(&self) -> u8 {
        match self {
            // The board received a garbled command: line noise.
            Self::Device(e) if (6..=8).contains(&e.code) => exit::CONNECTION,
            Self::Device(_) | Self::Unexpected { .. } | Self::BadCommand(_) => exit::FAILED,
            Self::Timeout { .. } | Self::Corrupt { .. } | Self::Link(_) => exit::CONNECTION,
            Self::Interrupted { .. } => exit::INTERRUPTED,
        }
    }

    /// The error number of an `ERR` answer.
    pub fn device_code(&self) -> Option<u8> {
        match self {
            Self::Device(e) => Some(e.code),
            _ => None,
        }
    }
}

impl fmt::Display for ClientError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Device(e) => write!(
                f,
                "the board refused `{}`: ERR {} {}",
                e.command, e.code, e.text
            ),
            Self::Timeout { command, after } => {
                write!(f, "no answer to `{command}` within {after:?}")
            }
            Self::Corrupt {
                command,
                line,
                reason,
            } => write!(f, "corrupted answer to `{command}` ({reason}): {line:?}"),
            Self::Link(e) => write!(f, "link: {e}"),
            Self::BadCommand(why) => write!(f, "cannot send: {why}"),
            Self::Interrupted { what } => write!(f, "interrupted: {what}"),
            Self::Unexpected {
                command,
                answer,
                what,
            } => write!(f, "unexpected answer to `{command}` ({what}): {answer}"),
        }
    }
}

impl std::error::Error for ClientError {}

/// A client error ends the command with its own exit status ([`ClientError::exit_code`]) and
/// its text; the error stays whole for the CLI (`--json` prints a board's refusal on stdout).
impl From<ClientError> for host_cli::Failure {
    fn from(error: ClientError) -> Self {
        Self::Error {
            status: error.exit_code(),
            error: Box::new(error),
        }
    }
}

impl From<io::Error> for ClientError {
    fn from(e: io::Error) -> Self {
        Self::Link(e)
    }
}

/// What a checked answer line says.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Reply {
    /// `OK [fields][~]`.
    Ok {
        /// The fields after `OK`, without the `~` mark.
        text: String,
        /// The answer ended in `~`: the board cut it to fit its buffer.
        truncated: bool,
    },
    /// `ERR <code> <text>`.
    Err {
        /// The error number.
        code: u8,
        /// Everything after the code.
        text: String,
    },
}

/// Checks one answer line (with its `\r\n`): printable, a valid CRC suffix, `OK` or
/// `ERR <code> <text>`. The error says what is wrong with it. The only answers accepted without
/// a CRC are `ERR 6`, `ERR 7` and `ERR 8`: the board could not read the request (bad checksum,
/// overlong, non-printable: line noise on a checksummed request) and so answers it plain.
pub fn check_answer(line: &[u8]) -> Result<Reply, &'static str> {
    let line = line.strip_suffix(b"\r\n").ok_or("no CRLF")?;
    if !line.iter().all(|b| (0x20..0x7f).contains(b)) {
        return Err("non-printable bytes");
    }
    // Printable ASCII is UTF-8.
    let line = std::str::from_utf8(line).map_err(|_| "not text")?;
    let Some((body, crc)) = line.rsplit_once('*') else {
        return match parse_body(line) {
            // The board could not read the request: it answers without a CRC.
            Ok(reply @ Reply::Err { code: 6..=8, .. }) => Ok(reply),
            _ => Err("no CRC suffix"),
        };
    };
    if crc.len() != 4 || !crc.bytes().all(|b| b.is_ascii_hexdigit()) {
        return Err("malformed CRC suffix");
    }
    if u16::from_str_radix(crc, 16) != Ok(crc16(body.as_bytes())) {
        return Err("CRC mismatch");
    }
    parse_body(body)
}

/// `OK [fields][~]` or `ERR <code> <text>`.
fn parse_body(body: &str) -> Result<Reply, &'static str> {
    let (body, truncated) = match body.strip_suffix('~') {
        Some(b) => (b, true),
        None => (body, false),
    };
    if body == "OK" || body.starts_with("OK ") {
        let text = body[2..].trim_start().to_owned();
        return Ok(Reply::Ok { text, truncated });
    }
    let rest = body.strip_prefix("ERR ").ok_or("neither OK nor ERR")?;
    let (number, text) = rest.split_once(' ').unwrap_or((rest, ""));
    let code = number.parse().map_err(|_| "ERR without a code")?;
    Ok(Reply::Err {
        code,
        text: text.to_owned(),
    })
}

/// A command as answers and errors show it: the key of `unlock` and `key provision` replaced
/// by `<key>` (the rest of such a line is the key).
pub fn shown_command(text: &str) -> String {
    let mut words = text.split_whitespace();
    let is = |word: Option<&str>, name: &str| word.is_some_and(|w| w.eq_ignore_ascii_case(name));
    let first = words.next();
    if is(first, "unlock") {
        "unlock <key>".to_owned()
    } else if is(first, "key") {
        "key provision <key>".to_owned()
    } else {
        text.to_owned()
    }
}

/// `<text>*XXXX\n`, or why the text cannot be a command.
pub fn frame_command(text: &str) -> Result<Vec<u8>, ClientError> {
    let shown = shown_command(text);
    let bad = |why: &str| Err(ClientError::BadCommand(format!("{why}: {shown:?}")));
    if !text
        .bytes()
        .all(|b| b == b'\t' || (0x20..0x7f).contains(&b))
    {
        return bad("only printable ASCII can be sent");
    }
    if text.contains('*') {
        return bad("`*` starts the CRC suffix");
    }
    if text.len() + 5 > MAX_LINE {
        return bad("longer than the board's line buffer");
    }
    Ok(format!("{text}*{:04X}\n", crc16(text.as_bytes())).into_bytes())
}

/// The client over a link.
pub struct Client<L> {
    link: L,
    timeout: Duration,
    inbox: Vec<u8>,
    streaming: bool,
    frames: Vec<Vec<u8>>,
    skipped_bytes: usize,
    /// The last command timed out: its answer may still come.
    answer_overdue: bool,
}

/// How long to wait for the answer to `command`: the client's `timeout`, or longer for a
/// command whose execution takes longer on the board. `store` (and `key provision`, which
/// programs OTP through the same flash controller) may stall the board for a sector erase
/// plus the programming, `firmware::storage::STORE_STALL_MAX_MS` (2.002 s on the F405), during
/// which it cannot answer: those wait that long plus the client's timeout. The other commands
/// answer within microseconds to milliseconds on the board.
pub fn answer_timeout(command: &str, timeout: Duration) -> Duration {
    let word = |w: &str| {
        command
            .split_whitespace()
            .next()
            .is_some_and(|first| first.eq_ignore_ascii_case(w))
    };
    if word("store") || word("key") {
        timeout + Duration::from_millis(firmware::storage::STORE_STALL_MAX_MS as u64)
    } else {
        timeout
    }
}

/// Default answer timeout.
pub const DEFAULT_TIMEOUT: Duration = Duration::from_secs(2);

impl<L: Link> Client<L> {
    /// A client in text mode over `link`, answer timeout [`DEFAULT_TIMEOUT`].
    pub fn new(link: L) -> Self {
        Self {
            link,
            timeout: DEFAULT_TIMEOUT,
            inbox: Vec::new(),
            streaming: false,
            frames: Vec::new(),
            skipped_bytes: 0,
            answer_overdue: false,
        }
    }

    /// The same client with another answer timeout (measured on the link's clock).
    pub fn with_timeout(mut self, timeout: Duration) -> Self {
        self.timeout = timeout;
        self
    }

    /// The answer timeout.
    pub fn timeout(&self) -> Duration {
        self.timeout
    }

    /// Changes the answer timeout.
    pub fn set_timeout(&mut self, timeout: Duration) {
        self.timeout = timeout;
    }

    /// The link underneath.
    pub fn link(&self) -> &L {
        &self.link
    }

    /// The link underneath, e.g. to reach the simulated board behind a `SimLink`.
    pub fn link_mut(&mut self) -> &mut L {
        &mut self.link
    }

    /// Ends the client and hands back its link (unread bytes are dropped).
    pub fn into_link(self) -> L {
        self.link
    }

    /// Whether the board is streaming frames (as far as its answers told).
    pub fn streaming(&self) -> bool {
        self.streaming
    }

    /// Bytes received and not yet consumed (in text mode, after an answer: bytes the board
    /// sent beyond its one answer).
    pub fn pending(&self) -> usize {
        self.inbox.len()
    }

    /// Bytes received that were neither answers nor frames: stream leftovers, `#` notices,
    /// stale or late answers.
    pub fn skipped_bytes(&self) -> usize {
        self.skipped_bytes
    }

    /// Sends one command and waits for its one answer.
    pub fn command(&mut self, text: &str) -> Result<Answer, ClientError> {
        let wire = frame_command(text)?;
        let shown = shown_command(text);
        self.drop_stale_input()?;
        self.link.send(&wire)?;
        let line = self.read_answer_line(&shown)?;
        let reply = check_answer(&line).map_err(|reason| ClientError::Corrupt {
            command: shown.clone(),
            line: String::from_utf8_lossy(&line).into_owned(),
            reason,
        })?;
        match reply {
            Reply::Ok {
                text: fields,
                truncated,
            } => {
                if fields.starts_with("stream=on") || fields.starts_with("stream=output") {
                    self.streaming = true;
                } else if fields.starts_with("stream=off") {
                    self.streaming = false;
                }
                Ok(Answer {
                    command: shown,
                    text: fields,
                    truncated,
                })
            }
            Reply::Err { code, text: detail } => Err(ClientError::Device(DeviceError {
                command: shown,
                code,
                kind: error_code(code),
                text: detail,
            })),
        }
    }

    /// Receives for at most `wait` and sorts what arrived (stream mode: into frames).
    pub fn poll(&mut self, wait: Duration) -> Result<(), ClientError> {
        self.link.receive(&mut self.inbox, wait)?;
        if self.streaming {
            // Answers are not expected here; frames are collected.
            while let Some(chunk) = self.next_chunk() {
                self.frames.push(chunk);
            }
        }
        Ok(())
    }

    /// The 0x00-delimited chunks received while streaming (candidate frames), in order.
    pub fn take_frames(&mut self) -> Vec<Vec<u8>> {
        std::mem::take(&mut self.frames)
    }

    /// Lets time pass on the link's clock (stream mode: collecting frames meanwhile).
    pub fn pause(&mut self, duration: Duration) -> Result<(), ClientError> {
        self.link.pause(duration);
        if self.streaming {
            self.poll(Duration::ZERO)?;
        }
        Ok(())
    }

    /// Time on the link's clock.
    pub fn elapsed(&self) -> Duration {
        self.link.elapsed()
    }

    /// The answer line to `command` (as shown; its first word sets the timeout).
    fn read_answer_line(&mut self, command: &str) -> Result<Vec<u8>, ClientError> {
        let timeout = answer_timeout(command, self.timeout);
        let deadline = self.link.elapsed() + timeout;
        loop {
            let found = if self.streaming {
                self.next_wrapped_answer()
            } else {
                self.next_text_answer()
            };
            if let Some(line) = found {
                return Ok(line);
            }
            let now = self.link.elapsed();
            if now >= deadline {
                self.answer_overdue = true;
                return Err(ClientError::Timeout {
                    command: command.to_owned(),
                    after: timeout,
                });
            }
            self.link.receive(&mut self.inbox, deadline - now)?;
        }
    }

    /// Whatever arrived unasked before a command is not its answer: text mode drops it all,
    /// stream mode drops the answers and keeps the frames (an unfinished chunk waits for its
    /// delimiter). After a timeout, the late answer is awaited (one more timeout at most) and
    /// dropped too.
    fn drop_stale_input(&mut self) -> Result<(), ClientError> {
        if std::mem::take(&mut self.answer_overdue) {
            let end = self.link.elapsed() + self.timeout;
            loop {
                if self.drop_answers() {
                    break;
                }
                let now = self.link.elapsed();
                if now >= end {
                    break;
                }
                self.link.receive(&mut self.inbox, end - now)?;
            }
        }
        self.link.receive(&mut self.inbox, Duration::ZERO)?;
        self.drop_answers();
        Ok(())
    }

    /// Drops the answers received so far (text mode: all complete lines and the bytes after
    /// them; stream mode: the wrapped answers, the frames kept); returns whether one was
    /// dropped.
    fn drop_answers(&mut self) -> bool {
        if !self.streaming {
            let answered = self.inbox.windows(2).any(|w| w == b"\r\n");
            self.skipped_bytes += self.inbox.len();
            self.inbox.clear();
            return answered;
        }
        let mut dropped = false;
        while let Some(chunk) = self.next_chunk() {
            if starts_like_answer(&chunk) {
                self.skipped_bytes += chunk.len();
                dropped = true;
            } else {
                self.frames.push(chunk);
            }
        }
        dropped
    }

    /// Text mode: the next line that can be an answer (stream leftovers and `#` notices
    /// skipped).
    fn next_text_answer(&mut self) -> Option<Vec<u8>> {
        while let Some(end) = self.inbox.windows(2).position(|w| w == b"\r\n") {
            let mut line: Vec<u8> = self.inbox.drain(..end + 2).collect();
            if let Some(zero) = line.iter().rposition(|&b| b == 0) {
                self.skipped_bytes += zero + 1;
                line.drain(..=zero);
                // A wrapped answer (the one that starts a stream): its closing delimiter too.
                if self.inbox.first() == Some(&0) {
                    self.inbox.remove(0);
                }
            }
            let printable = is_printable_line(&line);
            if (printable && !line.starts_with(b"#")) || starts_like_answer(&line) {
                return Some(line);
            }
            self.skipped_bytes += line.len();
        }
        None
    }

    /// Stream mode: the next 0x00-delimited answer; frames before it are kept. An unwrapped
    /// answer at the start of the undelimited rest is taken too (the board reset meanwhile and
    /// is in text mode again: a frame never starts with `O` or `E`), after a `# ` notice line
    /// (the board's start-up banner).
    fn next_wrapped_answer(&mut self) -> Option<Vec<u8>> {
        while let Some(chunk) = self.next_chunk() {
            if starts_like_answer(&chunk) && chunk.ends_with(b"\r\n") {
                return Some(chunk);
            }
            self.frames.push(chunk);
        }
        loop {
            let end = self.inbox.windows(2).position(|w| w == b"\r\n")?;
            let line = &self.inbox[..end + 2];
            if !is_printable_line(line) {
                return None;
            }
            if starts_like_answer(line) {
                return Some(self.inbox.drain(..end + 2).collect());
            }
            if !line.starts_with(b"# ") {
                return None;
            }
            self.skipped_bytes += end + 2;
            self.inbox.drain(..end + 2);
        }
    }

    /// The next complete non-empty 0x00-delimited chunk.
    fn next_chunk(&mut self) -> Option<Vec<u8>> {
        while let Some(zero) = self.inbox.iter().position(|&b| b == 0) {
            let mut chunk: Vec<u8> = self.inbox.drain(..=zero).collect();
            chunk.pop();
            if !chunk.is_empty() {
                return Some(chunk);
            }
        }
        None
    }
}

/// A line (with its `\r\n`) of printable ASCII.
fn is_printable_line(line: &[u8]) -> bool {
    line[..line.len() - 2]
        .iter()
        .all(|b| (0x20..0x7f).contains(b))
}

fn starts_like_answer(bytes: &[u8]) -> bool {
    bytes.starts_with(b"OK") || bytes.starts_with(b"ERR")
}
