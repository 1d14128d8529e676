//! The board's fixed-rate output (`stream output`) on the host: frames -> records, lost
//! records, and CSV rows as they arrive (`rlg-cal record`).
//!
//! Frames are decoded with the firmware's own [`decode_output_frame`] (COBS + CRC-32); a chunk
//! that fails is a bad frame. The records carry a 64-bit sequence number and the 64-bit
//! capture-timer time of their latch, so lost records are counted exactly ([`OutputGaps`]) and
//! written as rows of their own, `valid` 0 and no angle, at the times the missing sequence
//! numbers would have had (the neighbours' period): an Allan deviation or an integration over
//! the file sees the gap, never an angle spliced across it.
//!
//! CSV columns: `t_s,delta_angle_arcsec,valid,sequence,status` (`t_s` from the first record;
//! the increment in arcsec with the board's scale factor from `id`; `status` the record's bits
//! in hex, `lost` for a row standing for a lost record). The first three are those of
//! `rlg-sim record`'s file, which carries the truth beside them instead.

use crate::capture::RateScale;
use firmware::protocol::output_frame::{decode_output_frame, OutputGaps};
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
    /// Time ticks and sequence of the first record, and of the last one.
    first: Option<(u64, u64)>,
    last: Option<(u64, u64)>,
    /// Chunks that were not valid frames.
    pub bad_frames: u64,
    /// Invalid records received.
    pub invalid: u64,
    last_flush: Instant,
}

impl<W: Write> OutputRows<W> {
    /// Writes the header.
    pub fn new(out: W, scale: RateScale) -> io::Result<Self> {
        let mut out = io::BufWriter::new(out);
        writeln!(out, "{HEADER}")?;
        Ok(Self {
            out,
            scale,
            gaps: OutputGaps::default(),
            first: None,
            last: None,
            bad_frames: 0,
            invalid: 0,
            last_flush: Instant::now(),
        })
    }

    /// One 0x00-delimited chunk from the link: a record's row (and rows for the records lost
    /// before it), or a bad frame counted.
    pub fn push_chunk(&mut self, chunk: &[u8]) -> io::Result<Option<OutputRecord>> {
        match decode_output_frame(chunk) {
            Ok(record) => {
                self.push(&record)?;
                Ok(Some(record))
            }
            Err(_) => {
                self.bad_frames += 1;
                Ok(None)
            }
        }
    }

    fn seconds(&self, ticks: u64) -> f64 {
        let t0 = self.first.map_or(ticks, |(t, _)| t);
        ticks.wrapping_sub(t0) as f64 / self.scale.timer_hz
    }

    /// One record: rows for any records lost before it, then its own.
    pub fn push(&mut self, record: &OutputRecord) -> io::Result<()> {
        self.gaps.observe(record.sequence);
        if self.first.is_none() {
            self.first = Some((record.time_ticks, record.sequence));
        }
        if let Some((t_last, seq_last)) = self.last {
            if record.sequence > seq_last + 1 {
                let missing = record.sequence - seq_last - 1;
                let step = record.time_ticks.saturating_sub(t_last) as f64 / (missing + 1) as f64;
                for k in 1..=missing {
                    let t = self.seconds(t_last) + k as f64 * step / self.scale.timer_hz;
                    writeln!(self.out, "{t:.6},,0,{},lost", seq_last + k)?;
                }
            }
        }
        self.last = Some((record.time_ticks, record.sequence));
        let valid = record.is_valid();
        self.invalid += u64::from(!valid);
        let arcsec = record.delta_angle_fringes() * self.scale.scale_factor_arcsec;
        writeln!(
            self.out,
            "{:.6},{arcsec:.6},{},{},{:04x}",
            self.seconds(record.time_ticks),
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

    /// Seconds of board time between the first and the last record.
    pub fn span_s(&self) -> f64 {
        self.last.map_or(0.0, |(t, _)| self.seconds(t))
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
            time_ticks: 1_000_000 + sequence * 84_000,
            period_ticks: 84_000,
            delta_angle_q16: 65536,
            angle_q16: sequence as i64 * 65536,
            rate_deg_per_h: 0.0,
            status: OutputStatus::VALID.union(OutputStatus::DITHER_LOCKED),
        }
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
            rows.push(&record(s)).unwrap();
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
}
