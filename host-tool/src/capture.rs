//! Streamed frames -> per-cycle records, lost frames, CSV rows and an SVG plot of the rate.
//!
//! Frames are decoded with the firmware's own [`decode_frame`] (COBS + CRC-32); a chunk that
//! fails is counted as a bad frame, and a gap in the sequence numbers as lost frames
//! ([`GapCounter`]). Frames carry no timestamp: the time of a record is its sequence distance
//! from the first one times the divider times the mean cycle duration of the records up to it
//! ([`FrameClock`]), which counts lost frames in, is exact to the dither period's stability and
//! is known the moment the record arrives: [`CsvRows`] writes each row as it comes (buffered,
//! flushed at least once a second), so an interrupted run keeps every frame received.
//!
//! Rates: a cycle's increment in Q32 fringes times the scale factor (arcsec per fringe) over
//! its duration (capture-timer ticks over the timer frequency) is arcsec/s, which is deg/h.

use firmware::profile::BoardProfile;
use firmware::protocol::stream::{decode_frame, sequence_step, GapCounter, StreamRecord};
use firmware::units::Q32_PER_FRINGE;
use host_cli::plot::{Figure, Panel, Series, Style};
use std::io::{self, Write};
use std::time::{Duration, Instant};

/// Capture-timer frequency of the board (the F405's TIM2/TIM5), Hz: the board profile's.
pub const DEFAULT_TIMER_HZ: f64 = BoardProfile::F405.timer_hz as f64;

/// What turns frame fields into physical units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RateScale {
    /// From the board's `id` (`sf_arcsec`).
    pub scale_factor_arcsec: f64,
    /// Capture-timer frequency, Hz: the unit of `duration_ticks` (the board's `id`, `timer_hz`).
    pub timer_hz: f64,
}

impl RateScale {
    /// Rate over one or more cycles: summed increment (Q32 fringes) over summed ticks, deg/h.
    pub fn rate_deg_per_h(&self, increment_q32: f64, duration_ticks: f64) -> f64 {
        if duration_ticks <= 0.0 {
            return f64::NAN;
        }
        increment_q32 / Q32_PER_FRINGE * self.scale_factor_arcsec / (duration_ticks / self.timer_hz)
    }
}

/// The frames of one streaming session.
#[derive(Clone, Debug, Default)]
pub struct Capture {
    /// The valid frames, in arrival order.
    pub records: Vec<StreamRecord>,
    /// Frames received and lost, from the sequence numbers.
    pub gaps: GapCounter,
    /// Chunks that were not valid frames (broken COBS, wrong length, bad CRC).
    pub bad_frames: u64,
    /// Cycles per frame (`stream on <divider>`).
    pub divider: u16,
}

/// One second of the stream, averaged.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SecondMean {
    /// Middle of the second, s from the first record.
    pub time_s: f64,
    /// Mean compensated rate over the second, deg/h.
    pub compensated_deg_per_h: f64,
    /// Mean uncompensated rate over the second, deg/h.
    pub raw_deg_per_h: f64,
    /// Frames received in the second.
    pub frames: usize,
}

impl Capture {
    /// An empty capture of a stream at `divider` cycles per frame (0 is taken as 1).
    pub fn new(divider: u16) -> Self {
        Self {
            divider: divider.max(1),
            ..Self::default()
        }
    }

    /// One 0x00-delimited chunk from the link; the record, if it was a valid frame.
    pub fn push_chunk(&mut self, chunk: &[u8]) -> Option<&StreamRecord> {
        match decode_frame(chunk) {
            Ok(record) => {
                self.gaps.observe(record.sequence);
                self.records.push(record);
                self.records.last()
            }
            Err(_) => {
                self.bad_frames += 1;
                None
            }
        }
    }

    /// Frames missing from the sequence numbers.
    pub fn lost(&self) -> u64 {
        self.gaps.lost
    }

    /// Each record's time from the first record, s (lost frames counted in; [`FrameClock`]).
    pub fn times_s(&self, scale: &RateScale) -> Vec<f64> {
        let mut clock = FrameClock::new(self.divider, scale.timer_hz);
        self.records.iter().map(|r| clock.time_s(r)).collect()
    }

    /// Mean compensated and raw rates over the whole capture, deg/h.
    pub fn mean_rates(&self, scale: &RateScale) -> (f64, f64) {
        mean_rates(&self.records, scale)
    }

    /// Rates averaged per second of the capture.
    pub fn per_second(&self, scale: &RateScale) -> Vec<SecondMean> {
        let times = self.times_s(scale);
        let mut out: Vec<SecondMean> = Vec::new();
        let mut start = 0;
        while start < self.records.len() {
            let second = times[start].floor();
            let end = start + times[start..].partition_point(|t| t.floor() == second);
            let (comp, raw) = mean_rates(&self.records[start..end], scale);
            out.push(SecondMean {
                time_s: second + 0.5,
                compensated_deg_per_h: comp,
                raw_deg_per_h: raw,
                frames: end - start,
            });
            start = end;
        }
        out
    }

    /// One row per record: the frame's fields exactly, plus time and compensated rate.
    pub fn write_csv(&self, out: impl Write, scale: &RateScale) -> io::Result<()> {
        let mut rows = CsvRows::new(out, self.divider, *scale)?;
        for r in &self.records {
            rows.push(r)?;
        }
        rows.finish().map(drop)
    }

