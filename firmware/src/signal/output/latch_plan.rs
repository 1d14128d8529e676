//! Stage 6, the output latch's timing: one hardware latch, two clients.
//!
//! On the F405 the turnaround latch is a compare of the capture timer (TIM2 CC1) whose trigger
//! pulse converts both photodiodes (ADC1/ADC2 injected) and captures the encoder count (TIM5
//! IC3) in the same clock: count and fractional fringe belong together to within a few tens of
//! nanoseconds, which a fringe rate of 590 kHz needs. An output latch (a sync edge, or the
//! internal output rate) needs exactly that too, plus the pick-off (ADC3, triggered by the same
//! pulse). So the output latch reuses the compare: the sync edge is captured (TIM2 CC2), and
//! the compare is armed for it a short lead later, unless a turnaround is armed close by, in
//! which case the output latch waits until just after it. [`LatchPlan`] decides which compare
//! is armed: plain logic, host-tested, called by the board's TIM2 and latch handlers.
//!
//! # Timing
//!
//! - An output latch fires [`OUTPUT_LEAD_TICKS`] after the later of its edge and the moment the
//!   handler arms it (2 us at 84 MHz), or [`GUARD_TICKS`] after a turnaround armed within
//!   [`GUARD_TICKS`] of it (and out of the drive tick's conversion window, [`KeepOut`]): the
//!   record's time is the latch's, so the navigation computer sees when the angle was taken
//!   (2 us after its sync edge, at most about 13 us when it meets a turnaround and a window).
//! - A turnaround is never moved: an output latch due within [`GUARD_TICKS`] before it waits
//!   until after it (the turnaround's own ~1 us accuracy is what the lock-in terms need).
//! - One output latch may be pending; a second sync edge before the first latch fired (a sync
//!   faster than ~15 us) is counted as an overrun and dropped: the record then spans two sync
//!   periods, which its `period_ticks` shows.
//!
//! Ticks wrap (32-bit, 51 s at 84 MHz); every comparison is of wrapping differences within
//! half a wrap.

use crate::sample::TurnaroundKind;

/// Lead from a sync edge (or from the handler, if it runs later) to the output latch, ticks
/// (2 us at 84 MHz: the handler's return and the compare's set-up).
pub const OUTPUT_LEAD_TICKS: u32 = 168;
/// Closest two latches may be, ticks (5 us): the injected conversions (15 ADC clocks of
/// sampling plus 12 of conversion at 21 MHz, 1.3 us), the latch handler's entry and copy, and
/// still the board's minimum lead (2 us) to arm the next compare when the first has fired.
pub const GUARD_TICKS: u32 = 420;

/// What a compare latch is for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LatchKind {
    /// A turnaround of this kind (its sample goes to the cycle assembly).
    Turnaround(TurnaroundKind),
    /// An output latch (its sample ends an output period).
    Output,
}

/// The compare to arm: what and when (ticks), or nothing pending.
pub type Arm = Option<(LatchKind, u32)>;

/// A periodic window an output latch must avoid: on the F405 the drive tick's conversion of
/// the pick-off on the same converter (ADC3 injected, which would delay the latch's regular
/// conversion of it).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct KeepOut {
    /// Period of the window, ticks (the drive tick: 2100).
    pub period_ticks: u32,
    /// A counter instant at which a window starts (not reduced modulo the period: 2^32 is no
    /// multiple of it), within half a counter wrap of every instant placed against it; the
    /// board re-anchors it from its two timers at every use (`board_timing::phase`).
    pub start_ticks: u32,
    /// Its width, ticks.
    pub width_ticks: u32,
}

impl KeepOut {
    /// `at`, or the end of the window it falls in.
    pub fn clear_of(&self, at: u32) -> u32 {
        if self.period_ticks == 0 {
            return at;
        }
        let into = i64::from(at.wrapping_sub(self.start_ticks) as i32)
            .rem_euclid(i64::from(self.period_ticks)) as u32;
        if into < self.width_ticks {
            at.wrapping_add(self.width_ticks - into)
        } else {
            at
        }
    }
}

/// The two clients' pending latches.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LatchPlan {
    turnaround: Option<(TurnaroundKind, u32)>,
    output: Option<u32>,
    keep_out: Option<KeepOut>,
    /// Sync edges dropped because an output latch was still pending (saturating).
    pub overruns: u32,
}

