//! The board's fixed-rate output (`stream output`) on the host: frames -> records, lost
//! records, and CSV rows as they arrive (`rlg-cal record`).
//!
//! Frames are decoded with the firmware's own [`OutputStreamDecoder`] (COBS + CRC-32; the
//! records and the thermal frames that give them the block's temperature); a chunk that fails
//! is a bad frame. The records carry a 64-bit sequence number and the 64-bit
//! capture-timer time of their latch, so lost records are counted exactly ([`OutputGaps`]) and
//! written as rows of their own, `valid` 0 and no angle, at the times the missing sequence
//! numbers would have had (the neighbours' period): an Allan deviation or an integration over
//! the file sees the gap, never an angle spliced across it.
//!
//! A forged frame, or a corrupt one whose CRC happens to pass, must not make the host write a
//! row for every sequence number it skips (one far ahead would fill the disk). A step forward
//! is written as lost rows only when both clocks allow it ([`OutputRows::push`]): the board's
//! time advances, the board time of all believed steps together is not ahead of the host's
//! clock since the first record (by more than 1 % and 1 s: crystal tolerance, the link's
//! buffering), and the missing records fit in the board time between the two records at up to
//! twice the previous record's rate and at most [`MAX_OUTPUT_RATE_HZ`]. So the file grows by at
//! most that many rows per second of the host's clock, whatever arrives. Any other step is a
//! restart (a board reset, or an error): counted ([`OutputGaps::jumps`], `out_of_order`), no
//! rows, and the record starts a new segment whose times go on from the last row by the host
//! time between them, so `t_s` never goes back.
//!
//! CSV columns: `t_s,delta_angle_arcsec,valid,sequence,status` (`t_s` from the first record;
//! the increment in arcsec with the board's scale factor from `id`; `status` the record's bits
//! in hex, `lost` for a row standing for a lost record). The first three are those of
//! `rlg-sim record`'s file, which carries the truth beside them instead.

use crate::capture::RateScale;
use firmware::protocol::output_frame::{
    OutputGaps, OutputStreamDecoder, OutputStreamFrame, MAX_OUTPUT_RATE_HZ,
};
use firmware::signal::output::record::OutputRecord;
use std::io::{self, Write};
use std::time::{Duration, Instant};

/// The CSV header of a recorded output.
pub const HEADER: &str = "t_s,delta_angle_arcsec,valid,sequence,status";

/// A recording in progress: the gap count and the rows written.
pub struct OutputRows<W: Write> {
    out: io::BufWriter<W>,
    scale: RateScale,
    gaps: OutputGaps,
    /// The segment the records belong to (from the first record, and after each restart).
    segment: Option<Segment>,
    /// The last record: its time ticks, sequence, period, row time (s) and host clock.
    last: Option<Last>,
    /// The host's clock at the first record.
    first_received: Duration,
    /// Board time of all believed steps, s (compared with the host's clock).
    board_span_s: f64,
    /// The stream's decoder (it keeps the thermal values in force).
    decoder: OutputStreamDecoder,
    /// Chunks that were not valid frames.
    pub bad_frames: u64,
    /// Invalid records received.
    pub invalid: u64,
    last_flush: Instant,
}

/// A run of records with one time base: the first record's ticks and its row time.
#[derive(Clone, Copy)]
struct Segment {
    t0_ticks: u64,
    base_s: f64,
}

#[derive(Clone, Copy)]
struct Last {
    ticks: u64,
    sequence: u64,
    period_ticks: u32,
    t_s: f64,
    received: Duration,
}

/// How far the board's clock may run ahead of the host's before a step is not believed:
/// relative (crystals are good to 1e-4; 1 % is generous) and absolute (the link's buffering).
const CLOCK_AHEAD_REL: f64 = 0.01;
const CLOCK_AHEAD_S: f64 = 1.0;

impl<W: Write> OutputRows<W> {
    /// Writes the header.
    pub fn new(out: W, scale: RateScale) -> io::Result<Self> {
        let mut out = io::BufWriter::new(out);
        writeln!(out, "{HEADER}")?;
        Ok(Self {
            out,
            scale,
            gaps: OutputGaps::default(),
            segment: None,
            last: None,
            first_received: Duration::ZERO,
            board_span_s: 0.0,
            decoder: OutputStreamDecoder::default(),
            bad_frames: 0,
            invalid: 0,
            last_flush: Instant::now(),
        })
    }

    /// One 0x00-delimited chunk from the link, received at `received` on the link's clock: a
    /// record's row (and rows for the records lost before it), or a bad frame counted.
    pub fn push_chunk(
        &mut self,
        chunk: &[u8],
        received: Duration,
    ) -> io::Result<Option<OutputRecord>> {
        match self.decoder.decode(chunk) {
            Ok(OutputStreamFrame::Record(record)) => {
                self.push(&record, received)?;
                Ok(Some(record))
            }
            Ok(OutputStreamFrame::Thermal(_)) => Ok(None),
            Err(_) => {
                self.bad_frames += 1;
                Ok(None)
            }
        }
    }

