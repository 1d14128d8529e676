//! Stream decoding: frames out of a session through the client, lost frames (sequence gaps)
//! and corrupted frames counted, times and rates, CSV and SVG.

use firmware::protocol::parse::crc16;
use firmware::protocol::stream::{decode_frame, encode_frame, StreamRecord, MAX_FRAME};
use hal_sim::flash::CalibrationFlash;
use rlg_cal::capture::{Capture, RateScale, DEFAULT_TIMER_HZ};
use rlg_cal::client::Client;
use rlg_cal::link::{Link, SimLink};
use rlg_cal::ops;
use rlg_cal::sim::{self, SimInput};
use std::collections::VecDeque;
use std::io;
use std::time::Duration;

const SCALE: RateScale = RateScale {
    scale_factor_arcsec: 1.8655,
    timer_hz: DEFAULT_TIMER_HZ,
};
const TICKS: u32 = 215_938;
/// 10 deg/h over one cycle of TICKS: 10 arcsec/s * (TICKS / timer) s / sf arcsec per fringe.
fn increment_q32(rate_deg_per_h: f64) -> i64 {
    (rate_deg_per_h * (TICKS as f64 / DEFAULT_TIMER_HZ) / 1.8655 * firmware::units::Q32_PER_FRINGE)
        .round() as i64
}

fn record(sequence: u32, rate_deg_per_h: f64) -> StreamRecord {
    let inc = increment_q32(rate_deg_per_h);
    StreamRecord {
        sequence,
        end_phase_q32: inc * sequence as i64,
        raw_increment_q32: inc + 1000,
        compensated_increment_q32: inc,
        p1_s: 2.5e-5,
        p2_s: -1.25e-5,
        duration_ticks: TICKS,
        flags: 0,
    }
}

fn frame(r: &StreamRecord) -> Vec<u8> {
    let mut buf = [0u8; MAX_FRAME];
    let n = encode_frame(r, &mut buf);
    buf[..n].to_vec()
}

fn with_crc(body: &str) -> Vec<u8> {
    format!("{body}*{:04X}\r\n", crc16(body.as_bytes())).into_bytes()
}

/// A board that streams a prepared byte string after `stream on`, on a fake clock.
struct Prepared {
    frames: Vec<u8>,
    inbox: VecDeque<u8>,
    now: Duration,
}

impl Link for Prepared {
    fn send(&mut self, bytes: &[u8]) -> io::Result<()> {
        if bytes.starts_with(b"stream on") {
            self.inbox
                .extend(with_crc("OK stream=on divider=1 frame_bytes=47"));
            self.inbox.extend(std::mem::take(&mut self.frames));
        } else if bytes.starts_with(b"stream off") {
            self.inbox.push_back(0);
            self.inbox.extend(with_crc("OK stream=off"));
            self.inbox.push_back(0);
        }
        Ok(())
    }
    fn receive(&mut self, out: &mut Vec<u8>, timeout: Duration) -> io::Result<usize> {
        // A few bytes at a time: frames arrive split across reads.
        let n = self.inbox.len().min(29);
        if n == 0 {
            self.now += timeout;
        }
        out.extend(self.inbox.drain(..n));
        Ok(n)
    }
    fn elapsed(&self) -> Duration {
        self.now
    }
    fn pause(&mut self, d: Duration) {
        self.now += d;
    }
}

/// 200 frames, three dropped on the way (10, 11, 50) and one corrupted (100): 196 decoded, 4
/// lost, 1 bad; the times count the missing frames in.
#[test]
fn injected_lost_and_corrupted_frames_are_counted() {
    let mut bytes = Vec::new();
    for seq in 0..200u32 {
        if [10, 11, 50].contains(&seq) {
            continue;
        }
        let mut f = frame(&record(seq, 10.0));
        if seq == 100 {
            f[20] ^= 0x40;
        }
        bytes.extend(f);
    }
    let link = Prepared {
        frames: bytes,
        inbox: VecDeque::new(),
        now: Duration::ZERO,
    };
    let mut client = Client::new(link);
    let capture = ops::stream(&mut client, 1, Duration::from_secs(1), &mut |_| {}).unwrap();
    assert!(!client.streaming());
    assert_eq!(capture.records.len(), 196);
    assert_eq!((capture.lost(), capture.bad_frames), (4, 1));

    let times = capture.times_s(&SCALE);
    let cycle_s = TICKS as f64 / DEFAULT_TIMER_HZ;
    for (r, t) in capture.records.iter().zip(&times) {
        assert!(
            (t - r.sequence as f64 * cycle_s).abs() < 1e-9,
            "seq {}",
            r.sequence
        );
    }
    let (compensated, raw) = capture.mean_rates(&SCALE);
    assert!((compensated - 10.0).abs() < 1e-6, "{compensated}");
    assert!(raw > compensated);

    let mut csv = Vec::new();
    capture.write_csv(&mut csv, &SCALE).unwrap();
    let csv = String::from_utf8(csv).unwrap();
    let rows: Vec<&str> = csv.lines().collect();
    assert_eq!(rows.len(), 197);
    assert!(rows[0].starts_with("sequence,time_s,end_phase_q32,raw_increment_q32,"));
    let row12: Vec<&str> = rows[11].split(',').collect();
    assert_eq!(row12[0], "12");
    assert_eq!(row12[1], format!("{:.6}", 12.0 * cycle_s));
    assert_eq!(row12[4], increment_q32(10.0).to_string());
    assert_eq!(
        (row12[5], row12[6], row12[7]),
        ("0.000025", "-0.0000125", "215938")
    );
    assert!((row12[9].parse::<f64>().unwrap() - 10.0).abs() < 1e-5);

    let svg = capture.svg(&SCALE, "Test");
    assert!(svg.starts_with("<svg") && svg.contains("196 frames, 4 lost, 1 bad"));
}

