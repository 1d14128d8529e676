//! The `host` target: arbitrary bytes to what `rlg-cal` makes of a board's output: the answer
//! checker, the answer-to-fields rule and its JSON, the client reading one answer from a link
//! that sends the bytes, the stream capture with its CSV rows and per-second means, and the
//! output recording's rows.
//!
//! Checked, besides no panic:
//! - an answer the checker accepts is printable, and its fields render as one JSON object;
//! - the client returns exactly one result for a command and never takes more than the
//!   bytes sent;
//! - the cycle-stream capture counts every chunk as a record or a bad frame, and writes one CSV
//!   row per record;
//! - the output recording writes at most one row per record received plus the lost records its
//!   clocks allow: never more than `MAX_OUTPUT_RATE_HZ` rows per second of the host's clock
//!   (plus 1 % and 1 s), however the records' sequence numbers and times jump.
//!
//! The first byte picks the part; the rest is its input. For the output recording the input is
//! read as records: 38 bytes of payload (as on the wire, without COBS and CRC, so that every
//! field value reaches the writer) and 2 bytes of milliseconds the host's clock advances.

use std::io::{self, Write};
use std::time::Duration;

use firmware::protocol::output_frame::MAX_OUTPUT_RATE_HZ;
use firmware::signal::output::record::{OutputRecord, OutputStatus};
use rlg_cal::capture::{Capture, CsvRows, RateScale};
use rlg_cal::client::{check_answer, Client, Reply};
use rlg_cal::link::Link;
use rlg_cal::output::{fields, Format};
use rlg_cal::output_capture::OutputRows;

const SCALE: RateScale = RateScale {
    scale_factor_arcsec: 1.8655,
    timer_hz: 84e6,
};

/// Counts lines written, keeps nothing.
#[derive(Default)]
struct LineCount(usize);

impl Write for LineCount {
    fn write(&mut self, bytes: &[u8]) -> io::Result<usize> {
        self.0 += bytes.iter().filter(|&&b| b == b'\n').count();
        Ok(bytes.len())
    }
    fn flush(&mut self) -> io::Result<()> {
        Ok(())
    }
}

/// A link that answers any command with `reply`, once.
struct Replying {
    reply: Vec<u8>,
    now: Duration,
}

impl Link for Replying {
    fn send(&mut self, _bytes: &[u8]) -> io::Result<()> {
        Ok(())
    }
    fn receive(&mut self, out: &mut Vec<u8>, timeout: Duration) -> io::Result<usize> {
        if self.reply.is_empty() {
            self.now += timeout;
            return Ok(0);
        }
        let n = self.reply.len();
        out.append(&mut self.reply);
        Ok(n)
    }
    fn elapsed(&self) -> Duration {
        self.now
    }
    fn pause(&mut self, duration: Duration) {
        self.now += duration;
    }
}

fn check_answers(data: &[u8]) {
    for line in data.split_inclusive(|&b| b == b'\n') {
        if let Ok(reply) = check_answer(line) {
            assert!(line
                .iter()
                .all(|&b| b == b'\r' || b == b'\n' || (0x20..0x7f).contains(&b)));
            let text = match reply {
                Reply::Ok { text, .. } | Reply::Err { text, .. } => text,
            };
            let pairs = fields(&text);
            let json = Format::Json.render(&pairs, &[("s", pairs.clone())]);
            assert!(json.starts_with('{') && json.ends_with('}') && !json.contains('\n'));
            let _ = Format::KeyValue.render(&pairs, &[]);
        }
    }
    let mut client = Client::new(Replying {
        reply: data.to_vec(),
        now: Duration::ZERO,
    })
    .with_timeout(Duration::from_millis(100));
    let _ = client.command("status");
    assert!(client.pending() + client.skipped_bytes() <= data.len());
    let _ = client.command("stream on 1");
    let _ = client.command("get a");
}

fn check_capture(data: &[u8]) {
    let mut capture = Capture::new(1);
    let mut rows = CsvRows::new(LineCount::default(), 1, SCALE).expect("in memory");
    let mut chunks = 0;
    for chunk in data.split(|&b| b == 0).filter(|c| !c.is_empty()) {
        chunks += 1;
        if let Some(record) = capture.push_chunk(chunk) {
            let record = *record;
            rows.push(&record).expect("in memory");
        }
    }
    assert_eq!(capture.records.len() as u64 + capture.bad_frames, chunks);
    assert_eq!(rows.rows(), capture.records.len() as u64);
    let _ = capture.per_second(&SCALE);
    let _ = capture.mean_rates(&SCALE);
}

fn record_from(bytes: &[u8; 38]) -> OutputRecord {
    let u64_at = |i: usize| u64::from_le_bytes(bytes[i..i + 8].try_into().expect("8 bytes"));
    let u32_at = |i: usize| u32::from_le_bytes(bytes[i..i + 4].try_into().expect("4 bytes"));
    OutputRecord {
        sequence: u64_at(0),
        time_ticks: u64_at(8),
        period_ticks: u32_at(16),
        delta_angle_q16: u32_at(20) as i32,
        angle_q16: u64_at(24) as i64,
        rate_deg_per_h: f32::from_bits(u32_at(32)),
        status: OutputStatus(u16::from_le_bytes([bytes[36], bytes[37]])),
        temperature_q7: firmware::thermal::state::NO_VALUE,
        temperature_rate_centi_c_per_min: firmware::thermal::state::NO_VALUE,
    }
}

fn check_recording(data: &[u8]) {
    let mut out = LineCount::default();
    let mut rows = OutputRows::new(&mut out, SCALE).expect("in memory");
    let mut received = Duration::ZERO;
    let mut first = None;
    let mut records = 0usize;
    for chunk in data.chunks_exact(40) {
        let payload: &[u8; 38] = chunk[..38].try_into().expect("38 bytes");
        received += Duration::from_millis(u16::from_le_bytes([chunk[38], chunk[39]]).into());
        first.get_or_insert(received);
        rows.push(&record_from(payload), received)
            .expect("in memory");
        records += 1;
    }
    let gaps = rows.finish().expect("in memory");
    let host_s = first.map_or(0.0, |f| (received - f).as_secs_f64());
    let lost_allowed = (host_s * 1.01 + 1.0) * MAX_OUTPUT_RATE_HZ + records as f64;
    assert!(gaps.lost as f64 <= lost_allowed, "{gaps:?} over {host_s} s");
    assert_eq!(
        out.0 as u64,
        1 + records as u64 + gaps.lost,
        "header, records, lost rows"
    );
}

/// Runs the host's decoders and writers over `data` (panics on a broken promise).
pub fn check(data: &[u8]) {
    let Some((&part, rest)) = data.split_first() else {
        return;
    };
    match part % 3 {
        0 => check_answers(rest),
        1 => check_capture(rest),
        _ => check_recording(rest),
    }
}