    /// Seconds on the board's clock from `from` to `to` ticks (`None` when `to` is not later).
    fn board_s(&self, from: u64, to: u64) -> Option<f64> {
        to.checked_sub(from)
            .filter(|&d| d > 0)
            .map(|d| d as f64 / self.scale.timer_hz)
    }

    /// The records missing before `record`, and the board time between the two, when its step
    /// from `last` is believed (see the module docs); else `None` (a restart or an error).
    fn believed_gap(
        &self,
        last: &Last,
        record: &OutputRecord,
        received: Duration,
    ) -> Option<(u64, f64)> {
        if record.sequence <= last.sequence {
            return None;
        }
        let missing = record.sequence - last.sequence - 1;
        let between_s = self.board_s(last.ticks, record.time_ticks)?;
        let host_since_s = received.saturating_sub(self.first_received).as_secs_f64();
        if self.board_span_s + between_s > host_since_s * (1.0 + CLOCK_AHEAD_REL) + CLOCK_AHEAD_S {
            return None;
        }
        let period_s = f64::from(last.period_ticks.max(1)) / self.scale.timer_hz;
        let allowed = (2.0 * between_s / period_s).min(between_s * MAX_OUTPUT_RATE_HZ) + 1.0;
        (missing as f64 + 1.0 <= allowed).then_some((missing, between_s))
    }

    /// One record, received at `received` on the link's clock: rows for any records lost
    /// before it (when the step is believed), then its own.
    pub fn push(&mut self, record: &OutputRecord, received: Duration) -> io::Result<()> {
        let gap = self
            .last
            .and_then(|last| Some((last, self.believed_gap(&last, record, received)?)));
        match (self.last, gap) {
            (None, _) => {
                self.gaps.observe(record.sequence);
                self.first_received = received;
                self.segment = Some(Segment {
                    t0_ticks: record.time_ticks,
                    base_s: 0.0,
                });
            }
            (Some(_), Some((last, (missing, between_s)))) => {
                self.gaps.observe(record.sequence);
                self.board_span_s += between_s;
                let step_s = between_s / (missing + 1) as f64;
                for k in 1..=missing {
                    let t = last.t_s + k as f64 * step_s;
                    writeln!(self.out, "{t:.6},,0,{},lost", last.sequence + k)?;
                }
            }
            (Some(last), None) => {
                // A restart or an error: a new segment, its time going on by the host's clock.
                if record.sequence > last.sequence {
                    self.gaps.observe_jump(record.sequence);
                } else {
                    self.gaps.observe(record.sequence);
                }
                let host_s = received.saturating_sub(last.received).as_secs_f64();
                self.segment = Some(Segment {
                    t0_ticks: record.time_ticks,
                    base_s: last.t_s + host_s,
                });
            }
        }
        let t_s = self.segment.map_or(0.0, |s| {
            s.base_s + record.time_ticks.saturating_sub(s.t0_ticks) as f64 / self.scale.timer_hz
        });
        self.last = Some(Last {
            ticks: record.time_ticks,
            sequence: record.sequence,
            period_ticks: record.period_ticks,
            t_s,
            received,
        });
        let valid = record.is_valid();
        self.invalid += u64::from(!valid);
        let arcsec = record.delta_angle_fringes() * self.scale.scale_factor_arcsec;
        writeln!(
            self.out,
            "{t_s:.6},{arcsec:.6},{},{},{:04x}",
            u8::from(valid),
            record.sequence,
            record.status.0
        )?;
        if self.last_flush.elapsed() >= Duration::from_secs(1) {
            self.last_flush = Instant::now();
            self.out.flush()?;
        }
        Ok(())
    }

    /// Records received and lost so far.
    pub fn gaps(&self) -> OutputGaps {
        self.gaps
    }

    /// Seconds from the first record to the last (board time, restarts bridged by the host's).
    pub fn span_s(&self) -> f64 {
        self.last.map_or(0.0, |last| last.t_s)
    }

