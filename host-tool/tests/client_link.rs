//! The client's defences: corrupted answers are detected (CRC), silent links time out, stream
//! leftovers are skipped, commands that cannot be sent are refused before sending.

use firmware::protocol::parse::crc16;
use hal_sim::flash::CalibrationFlash;
use rlg_cal::client::{check_answer, frame_command, Client, ClientError, Reply};
use rlg_cal::link::{self, Link, SimLink};
use rlg_cal::sim::{self, SimInput};
use std::collections::VecDeque;
use std::io;
use std::net::TcpListener;
use std::time::{Duration, Instant};

/// A link with a fake clock: each sent line gets the bytes `reply` makes of it; waiting for
/// more advances the clock by the whole timeout at once.
struct Scripted<F> {
    reply: F,
    inbox: VecDeque<u8>,
    now: Duration,
}

impl<F: FnMut(&[u8]) -> Vec<u8>> Scripted<F> {
    fn new(reply: F) -> Self {
        Self {
            reply,
            inbox: VecDeque::new(),
            now: Duration::ZERO,
        }
    }
}

impl<F: FnMut(&[u8]) -> Vec<u8>> Link for Scripted<F> {
    fn send(&mut self, bytes: &[u8]) -> io::Result<()> {
        let out = (self.reply)(bytes);
        self.inbox.extend(out);
        Ok(())
    }
    fn receive(&mut self, out: &mut Vec<u8>, timeout: Duration) -> io::Result<usize> {
        if self.inbox.is_empty() {
            self.now += timeout;
            return Ok(0);
        }
        let n = self.inbox.len();
        out.extend(self.inbox.drain(..));
        Ok(n)
    }
    fn elapsed(&self) -> Duration {
        self.now
    }
    fn pause(&mut self, duration: Duration) {
        self.now += duration;
    }
}

fn with_crc(body: &str) -> Vec<u8> {
    format!("{body}*{:04X}\r\n", crc16(body.as_bytes())).into_bytes()
}

/// A real answer of the simulated board to `line`.
fn board_answer(line: &str) -> Vec<u8> {
    let device = sim::boot(
        SimInput::Constant {
            rate_deg_per_h: 5.0,
        },
        3,
        CalibrationFlash::default(),
        0,
        Some(sim::test_key()),
    )
    .unwrap();
    let mut link = SimLink::new(device);
    link.send(&frame_command(line).unwrap()).unwrap();
    let mut out = Vec::new();
    link.receive(&mut out, Duration::ZERO).unwrap();
    out
}

#[test]
fn the_checked_answer_passes() {
    let answer = board_answer("get coeffs");
    let mut c = Client::new(Scripted::new(|_: &[u8]| answer.clone()));
    let a = c.command("get coeffs").unwrap();
    assert!(a.text.starts_with("a=0 b=0"), "{}", a.text);
}

/// Every single flipped bit of a real answer is caught: a corrupted answer, or (the line end
/// destroyed) a timeout; never an `OK` with wrong contents (a hex digit of the CRC changing
/// case changes nothing: the suffix is read case-insensitively, as the board reads it).
#[test]
fn every_corrupted_byte_of_an_answer_is_detected() {
    let answer = board_answer("get coeffs");
    let good = Client::new(Scripted::new(|_: &[u8]| answer.clone()))
        .command("get coeffs")
        .unwrap();
    for i in 0..answer.len() {
        for flip in [0x01u8, 0x20, 0x80] {
            let mut bad = answer.clone();
            bad[i] ^= flip;
            let mut c = Client::new(Scripted::new(move |_: &[u8]| bad.clone()))
                .with_timeout(Duration::from_millis(100));
            match c.command("get coeffs") {
                Err(e @ (ClientError::Corrupt { .. } | ClientError::Timeout { .. })) => {
                    assert_eq!(e.exit_code(), 3);
                }
                Ok(a) if a == good => {}
                other => panic!("byte {i} ^ {flip:#x}: {other:?}"),
            }
        }
    }
}

#[test]
fn a_corrupted_answer_names_the_reason() {
    let mut answer = with_crc("OK a=344.25");
    answer[5] = b'9';
    let mut c = Client::new(Scripted::new(move |_: &[u8]| answer.clone()));
    match c.command("get a") {
        Err(ClientError::Corrupt { reason, line, .. }) => {
            assert_eq!(reason, "CRC mismatch");
            assert!(line.starts_with("OK a=944.25"), "{line}");
        }
        other => panic!("{other:?}"),
    }
    // An answer without a suffix (a board that ignored ours) is refused too.
    let mut c = Client::new(Scripted::new(|_: &[u8]| b"OK a=0\r\n".to_vec()));
    assert!(matches!(
        c.command("get a"),
        Err(ClientError::Corrupt {
            reason: "no CRC suffix",
            ..
        })
    ));
}