#[test]
fn per_second_means_follow_a_rate_step() {
    let mut capture = Capture::new(1);
    let cycles_per_s = (DEFAULT_TIMER_HZ / TICKS as f64).round() as u32; // 389
    for seq in 0..3 * cycles_per_s {
        let rate = if seq < cycles_per_s { 5.0 } else { -20.0 };
        let f = frame(&record(seq, rate));
        capture.push_chunk(&f[..f.len() - 1]);
    }
    let seconds = capture.per_second(&SCALE);
    assert_eq!(seconds.len(), 3, "{seconds:?}");
    assert!(
        (seconds[0].compensated_deg_per_h - 5.0).abs() < 0.1,
        "{seconds:?}"
    );
    assert!((seconds[2].compensated_deg_per_h + 20.0).abs() < 1e-6);
    assert_eq!(
        seconds.iter().map(|s| s.frames).sum::<usize>(),
        3 * cycles_per_s as usize
    );
}

/// The simulated board's real stream with every 7th frame dropped on the link.
struct DropEvery7 {
    inner: SimLink,
    pending: Vec<u8>,
    frames_seen: usize,
    dropped: u64,
}

impl Link for DropEvery7 {
    fn send(&mut self, bytes: &[u8]) -> io::Result<()> {
        self.inner.send(bytes)
    }
    fn receive(&mut self, out: &mut Vec<u8>, timeout: Duration) -> io::Result<usize> {
        self.inner.receive(&mut self.pending, timeout)?;
        let before = out.len();
        // Pass text lines through; filter complete 0x00-terminated chunks.
        while let Some(zero) = self.pending.iter().position(|&b| b == 0) {
            let chunk: Vec<u8> = self.pending.drain(..=zero).collect();
            if decode_frame(&chunk[..chunk.len() - 1]).is_ok() {
                self.frames_seen += 1;
                if self.frames_seen.is_multiple_of(7) {
                    self.dropped += 1;
                    continue;
                }
            }
            out.extend(chunk);
        }
        if self.pending.ends_with(b"\r\n") {
            out.append(&mut self.pending);
        }
        Ok(out.len() - before)
    }
    fn elapsed(&self) -> Duration {
        self.inner.elapsed()
    }
    fn pause(&mut self, d: Duration) {
        self.inner.pause(d)
    }
}

#[test]
fn frames_lost_on_a_real_stream_are_counted_exactly() {
    let device = sim::boot(
        SimInput::Constant {
            rate_deg_per_h: 13.888,
        },
        5,
        CalibrationFlash::default(),
        0,
        Some(sim::test_key()),
    )
    .unwrap();
    let mut link = SimLink::new(device);
    link.pause(Duration::from_millis(500));
    let mut client = Client::new(DropEvery7 {
        inner: link,
        pending: Vec::new(),
        frames_seen: 0,
        dropped: 0,
    });
    let capture = ops::stream(&mut client, 2, Duration::from_secs(2), &mut |_| {}).unwrap();
    let dropped = client.link().dropped;
    assert!(dropped >= 50, "{dropped}");
    let span = capture.records.last().unwrap().sequence - capture.records[0].sequence + 1;
    assert_eq!(capture.records.len() as u64 + capture.lost(), span as u64);
    // Drops after the last received frame cannot show as a gap.
    assert!(
        dropped - capture.lost() <= 1,
        "{dropped} vs {}",
        capture.lost()
    );
    assert_eq!(capture.bad_frames, 0);
}

/// Line noise instead of frames: never a panic, never a record that fails its CRC, every
/// chunk counted as bad (a random 45-byte chunk passes CRC-32 with odds of 2^-32).
#[test]
fn random_bytes_are_bad_frames_not_records() {
    let mut x: u64 = 0x0DDB_A11C_AFE5_EED5;
    let mut capture = Capture::new(1);
    let mut chunks = 0;
    for _ in 0..20_000 {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        let len = (x % 60) as usize + 1;
        let chunk: Vec<u8> = (0..len)
            .map(|i| {
                ((x >> (i % 8 * 8)) as u8)
                    .wrapping_add((i as u8).wrapping_mul(31))
                    .max(1)
            })
            .collect();
        capture.push_chunk(&chunk);
        chunks += 1;
    }
    assert_eq!(capture.records.len(), 0);
    assert_eq!(capture.bad_frames, chunks);
}

/// A board that restarts mid-stream (its sequence starts again from 0) and a repeated frame
/// are no lost frames, and the records' times go on instead of jumping by 2^32 frames.
#[test]
fn a_restart_and_a_repeat_are_neither_lost_frames_nor_a_time_jump() {
    let scale = RateScale {
        scale_factor_arcsec: 1.8655,
        timer_hz: DEFAULT_TIMER_HZ,
    };
    let mut capture = Capture::new(1);
    for s in [10, 11, 11, 0, 1] {
        let f = frame(&record(s, 5.0));
        capture.push_chunk(&f[..f.len() - 1]);
    }
    assert_eq!((capture.lost(), capture.gaps.out_of_order), (0, 2));
    let times = capture.times_s(&scale);
    let cycle_s = 215_938.0 / DEFAULT_TIMER_HZ;
    for (i, t) in times.iter().enumerate() {
        assert!((t - i as f64 * cycle_s).abs() < 1e-9, "{times:?}");
    }
}