    /// Flushes the rows to the file.
    pub fn finish(mut self) -> io::Result<OutputGaps> {
        self.out.flush()?;
        Ok(self.gaps)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use firmware::signal::output::record::OutputStatus;

    fn record(sequence: u64) -> OutputRecord {
        OutputRecord {
            sequence,
            time_ticks: sequence.wrapping_mul(84_000).wrapping_add(1_000_000),
            period_ticks: 84_000,
            delta_angle_q16: 65536,
            angle_q16: sequence as i64 * 65536,
            rate_deg_per_h: 0.0,
            status: OutputStatus::VALID.union(OutputStatus::DITHER_LOCKED),
            temperature_q7: firmware::thermal::state::NO_VALUE,
            temperature_rate_centi_c_per_min: firmware::thermal::state::NO_VALUE,
        }
    }

    /// The host's clock when record `sequence` arrives: with the board's (1 ms per record).
    fn at(sequence: u64) -> Duration {
        Duration::from_millis(sequence)
    }

    /// Lost records are counted and get rows of their own (valid 0, no angle) at their times.
    #[test]
    fn lost_records_are_rows_and_counted() {
        let scale = RateScale {
            scale_factor_arcsec: 2.0,
            timer_hz: 84e6,
        };
        let mut buf = Vec::new();
        let mut rows = OutputRows::new(&mut buf, scale).unwrap();
        for s in [5, 6, 9, 10] {
            rows.push(&record(s), at(s)).unwrap();
        }
        let gaps = rows.finish().unwrap();
        assert_eq!((gaps.received, gaps.lost), (4, 2));
        let text = String::from_utf8(buf).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines[0], HEADER);
        assert_eq!(lines[1], "0.000000,2.000000,1,5,0003");
        assert_eq!(lines[3], "0.002000,,0,7,lost");
        assert_eq!(lines[4], "0.003000,,0,8,lost");
        assert_eq!(lines[5], "0.004000,2.000000,1,9,0003");
        assert_eq!(lines.len(), 7);
    }

    /// A writer that fails past `limit` bytes (a disk filling up).
    struct Limited {
        buf: Vec<u8>,
        limit: usize,
    }

    impl Write for Limited {
        fn write(&mut self, bytes: &[u8]) -> io::Result<usize> {
            if self.buf.len() + bytes.len() > self.limit {
                return Err(io::Error::other("disk full"));
            }
            self.buf.extend_from_slice(bytes);
            Ok(bytes.len())
        }
        fn flush(&mut self) -> io::Result<()> {
            Ok(())
        }
    }

    /// One forged (or corrupt but CRC-valid) frame far ahead, even with a time that matches
    /// its sequence, writes no rows for the records it pretends were lost: the jump is beyond
    /// what the elapsed time allows, so it is a restart or an error, counted as such; the
    /// records after it go on. A sequence at u64::MAX does not overflow.
    #[test]
    fn a_frame_far_ahead_is_a_jump_not_a_gap_of_rows() {
        let scale = RateScale {
            scale_factor_arcsec: 2.0,
            timer_hz: 84e6,
        };
        let mut out = Limited {
            buf: Vec::new(),
            limit: 1 << 20,
        };
        let mut rows = OutputRows::new(&mut out, scale).unwrap();
        for (sequence, host_ms) in [
            (5, 5),
            (6, 6),
            (1_000_000_000_000, 7),
            (7, 8),
            (u64::MAX, 9),
            (8, 10),
        ] {
            rows.push(&record(sequence), at(host_ms)).unwrap();
        }
        let gaps = rows.finish().unwrap();
        assert_eq!(
            (gaps.received, gaps.lost, gaps.jumps, gaps.out_of_order),
            (6, 0, 2, 2)
        );
        let text = String::from_utf8(out.buf).unwrap();
        assert_eq!(text.lines().count(), 7, "{text}");
        let times: Vec<f64> = text
            .lines()
            .skip(1)
            .map(|l| l.split(',').next().unwrap().parse().unwrap())
            .collect();
        assert!(times.windows(2).all(|w| w[1] > w[0]), "{times:?}");
        assert!(times[5] < 0.01, "{times:?}");
    }

    /// A gap the board's time allows but the host's does not (the board's clock far ahead of
    /// the host's since the first record) is a jump too; one both allow is written.
    #[test]
    fn a_gap_is_written_only_when_both_clocks_allow_it() {
        let scale = RateScale {
            scale_factor_arcsec: 2.0,
            timer_hz: 84e6,
        };
        let mut buf = Vec::new();
        let mut rows = OutputRows::new(&mut buf, scale).unwrap();
        rows.push(&record(0), at(0)).unwrap();
        // 5000 records (5 s of board time) missing, the host 4.5 s later: believed.
        rows.push(&record(5_001), Duration::from_millis(4_500))
            .unwrap();
        // 10 000 more, but the host only 0.1 s later: the board 11 s ahead of it.
        rows.push(&record(15_002), Duration::from_millis(4_600))
            .unwrap();
        let gaps = rows.finish().unwrap();
        assert_eq!((gaps.lost, gaps.jumps), (5_000, 1));
        assert_eq!(String::from_utf8(buf).unwrap().lines().count(), 1 + 5_003);
        // A period of one tick claimed, then 100 000 records in one second on both clocks:
        // more than MAX_OUTPUT_RATE_HZ allows, a jump.
        let mut buf = Vec::new();
        let mut rows = OutputRows::new(&mut buf, scale).unwrap();
        let fast = OutputRecord {
            period_ticks: 1,
            ..record(0)
        };
        rows.push(&fast, at(0)).unwrap();
        let far = OutputRecord {
            time_ticks: fast.time_ticks + 84_000_000,
            ..record(100_001)
        };
        rows.push(&far, Duration::from_secs(1)).unwrap();
        let gaps = rows.finish().unwrap();
        assert_eq!((gaps.lost, gaps.jumps), (0, 1));
    }
}