    /// The streamed rate over time, averaged per second, as an SVG document.
    pub fn svg(&self, scale: &RateScale, title: &str) -> String {
        let seconds = self.per_second(scale);
        let series = |label: &str, color, pick: fn(&SecondMean) -> f64| Series {
            label: label.to_owned(),
            points: seconds.iter().map(|s| (s.time_s, pick(s))).collect(),
            color,
            style: Style::LineAndMarkers,
        };
        Figure {
            title: format!(
                "{title}: {} frames, {} lost, {} bad",
                self.records.len(),
                self.lost(),
                self.bad_frames
            ),
            x_label: "time (s)".into(),
            panels: vec![Panel {
                title: format!("rate averaged per second (every {} cycle(s))", self.divider),
                y_label: "rate (deg/h)".into(),
                series: vec![
                    series("compensated", "#1f77b4", |s| s.compensated_deg_per_h),
                    series("raw", "#d62728", |s| s.raw_deg_per_h),
                ],
                weight: 1.0,
            }],
            width_px: 900.0,
            height_px: 500.0,
            axes: host_cli::plot::Axes::Linear,
        }
        .to_svg()
    }
}

fn mean_rates(records: &[StreamRecord], scale: &RateScale) -> (f64, f64) {
    let ticks: f64 = records.iter().map(|r| r.duration_ticks as f64).sum();
    let comp: f64 = records
        .iter()
        .map(|r| r.compensated_increment_q32 as f64)
        .sum();
    let raw: f64 = records.iter().map(|r| r.raw_increment_q32 as f64).sum();
    (
        scale.rate_deg_per_h(comp, ticks),
        scale.rate_deg_per_h(raw, ticks),
    )
}

/// The time of each record as it arrives: its sequence distance from the first record times
/// the divider times the mean cycle duration of the records so far, s.
#[derive(Clone, Debug)]
pub struct FrameClock {
    divider: f64,
    timer_hz: f64,
    last_sequence: Option<u32>,
    frames_since_first: u64,
    ticks: f64,
    records: u64,
}

impl FrameClock {
    /// A clock for a stream of every `divider`-th cycle, capture timer at `timer_hz`.
    pub fn new(divider: u16, timer_hz: f64) -> Self {
        Self {
            divider: divider.max(1) as f64,
            timer_hz,
            last_sequence: None,
            frames_since_first: 0,
            ticks: 0.0,
            records: 0,
        }
    }

    /// The next record's time, s from the first record. A frame whose sequence does not step
    /// forward (a board restart, a repeat) is taken as the next one, so the time goes on.
    pub fn time_s(&mut self, record: &StreamRecord) -> f64 {
        if let Some(last) = self.last_sequence {
            let step = sequence_step(last, record.sequence).unwrap_or(1);
            self.frames_since_first += u64::from(step);
        }
        self.last_sequence = Some(record.sequence);
        self.ticks += record.duration_ticks as f64;
        self.records += 1;
        let mean_cycle_s = self.ticks / self.records as f64 / self.timer_hz;
        self.frames_since_first as f64 * self.divider * mean_cycle_s
    }
}

/// The CSV of a stream, written row by row as the records arrive: buffered, flushed at least
/// once a second, so a run that is interrupted (or crashes) leaves every row received.
pub struct CsvRows<W: Write> {
    out: io::BufWriter<W>,
    clock: FrameClock,
    scale: RateScale,
    rows: u64,
    last_flush: Instant,
}

/// Longest time a written row may wait in the buffer.
pub const CSV_FLUSH_INTERVAL: Duration = Duration::from_secs(1);

impl<W: Write> CsvRows<W> {
    /// Writes the header.
    pub fn new(out: W, divider: u16, scale: RateScale) -> io::Result<Self> {
        let mut out = io::BufWriter::new(out);
        writeln!(
            out,
            "sequence,time_s,end_phase_q32,raw_increment_q32,compensated_increment_q32,\
p1_s,p2_s,duration_ticks,flags,compensated_rate_deg_h"
        )?;
        Ok(Self {
            out,
            clock: FrameClock::new(divider, scale.timer_hz),
            scale,
            rows: 0,
            last_flush: Instant::now(),
        })
    }

    /// One row: the frame's fields exactly, plus time and compensated rate.
    pub fn push(&mut self, r: &StreamRecord) -> io::Result<()> {
        let t = self.clock.time_s(r);
        let rate = self
            .scale
            .rate_deg_per_h(r.compensated_increment_q32 as f64, r.duration_ticks as f64);
        writeln!(
            self.out,
            "{},{t:.6},{},{},{},{},{},{},{},{rate:.6}",
            r.sequence,
            r.end_phase_q32,
            r.raw_increment_q32,
            r.compensated_increment_q32,
            r.p1_s,
            r.p2_s,
            r.duration_ticks,
            r.flags
        )?;
        self.rows += 1;
        if self.last_flush.elapsed() >= CSV_FLUSH_INTERVAL {
            self.out.flush()?;
            self.last_flush = Instant::now();
        }
        Ok(())
    }

    /// Rows written.
    pub fn rows(&self) -> u64 {
        self.rows
    }

    /// Flushes; returns the row count.
    pub fn finish(mut self) -> io::Result<u64> {
        self.out.flush()?;
        Ok(self.rows)
    }
}