/// `a` is before `b` (wrapping ticks).
fn before(a: u32, b: u32) -> bool {
    (b.wrapping_sub(a) as i32) > 0
}

impl LatchPlan {
    /// Nothing pending.
    pub const fn new() -> Self {
        Self {
            turnaround: None,
            output: None,
            keep_out: None,
            overruns: 0,
        }
    }

    /// Nothing pending; output latches kept out of `keep_out`'s windows.
    pub const fn with_keep_out(keep_out: KeepOut) -> Self {
        Self {
            keep_out: Some(keep_out),
            ..Self::new()
        }
    }

    /// Re-anchors the keep-out windows (the pending latches stay where they are).
    pub fn set_keep_out(&mut self, keep_out: KeepOut) {
        self.keep_out = Some(keep_out);
    }

    /// `at` moved out of a turnaround's guard and the keep-out windows (a move may land in the
    /// other: at most a few rounds, each moving forwards).
    fn place_output(&self, mut at: u32) -> u32 {
        for _ in 0..4 {
            let before_moves = at;
            if let Some((_, t)) = self.turnaround {
                if at.wrapping_sub(t).wrapping_add(GUARD_TICKS) < 2 * GUARD_TICKS {
                    at = t.wrapping_add(GUARD_TICKS);
                }
            }
            if let Some(k) = self.keep_out {
                at = k.clear_of(at);
            }
            if at == before_moves {
                break;
            }
        }
        at
    }

    /// The compare that must be armed now: the earlier pending latch.
    pub fn armed(&self) -> Arm {
        match (self.turnaround, self.output) {
            (Some((kind, t)), Some(o)) if !before(o, t) => Some((LatchKind::Turnaround(kind), t)),
            (_, Some(o)) => Some((LatchKind::Output, o)),
            (Some((kind, t)), None) => Some((LatchKind::Turnaround(kind), t)),
            (None, None) => None,
        }
    }

    /// The turnaround schedule armed a turnaround at `compare` (replacing any pending one); an
    /// output latch within [`GUARD_TICKS`] before or after it moves to just after it.
    pub fn on_turnaround(&mut self, kind: TurnaroundKind, compare: u32) -> Arm {
        self.turnaround = Some((kind, compare));
        if let Some(o) = self.output {
            self.output = Some(self.place_output(o));
        }
        self.armed()
    }

    /// The turnaround was dropped (parked, late): only an output latch may stay armed.
    pub fn cancel_turnaround(&mut self) -> Arm {
        self.turnaround = None;
        self.armed()
    }

    /// A sync edge at `edge`, seen by the handler at `now`: the output latch is planned
    /// [`OUTPUT_LEAD_TICKS`] after the later of the two, after a turnaround it would crowd.
    pub fn on_sync(&mut self, edge: u32, now: u32) -> Arm {
        if self.output.is_some() {
            self.overruns = self.overruns.saturating_add(1);
            return self.armed();
        }
        let start = if before(edge, now) { now } else { edge };
        self.output = Some(self.place_output(start.wrapping_add(OUTPUT_LEAD_TICKS)));
        self.armed()
    }

    /// The armed output latch could not be armed in time (the handler ran late): it moves to
    /// `at` (placed as a new one would be).
    pub fn defer_output(&mut self, at: u32) -> Arm {
        if self.output.is_some() {
            self.output = Some(self.place_output(at));
        }
        self.armed()
    }

