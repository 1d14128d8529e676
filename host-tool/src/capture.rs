//! Streamed frames -> per-cycle records, lost frames, CSV rows and an SVG plot of the rate.
//!
//! Frames are decoded with the firmware's own [`decode_frame`] (COBS + CRC-32); a chunk that
//! fails is counted as a bad frame, and a gap in the sequence numbers as lost frames
//! ([`GapCounter`]). Frames carry no timestamp: the time of a record is its sequence distance
//! from the first one times the divider times the mean cycle duration, which counts lost frames
//! in and is exact to the dither period's stability.
//!
//! Rates: a cycle's increment in Q32 fringes times the scale factor (arcsec per fringe) over
//! its duration (capture-timer ticks over the timer frequency) is arcsec/s, which is deg/h.

use firmware::protocol::stream::{decode_frame, GapCounter, StreamRecord};
use firmware::units::Q32_PER_FRINGE;
use rlg_sim::plot::{Figure, Panel, Series, Style};
use std::io::{self, Write};

/// Capture-timer frequency of the board (the F405's TIM2/TIM5 at 84 MHz), Hz.
pub const DEFAULT_TIMER_HZ: f64 = 84e6;

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

    /// One 0x00-delimited chunk from the link.
    pub fn push_chunk(&mut self, chunk: &[u8]) {
        match decode_frame(chunk) {
            Ok(record) => {
                self.gaps.observe(record.sequence);
                self.records.push(record);
            }
            Err(_) => self.bad_frames += 1,
        }
    }

    /// Frames missing from the sequence numbers.
    pub fn lost(&self) -> u64 {
        self.gaps.lost
    }

    /// Mean duration of a streamed cycle, s.
    fn mean_cycle_s(&self, scale: &RateScale) -> f64 {
        let ticks: f64 = self.records.iter().map(|r| r.duration_ticks as f64).sum();
        ticks / self.records.len().max(1) as f64 / scale.timer_hz
    }

    /// Each record's time from the first record, s (lost frames counted in).
    pub fn times_s(&self, scale: &RateScale) -> Vec<f64> {
        let step_s = self.mean_cycle_s(scale) * self.divider as f64;
        let Some(first) = self.records.first() else {
            return Vec::new();
        };
        let mut frames_since_first: u64 = 0;
        let mut last = first.sequence;
        self.records
            .iter()
            .map(|r| {
                frames_since_first += r.sequence.wrapping_sub(last) as u64;
                last = r.sequence;
                frames_since_first as f64 * step_s
            })
            .collect()
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
    pub fn write_csv(&self, mut out: impl Write, scale: &RateScale) -> io::Result<()> {
        writeln!(
            out,
            "sequence,time_s,end_phase_q32,raw_increment_q32,compensated_increment_q32,\
p1_s,p2_s,duration_ticks,flags,compensated_rate_deg_h"
        )?;
        for (r, t) in self.records.iter().zip(self.times_s(scale)) {
            let rate =
                scale.rate_deg_per_h(r.compensated_increment_q32 as f64, r.duration_ticks as f64);
            writeln!(
                out,
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
        }
        out.flush()
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