/// A garbled request is answered plain (`ERR 6/7/8`): a device error, and a link problem.
#[test]
fn a_garbled_request_is_a_link_error() {
    let mut c = Client::new(Scripted::new(|_: &[u8]| b"ERR 6 bad checksum\r\n".to_vec()));
    let e = c.command("status").unwrap_err();
    assert_eq!((e.device_code(), e.exit_code()), (Some(6), 3), "{e}");
    let mut c = Client::new(Scripted::new(|_: &[u8]| {
        with_crc("ERR 9 locked (unlock first)")
    }));
    let e = c.command("store").unwrap_err();
    assert_eq!((e.device_code(), e.exit_code()), (Some(9), 1), "{e}");
}

#[test]
fn a_silent_link_times_out() {
    let mut c =
        Client::new(Scripted::new(|_: &[u8]| Vec::new())).with_timeout(Duration::from_millis(1500));
    match c.command("id") {
        Err(e @ ClientError::Timeout { .. }) => {
            assert_eq!(e.exit_code(), 3);
            assert!(e.to_string().contains("no answer to `id`"), "{e}");
        }
        other => panic!("{other:?}"),
    }
    assert_eq!(c.link().elapsed(), Duration::from_millis(1500));
    // Half an answer is no answer either.
    let mut c = Client::new(Scripted::new(|_: &[u8]| b"OK a=0*".to_vec()));
    assert!(matches!(
        c.command("get a"),
        Err(ClientError::Timeout { .. })
    ));
}

/// A real socket on loopback whose peer accepts and never answers.
#[test]
fn a_silent_tcp_peer_times_out_in_time() {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let address = listener.local_addr().unwrap().to_string();
    let peer = std::thread::spawn(move || {
        let (mut stream, _) = listener.accept().unwrap();
        stream
            .set_read_timeout(Some(Duration::from_secs(3)))
            .unwrap();
        let mut sink = Vec::new();
        let _ = io::Read::read_to_end(&mut stream, &mut sink);
        sink
    });
    let link = link::tcp(&address, Duration::from_secs(1)).unwrap();
    let mut c = Client::new(link).with_timeout(Duration::from_millis(300));
    let start = Instant::now();
    assert!(matches!(c.command("id"), Err(ClientError::Timeout { .. })));
    let waited = start.elapsed();
    assert!(
        waited >= Duration::from_millis(300) && waited < Duration::from_secs(2),
        "{waited:?}"
    );
    drop(c);
    let received = peer.join().unwrap();
    assert_eq!(
        received,
        frame_command("id").unwrap(),
        "the command with its CRC"
    );
}

#[test]
fn a_closed_connection_is_a_link_error() {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let address = listener.local_addr().unwrap().to_string();
    let peer = std::thread::spawn(move || drop(listener.accept().unwrap()));
    let link = link::tcp(&address, Duration::from_secs(1)).unwrap();
    peer.join().unwrap();
    let mut c = Client::new(link).with_timeout(Duration::from_secs(2));
    let e = c.command("id").unwrap_err();
    assert!(matches!(e, ClientError::Link(_)), "{e}");
    assert_eq!(e.exit_code(), 3);
}

/// Leftovers of an earlier stream (binary, 0x00-delimited, even with CR LF inside) before the
/// answer are skipped.
#[test]
fn stream_leftovers_before_an_answer_are_skipped() {
    let mut junk = vec![
        0x2Du8, 0x81, b'\r', b'\n', 0x07, 0x00, 0x13, 0xF0, b'\r', b'\n',
    ];
    junk.extend_from_slice(&[0x05, 0x00]);
    junk.extend_from_slice(&with_crc("OK a=1.5"));
    let mut c = Client::new(Scripted::new(move |_: &[u8]| junk.clone()));
    assert_eq!(c.command("get a").unwrap().text, "a=1.5");
    assert!(c.skipped_bytes() > 0);
}

#[test]
fn commands_that_cannot_be_sent_are_refused_before_sending() {
    assert_eq!(
        frame_command("get a").unwrap(),
        format!("get a*{:04X}\n", crc16(b"get a")).into_bytes()
    );
    for bad in ["get a*1234", "get\na", "set a \u{e9}", &"x".repeat(92)] {
        let e = frame_command(bad).unwrap_err();
        assert!(matches!(e, ClientError::BadCommand(_)), "{bad:?}");
        assert_eq!(e.exit_code(), 1);
    }
}