    /// The armed compare fired: what it latched, and the compare to arm next.
    pub fn on_fired(&mut self) -> (Option<LatchKind>, Arm) {
        let fired = self.armed().map(|(kind, _)| kind);
        match fired {
            Some(LatchKind::Output) => self.output = None,
            Some(LatchKind::Turnaround(_)) => self.turnaround = None,
            None => {}
        }
        (fired, self.armed())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use TurnaroundKind::{Minus, Plus};

    /// Alone, each latch is armed where it was asked for (a sync a lead after its edge).
    #[test]
    fn alone_each_latch_is_armed_as_asked() {
        let mut p = LatchPlan::new();
        assert_eq!(
            p.on_turnaround(Plus, 10_000),
            Some((LatchKind::Turnaround(Plus), 10_000))
        );
        assert_eq!(p.on_fired(), (Some(LatchKind::Turnaround(Plus)), None));
        assert_eq!(
            p.on_sync(50_000, 50_100),
            Some((LatchKind::Output, 50_100 + OUTPUT_LEAD_TICKS))
        );
        assert_eq!(p.on_fired(), (Some(LatchKind::Output), None));
        assert_eq!(p.on_fired(), (None, None));
    }

    /// The earlier one is armed first, the other after it fires; an output latch crowding a
    /// turnaround moves to just after it, the turnaround never moves.
    #[test]
    fn the_earlier_goes_first_and_the_turnaround_never_moves() {
        let mut p = LatchPlan::new();
        p.on_turnaround(Minus, 100_000);
        assert_eq!(
            p.on_sync(20_000, 20_010),
            Some((LatchKind::Output, 20_010 + OUTPUT_LEAD_TICKS))
        );
        assert_eq!(
            p.on_fired(),
            (
                Some(LatchKind::Output),
                Some((LatchKind::Turnaround(Minus), 100_000))
            )
        );
        // A sync whose latch would fall 100 ticks before the turnaround: after it instead.
        let edge = 100_000 - OUTPUT_LEAD_TICKS - 100;
        assert_eq!(
            p.on_sync(edge, edge),
            Some((LatchKind::Turnaround(Minus), 100_000))
        );
        assert_eq!(
            p.on_fired(),
            (
                Some(LatchKind::Turnaround(Minus)),
                Some((LatchKind::Output, 100_000 + GUARD_TICKS))
            )
        );
        // A turnaround scheduled onto a pending output latch pushes the latch, not itself.
        let mut p = LatchPlan::new();
        p.on_sync(0, 0);
        assert_eq!(
            p.on_turnaround(Plus, OUTPUT_LEAD_TICKS + 10),
            Some((LatchKind::Turnaround(Plus), OUTPUT_LEAD_TICKS + 10))
        );
        assert_eq!(
            p.on_fired().1,
            Some((LatchKind::Output, OUTPUT_LEAD_TICKS + 10 + GUARD_TICKS))
        );
    }

    /// Output latches stay out of the keep-out windows (the drive tick's conversion), also when
    /// moved after a turnaround.
    #[test]
    fn output_latches_avoid_the_keep_out_windows() {
        let k = KeepOut {
            period_ticks: 2100,
            start_ticks: 2000,
            width_ticks: 250,
        };
        let mut p = LatchPlan::with_keep_out(k);
        // Edge so that edge + lead = 2100 + 50: inside the window [2000, 2250) -> 2250.
        let edge = 2150 - OUTPUT_LEAD_TICKS;
        assert_eq!(p.on_sync(edge, edge), Some((LatchKind::Output, 2250)));
        p.on_fired();
        // Outside a window: unmoved.
        assert_eq!(
            p.on_sync(3000, 3000),
            Some((LatchKind::Output, 3000 + OUTPUT_LEAD_TICKS))
        );
        p.on_fired();
        // Moved after a turnaround at 5900 -> 5900 + 420 = 6320, which lies in the window
        // [6200, 6450): -> 6450.
        p.on_turnaround(Plus, 5900);
        p.on_sync(5900 - OUTPUT_LEAD_TICKS, 5900 - OUTPUT_LEAD_TICKS);
        assert_eq!(p.on_fired().1, Some((LatchKind::Output, 6450)));
        for at in (0..20_000u32).step_by(7) {
            let c = k.clear_of(at);
            let into = i64::from(c.wrapping_sub(2000) as i32).rem_euclid(2100);
            assert!(into >= 250 && c >= at && c - at <= 250, "{at}");
        }
    }

    /// A second sync edge while one is pending is an overrun; a cancelled turnaround leaves
    /// the output latch armed; all across the 32-bit wrap.
    #[test]
    fn overruns_cancels_and_the_wrap() {
        let mut p = LatchPlan::new();
        let t0 = u32::MAX - 50;
        p.on_turnaround(Plus, t0.wrapping_add(10_000));
        assert_eq!(
            p.on_sync(t0, t0),
            Some((LatchKind::Output, t0.wrapping_add(OUTPUT_LEAD_TICKS)))
        );
        p.on_sync(t0.wrapping_add(5), t0.wrapping_add(5));
        assert_eq!(p.overruns, 1);
        assert_eq!(
            p.cancel_turnaround(),
            Some((LatchKind::Output, t0.wrapping_add(OUTPUT_LEAD_TICKS)))
        );
        assert_eq!(p.on_fired(), (Some(LatchKind::Output), None));
    }
}
