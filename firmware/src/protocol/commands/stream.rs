//! `stream on [<n>]`, `stream output` and `stream off`: the countdown that picks every n-th
//! dither cycle for a binary frame, or every fixed-rate output record ([`StreamState`]). The
//! frame formats are [`crate::protocol::stream`] and [`crate::protocol::output_frame`]; one
//! stream at a time, so the host knows which frames it reads from the command it sent.

use super::ok_with;
use crate::protocol::output_frame::MAX_OUTPUT_FRAME;
use crate::protocol::respond::Response;
use crate::protocol::stream::{StreamRecord, MAX_FRAME};
use crate::protocol::thermal_frame::{ThermalFrame, ThermalFramer};
use crate::signal::lockin::CycleRecord;
use crate::signal::output::record::OutputRecord;

/// The stream settings and position.
#[derive(Clone, Debug, Default)]
pub struct StreamState {
    /// Every n-th cycle is sent; `None`: streaming off.
    divider: Option<u16>,
    /// Cycles until the next frame (the first frame goes with the next cycle).
    countdown: u16,
    /// The next frame's sequence number (wrapping; the host counts lost frames by it).
    sequence: u32,
    /// The output records are streamed (their own 64-bit sequence numbers count them).
    output: bool,
    /// When the output stream's thermal frames go (`protocol::thermal_frame`).
    thermal: ThermalFramer,
}

/// An output record to stream, and the thermal frame to send before it, if one is due.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StreamedOutput {
    /// New temperature and rate values, sent first.
    pub thermal: Option<ThermalFrame>,
    /// The record.
    pub record: OutputRecord,
}

impl StreamState {
    /// Whether binary streaming is on.
    pub fn on(&self) -> bool {
        self.divider.is_some() || self.output
    }

    /// `stream output`: every output record as a frame (the cycle stream stops).
    pub fn command_output(&mut self) -> Response {
        self.divider = None;
        self.output = true;
        self.thermal.restart();
        ok_with(format_args!("stream=output frame_bytes={MAX_OUTPUT_FRAME}"))
    }

    /// One output record: what to send, when the output is streamed.
    pub fn on_output(&mut self, record: &OutputRecord) -> Option<StreamedOutput> {
        self.output.then(|| StreamedOutput {
            thermal: self.thermal.before(record),
            record: *record,
        })
    }

    /// A thermal frame could not be sent: the next streamed record gets one.
    pub fn thermal_frame_lost(&mut self) {
        self.thermal.restart();
    }

    /// `stream on <n>` (`Some(n)`) or `stream off` (`None`).
    pub fn command(&mut self, divider: Option<u16>) -> Response {
        self.divider = divider;
        self.output = false;
        self.countdown = 1;
        match divider {
            Some(n) => ok_with(format_args!(
                "stream=on divider={n} frame_bytes={MAX_FRAME}"
            )),
            None => ok_with(format_args!("stream=off")),
        }
    }

    /// `n` dither cycles were closed but lost before they reached the service (a full record
    /// queue): the frames they were due are counted as sent, so the host sees the loss as a
    /// sequence gap of exactly that many frames.
    pub fn skip(&mut self, n: u32) {
        let Some(divider) = self.divider else {
            return;
        };
        // Frames due among the n cycles: the first when the countdown runs out, then every
        // `divider` cycles. Every new countdown lies in 1..=divider, so it fits a u16.
        let divider = u32::from(divider.max(1));
        let countdown = u32::from(self.countdown);
        let Some(after_first) = n.checked_sub(countdown) else {
            self.countdown = u16::try_from(countdown.saturating_sub(n)).unwrap_or(u16::MAX);
            return;
        };
        let due = after_first
            .checked_div(divider)
            .unwrap_or(0)
            .saturating_add(1);
        self.sequence = self.sequence.wrapping_add(due);
        let into = after_first.checked_rem(divider).unwrap_or(0);
        self.countdown = u16::try_from(divider.saturating_sub(into)).unwrap_or(u16::MAX);
    }