#[test]
fn answer_forms() {
    assert_eq!(
        check_answer(&with_crc("OK")),
        Ok(Reply::Ok {
            text: String::new(),
            truncated: false
        })
    );
    assert_eq!(
        check_answer(&with_crc("OK a=1 b=2~")),
        Ok(Reply::Ok {
            text: "a=1 b=2".into(),
            truncated: true
        })
    );
    assert_eq!(
        check_answer(&with_crc("ERR 14 too many attempts, wait wait_ms=900")),
        Ok(Reply::Err {
            code: 14,
            text: "too many attempts, wait wait_ms=900".into()
        })
    );
    assert_eq!(check_answer(&with_crc("HELLO")), Err("neither OK nor ERR"));
    assert_eq!(check_answer(b"OK*12\r\n"), Err("malformed CRC suffix"));
    assert_eq!(check_answer(b"OK*FFFF"), Err("no CRLF"));
    assert_eq!(
        check_answer(b"OK \x01*FFFF\r\n"),
        Err("non-printable bytes")
    );
}

/// The board's start-up banner (a `#` notice) is not an answer.
#[test]
fn a_reset_banner_before_an_answer_is_skipped() {
    let mut reply = b"# rlg-readout ready\r\n".to_vec();
    reply.extend_from_slice(&with_crc("OK a=0"));
    let mut c = Client::new(Scripted::new(move |_: &[u8]| reply.clone()));
    assert_eq!(c.command("get a").unwrap().text, "a=0");
    assert_eq!(c.skipped_bytes(), 21);
}

/// The board resets while streaming: its banner and plain (unwrapped) answers follow the last
/// frames, and the client still gets its answer and leaves stream mode.
#[test]
fn a_reset_while_streaming_is_survived() {
    use firmware::protocol::stream::{encode_frame, StreamRecord, MAX_FRAME};
    let mut buf = [0u8; MAX_FRAME];
    let record = StreamRecord {
        sequence: 1,
        end_phase_q32: 0,
        raw_increment_q32: 0x4F4B,
        compensated_increment_q32: 0x0D0A,
        p1_s: 0.0,
        p2_s: 0.0,
        duration_ticks: 215_938,
        flags: 0,
    };
    let n = encode_frame(&record, &mut buf);
    let frame = buf[..n].to_vec();
    let mut c = Client::new(Scripted::new(move |sent: &[u8]| {
        if sent.starts_with(b"stream on") {
            let mut r = with_crc("OK stream=on divider=1 frame_bytes=47");
            r.extend_from_slice(&frame);
            r
        } else {
            let mut r = frame.clone();
            r.extend_from_slice(b"# rlg-readout ready\r\n");
            r.extend_from_slice(&with_crc("OK stream=off"));
            r
        }
    }));
    c.command("stream on 1").unwrap();
    assert!(c.streaming());
    assert_eq!(c.command("stream off").unwrap().text, "stream=off");
    assert!(!c.streaming());
    assert_eq!(c.take_frames().len(), 2);
}

/// A board that answers the first command too late, the others at once.
struct LateFirst {
    sent: usize,
    queue: Vec<(Duration, Vec<u8>)>,
    now: Duration,
}

impl Link for LateFirst {
    fn send(&mut self, bytes: &[u8]) -> io::Result<()> {
        self.sent += 1;
        let delay = if self.sent == 1 { 1500 } else { 0 };
        let answer = if bytes.starts_with(b"get a") {
            with_crc("OK a=1")
        } else {
            with_crc("OK b=2")
        };
        self.queue
            .push((self.now + Duration::from_millis(delay), answer));
        Ok(())
    }
    fn receive(&mut self, out: &mut Vec<u8>, timeout: Duration) -> io::Result<usize> {
        let due = self
            .queue
            .iter()
            .position(|(t, _)| *t <= self.now + timeout);
        match due {
            Some(i) => {
                let (t, bytes) = self.queue.remove(i);
                self.now = self.now.max(t);
                out.extend_from_slice(&bytes);
                Ok(bytes.len())
            }
            None => {
                self.now += timeout;
                Ok(0)
            }
        }
    }
    fn elapsed(&self) -> Duration {
        self.now
    }
    fn pause(&mut self, d: Duration) {
        self.now += d;
    }
}

/// An answer that comes after its command timed out does not pass for the next one's.
#[test]
fn a_late_answer_is_not_taken_for_the_next_one() {
    let link = LateFirst {
        sent: 0,
        queue: Vec::new(),
        now: Duration::ZERO,
    };
    let mut c = Client::new(link).with_timeout(Duration::from_secs(1));
    assert!(matches!(
        c.command("get a"),
        Err(ClientError::Timeout { .. })
    ));
    assert_eq!(c.command("get b").unwrap().text, "b=2");
    assert_eq!(c.skipped_bytes(), with_crc("OK a=1").len());
}

/// A board whose answers come after a delay each: `reply` gives the delay and the bytes for
/// each line sent.
struct Delayed<F> {
    reply: F,
    queue: Vec<(Duration, Vec<u8>)>,
    now: Duration,
}

impl<F: FnMut(&[u8]) -> (u64, Vec<u8>)> Link for Delayed<F> {
    fn send(&mut self, bytes: &[u8]) -> io::Result<()> {
        let (delay_ms, answer) = (self.reply)(bytes);
        self.queue
            .push((self.now + Duration::from_millis(delay_ms), answer));
        Ok(())
    }
    fn receive(&mut self, out: &mut Vec<u8>, timeout: Duration) -> io::Result<usize> {
        let due = self
            .queue
            .iter()
            .position(|(t, _)| *t <= self.now + timeout);
        match due {
            Some(i) => {
                let (t, bytes) = self.queue.remove(i);
                self.now = self.now.max(t);
                out.extend_from_slice(&bytes);
                Ok(bytes.len())
            }
            None => {
                self.now += timeout;
                Ok(0)
            }
        }
    }
    fn elapsed(&self) -> Duration {
        self.now
    }
    fn pause(&mut self, d: Duration) {
        self.now += d;
    }
}

/// While streaming too, an answer that comes after its command timed out does not pass for
/// the next command's; the frames around it are kept.
#[test]
fn a_late_answer_while_streaming_is_not_taken_for_the_next_one() {
    use firmware::protocol::stream::{encode_frame, StreamRecord, MAX_FRAME};
    let mut buf = [0u8; MAX_FRAME];
    let record = StreamRecord {
        sequence: 1,
        end_phase_q32: 0,
        raw_increment_q32: 7,
        compensated_increment_q32: 7,
        p1_s: 0.0,
        p2_s: 0.0,
        duration_ticks: 215_938,
        flags: 0,
    };
    let n = encode_frame(&record, &mut buf);
    let frame = buf[..n].to_vec();
    let wrapped = |body: &str| {
        let mut r = frame.clone();
        r.push(0);
        r.extend_from_slice(&with_crc(body));
        r.push(0);
        r.extend_from_slice(&frame);
        r
    };
    let link = Delayed {
        reply: move |sent: &[u8]| {
            if sent.starts_with(b"stream on") {
                (0, with_crc("OK stream=on divider=1 frame_bytes=47"))
            } else if sent.starts_with(b"cal status") {
                (1500, wrapped("OK cal=idle"))
            } else {
                (0, wrapped("OK fw=1"))
            }
        },
        queue: Vec::new(),
        now: Duration::ZERO,
    };
    let mut c = Client::new(link).with_timeout(Duration::from_secs(1));
    c.command("stream on 1").unwrap();
    assert!(matches!(
        c.command("cal status"),
        Err(ClientError::Timeout { .. })
    ));
    assert_eq!(c.command("id").unwrap().text, "fw=1");
    c.poll(Duration::ZERO).unwrap();
    assert_eq!(c.take_frames().len(), 4, "the frames around both answers");
}

/// The key never appears in what the client reports: not in a refusal (wrong key, penalty,
/// no key), a timeout, a corrupted answer, a command it cannot send, nor in an answer's
/// `command` (which `--json` prints).
#[test]
fn the_key_is_in_no_error_or_answer() {
    const KEY: &str = "0123456789abcdef0123456789abcdef";
    let replies = [
        with_crc("ERR 15 wrong key"),
        with_crc("ERR 14 too many attempts, wait wait_ms=1000"),
        with_crc("ERR 16 no key provisioned"),
        Vec::new(),
        b"OK unlocked for_s=300*0000\r\n".to_vec(),
        with_crc("OK unlocked for_s=300"),
    ];
    for (i, reply) in replies.into_iter().enumerate() {
        for line in [format!("unlock {KEY}"), format!("key provision {KEY}")] {
            let reply = reply.clone();
            let mut c = Client::new(Scripted::new(move |_: &[u8]| reply.clone()))
                .with_timeout(Duration::from_millis(10));
            let shown = match c.command(&line) {
                Ok(answer) => answer.command,
                Err(e) => format!("{e} {e:?}"),
            };
            assert!(!shown.contains(KEY), "case {i}: {shown}");
            assert!(shown.contains("<key>"), "case {i}: {shown}");
        }
    }
    let e = frame_command(&format!("unlock {KEY}*")).unwrap_err();
    assert!(!format!("{e} {e:?}").contains(KEY), "{e}");
}