    /// One dither cycle: the frame to send, when one is due.
    pub fn on_cycle(&mut self, record: &CycleRecord) -> Option<StreamRecord> {
        let divider = self.divider?;
        if self.countdown > 1 {
            self.countdown = self.countdown.saturating_sub(1);
            return None;
        }
        self.countdown = divider;
        let frame = StreamRecord::from_cycle(self.sequence, record);
        self.sequence = self.sequence.wrapping_add(1);
        Some(frame)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::protocol::commands::testing::text;

    fn record() -> CycleRecord {
        CycleRecord {
            output: Default::default(),
            raw_increment: crate::units::PhaseDelta::from_q32(5),
            terms: Default::default(),
            end_phase: Default::default(),
            dither_amplitude_rad: 1.0,
            dither_hz: 389.0,
        }
    }

    #[test]
    fn off_sends_nothing() {
        let mut s = StreamState::default();
        assert!(!s.on());
        assert_eq!(s.on_cycle(&record()), None);
        assert_eq!(text(s.command(None)).trim_end(), "OK stream=off");
        assert_eq!(s.on_cycle(&record()), None);
    }

    #[test]
    fn on_sends_every_nth_cycle_with_consecutive_sequence_numbers() {
        let mut s = StreamState::default();
        let answer = text(s.command(Some(3)));
        assert_eq!(
            answer.trim_end(),
            format!("OK stream=on divider=3 frame_bytes={MAX_FRAME}")
        );
        assert!(s.on());
        let sent: Vec<Option<u32>> = (0..7)
            .map(|_| s.on_cycle(&record()).map(|f| f.sequence))
            .collect();
        assert_eq!(sent, [Some(0), None, None, Some(1), None, None, Some(2)]);
        // Switching again restarts the countdown, not the sequence.
        s.command(Some(1));
        assert_eq!(s.on_cycle(&record()).map(|f| f.sequence), Some(3));
        s.command(None);
        assert_eq!(s.on_cycle(&record()), None);
    }

    /// `stream output` sends every output record and no cycle; `stream on` or `off` ends it.
    #[test]
    fn output_mode_sends_every_record_and_no_cycle() {
        let mut s = StreamState::default();
        let out = OutputRecord {
            sequence: 7,
            time_ticks: 0,
            period_ticks: 84_000,
            delta_angle_q16: 1,
            angle_q16: 2,
            rate_deg_per_h: 3.0,
            status: Default::default(),
            temperature_q7: crate::thermal::state::NO_VALUE,
            temperature_rate_centi_c_per_min: crate::thermal::state::NO_VALUE,
        };
        assert_eq!(s.on_output(&out), None);
        assert_eq!(
            text(s.command_output()).trim_end(),
            format!("OK stream=output frame_bytes={MAX_OUTPUT_FRAME}")
        );
        assert!(s.on());
        // The stream's first record goes after a thermal frame; the next, unchanged, alone.
        let first = s.on_output(&out).unwrap();
        assert_eq!(first.record, out);
        assert_eq!(first.thermal.map(|t| t.from_sequence), Some(out.sequence));
        assert_eq!(s.on_output(&out).map(|o| o.thermal), Some(None));
        // A new `stream output` restarts them.
        s.command_output();
        assert!(s.on_output(&out).unwrap().thermal.is_some());
        assert_eq!(s.on_cycle(&record()), None);
        s.command(Some(1));
        assert_eq!(s.on_output(&out), None);
        assert!(s.on_cycle(&record()).is_some());
        s.command(None);
        assert!(!s.on());
    }

    /// Lost cycles consume the sequence numbers of the frames they were due: with divider 1
    /// every lost cycle is one missing number, with divider 3 one per three, and the
    /// countdown goes on where it was (the same frames as if the cycles had arrived).
    #[test]
    fn lost_cycles_leave_a_gap_of_the_frames_they_were_due() {
        for divider in [1u16, 3] {
            let (mut lossy, mut full) = (StreamState::default(), StreamState::default());
            lossy.command(Some(divider));
            full.command(Some(divider));
            let mut sent = Vec::new();
            for i in 0..40u32 {
                let f = full.on_cycle(&record()).map(|f| f.sequence);
                if (10..17).contains(&i) {
                    if i == 16 {
                        lossy.skip(7);
                    }
                    continue;
                }
                let l = lossy.on_cycle(&record()).map(|f| f.sequence);
                assert_eq!(l, f, "divider {divider}, cycle {i}");
                sent.extend(l);
            }
            assert!(sent.windows(2).any(|w| w[1] - w[0] > 1), "a gap shows");
        }
    }
}
