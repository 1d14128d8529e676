//! The driven dither: the resonator's response to the drive segments pushed so far, as a
//! timeline of closed-form segments ([`SegmentResponse`]), known up to a horizon.
//!
//! # The timeline
//!
//! Segment 0 starts at t = 0 from [`ResonatorParams::initial`] with no drive (the amplifier's
//! output at zero); every pushed [`DriveSegment`] starts a new one at its `start_s`, from the
//! state the previous one reaches there (continuous: piezo voltage, angle, rate), with f0 and
//! Q of its start time. While the temperature drifts, a segment is also split at the first
//! multiple of `hold_s` (from its start) where the temperature has changed. Segments are half
//! open, `[start, next start)`; a segment pushed at the same instant as the previous one
//! replaces it (the earlier one has zero length).
//!
//! The drive is known up to [`DrivenDither::known_until_s`]: the last pushed start, or later if
//! the caller says so ([`DrivenDither::extend_until`]). A segment may not start before that
//! time: the phase integrator may already have planned with the drive up to it.
//!
//! # Smoothness, and what the integrator must respect
//!
//! Inside a segment the angle is analytic. At a segment start the drive `y` steps, so the
//! piezo voltage has a kink (`v'` steps) and the angle's third derivative steps: a segment
//! start is a breakpoint of the free phase (see [`crate::phase::free_phase`]), and the phase
//! integrator never expands or steps across it. A temperature step (a split) changes `w0^2`,
//! so the angle's second derivative steps there.
//!
//! # Noise, and the cost of a segment
//!
//! With the angle random walk on, the noise steps snap to the segment starts ([`crate::noise`]):
//! a noise boundary moves to the first start within 1/8 of a nominal period of its nominal
//! time (the half-cycle grid), so a drive that starts its segments near the rate peaks, as a
//! firmware updating at the pick-off's zero crossings does, shares its breakpoints with the
//! noise: one piece boundary per half cycle instead of two. Measured (the bench `phase`, a
//! segment every half cycle ~3 ticks after the rate peaks, per 0.1 gyro-second): 1.92 ms
//! against 1.62 ms for the prescribed sine without noise (+19 %), 2.00 ms against 1.74 ms with
//! noise (+15 %; +31 % before the snap, 2.33 against 1.78 ms). The noise segments
//! then have their actual lengths, so the noise is known only once the drive decides each
//! segment's end: the noise horizon, less than 3/4 of a nominal period before
//! [`DrivenDither::known_until_s`] (inside the lead the gyro asks for). Where a noise step does
//! not snap it can fall anywhere in a dither cycle, inside a near region too (handled
//! exactly, as any breakpoint); a noise step that lands within `|jump| / psi_ddot` of a
//! turnaround (~0.3 ns at ARW 3e-4 deg/sqrt(h)) can carry the rate across zero, and that
//! turnaround is not reported ([`crate::phase::plan`]'s limitation).
//!
//! # History
//!
//! Segments that ended more than [`HISTORY_S`] before the gyro's time are dropped (a segment
//! every half cycle is ~780 per second); asking for the angle before the kept history panics.

use super::drive::{DriveError, DriveSegment};
use super::linear::{Forcing, ResonatorState, SegmentResponse};
use super::resonator::ResonatorParams;
use super::MAX_JET;
use firmware::sample::TurnaroundKind;
use std::cell::Cell;
use std::collections::VecDeque;

/// Drive history kept behind the gyro's time, s.
pub const HISTORY_S: f64 = 10.0;

#[derive(Clone, Copy, Debug, PartialEq)]
struct Resolved {
    start_s: f64,
    forcing: Forcing,
    response: SegmentResponse,
}

/// The driven dither of one gyro: the resonator's timeline.
#[derive(Clone, Debug)]
pub struct DrivenDither {
    params: ResonatorParams,
    nominal_hz: f64,
    /// Beat-phase rad per arcsec of body angle (2 pi / SF).
    scale: f64,
    segments: VecDeque<Resolved>,
    /// Index of `segments[0]` since the start.
    first: u64,
    known_until_s: f64,
    /// The next split of the last segment is at its start + `split_k` holds.
    split_k: u64,
    /// The segment the last lookup found (absolute index): the integrator asks for nearby
    /// times, so [`Self::index_at`] checks it and its successor before searching.
    hint: Cell<u64>,
}

impl DrivenDither {
    /// The resonator of `params` at t = 0, undriven; `nominal_hz` is the gyro's nominal dither
    /// frequency (the planner's grid), `scale` the beat phase per arcsec of body angle.
    pub fn new(params: &ResonatorParams, nominal_hz: f64, scale: f64) -> Self {
        let mut d = Self {
            params: *params,
            nominal_hz,
            scale,
            segments: VecDeque::new(),
            first: 0,
            hint: Cell::new(0),
            known_until_s: 0.0,
            split_k: 1,
        };
        d.push_resolved(0.0, Forcing::ZERO, params.initial);
        d
    }

    /// The parameters.
    pub fn params(&self) -> &ResonatorParams {
        &self.params
    }

    /// The gyro's nominal dither frequency, Hz.
    pub fn nominal_hz(&self) -> f64 {
        self.nominal_hz
    }

    /// The time up to which the drive is known, s.
    pub fn known_until_s(&self) -> f64 {
        self.known_until_s
    }

    fn push_resolved(&mut self, start_s: f64, forcing: Forcing, state: ResonatorState) {
        let response =
            SegmentResponse::new(&self.params.system_at(start_s), &forcing, start_s, &state);
        self.segments.push_back(Resolved {
            start_s,
            forcing,
            response,
        });
        self.split_k = 1;
    }

    fn last(&self) -> &Resolved {
        self.segments
            .back()
            .expect("segment 0 is never dropped alone")
    }

    /// Splits the last segment before `t_s` at the first multiple of `hold_s` after its start
    /// where the temperature differs from the one at its start (and so on from there): f0 and
    /// Q are refreshed at most every `hold_s`, and not at all while the temperature is flat.
    fn split_until(&mut self, t_s: f64) {
        let drift = self.params.temperature;
        if !drift.is_on() {
            return;
        }
        let hold = drift.hold_s;
        loop {
            let last = *self.last();
            let temp0 = drift.profile.at(last.start_s);
            let split = last.start_s + self.split_k as f64 * hold;
            if split >= t_s {
                return;
            }
            if drift.profile.at(split) == temp0 {
                self.split_k += 1;
                continue;
            }
            let state = last.response.state_at(split);
            self.push_resolved(split, last.forcing.later_by(split - last.start_s), state);
        }
    }

    /// Appends `segment`: it starts at or after [`Self::known_until_s`]; the previous segment
    /// holds until then.
    pub fn push(&mut self, segment: DriveSegment) -> Result<(), DriveError> {
        segment.validate()?;
        if segment.start_s < self.known_until_s {
            return Err(DriveError::InThePast {
                start_s: segment.start_s,
                known_until_s: self.known_until_s,
            });
        }
        self.split_until(segment.start_s);
        let state = self.last().response.state_at(segment.start_s);
        let forcing = self.params.forcing(&segment);
        self.push_resolved(segment.start_s, forcing, state);
        self.known_until_s = segment.start_s;
        Ok(())
    }

    /// States that the last segment holds at least until `t_s` (earlier times: no change).
    pub fn extend_until(&mut self, t_s: f64) -> Result<(), DriveError> {
        if !t_s.is_finite() {
            return Err(DriveError::Invalid("the drive horizon must be finite"));
        }
        if t_s > self.known_until_s {
            self.split_until(t_s);
            self.known_until_s = t_s;
        }
        Ok(())
    }

    /// Drops the segments that ended at or before `t_s` (keeps the one containing it).
    pub fn forget_before(&mut self, t_s: f64) {
        while self.segments.len() >= 2 && self.segments[1].start_s <= t_s {
            self.segments.pop_front();
            self.first += 1;
        }
    }

    /// Index of the segment containing `t_s` (counted from the start; before t = 0, segment 0).
    pub fn index_at(&self, t_s: f64) -> u64 {
        let contains = |i: usize| {
            self.segments.get(i).is_some_and(|r| r.start_s <= t_s)
                && self.segments.get(i + 1).is_none_or(|r| r.start_s > t_s)
        };
        let hint = self.hint.get().saturating_sub(self.first) as usize;
        for i in [hint, hint + 1] {
            if contains(i) {
                let index = self.first + i as u64;
                self.hint.set(index);
                return index;
            }
        }
        let i = self.segments.partition_point(|r| r.start_s <= t_s);
        if i == 0 {
            assert!(
                self.first == 0,
                "driven dither: t = {t_s} s lies before the kept history ({HISTORY_S} s)"
            );
            return 0;
        }
        let index = self.first + (i - 1) as u64;
        self.hint.set(index);
        index
    }

    /// The first segment start strictly after `t_s`, if one is known.
    pub fn segment_start_after(&self, t_s: f64) -> Option<f64> {
        let i = self.segments.partition_point(|r| r.start_s <= t_s);
        self.segments.get(i).map(|r| r.start_s)
    }

    /// The first segment start at or after `t_s`, if one is known (every start before
    /// [`Self::known_until_s`] is known: later drive cannot add one there). Panics if the kept
    /// history does not reach back to `t_s` (a dropped segment may have started after it).
    pub fn segment_start_at_or_after(&self, t_s: f64) -> Option<f64> {
        let i = self.segments.partition_point(|r| r.start_s < t_s);
        assert!(
            self.first == 0 || self.segments.front().is_some_and(|r| r.start_s <= t_s),
            "driven dither: t = {t_s} s lies before the kept history ({HISTORY_S} s)"
        );
        self.segments.get(i).map(|r| r.start_s)
    }

    fn response(&self, index: u64) -> &SegmentResponse {
        let i = index
            .checked_sub(self.first)
            .expect("driven dither: segment dropped from the kept history");
        &self.segments[i as usize].response
    }

    /// The dither angle and its derivatives at `t_s` with the formula of segment `index`, in
    /// beat phase (rad, rad/s, ...). `out.len() <= MAX_JET`.
    #[inline]
    pub fn angle_jet(&self, t_s: f64, index: u64, out: &mut [f64]) {
        debug_assert!(out.len() <= MAX_JET);
        self.response(index).angle_jet(t_s, self.scale, out);
    }

    fn check_known(&self, t_s: f64) {
        assert!(
            t_s <= self.known_until_s,
            "driven dither: t = {t_s} s lies beyond the drive known until {} s (push drive \
             segments ahead: keep a lead of two dither periods)",
            self.known_until_s
        );
    }

    /// The state (piezo voltage, angle, rate) at `t_s` (within the known drive).
    pub fn state_at(&self, t_s: f64) -> ResonatorState {
        self.check_known(t_s);
        self.response(self.index_at(t_s)).state_at(t_s)
    }

    /// The body's dither angle at `t_s`, arcsec (within the known drive).
    pub fn angle_arcsec(&self, t_s: f64) -> f64 {
        // The angle alone (the pick-off's 40 kHz samples ask for it): no rate, no voltage.
        self.check_known(t_s);
        let mut angle = [0.0; 1];
        self.response(self.index_at(t_s))
            .angle_jet(t_s, 1.0, &mut angle);
        angle[0]
    }

    /// The amplitude of the ringing (free) part at `t_s`, arcsec: how far the resonator is
    /// from the steady state of its current drive.
    pub fn free_amplitude_arcsec(&self, t_s: f64) -> f64 {
        self.response(self.index_at(t_s)).free_amplitude_arcsec(t_s)
    }

    /// Amplitude of the current drive's steady response at `t_s`, arcsec.
    pub fn forced_amplitude_arcsec(&self, t_s: f64) -> f64 {
        self.response(self.index_at(t_s)).forced_amplitude_arcsec()
    }

    /// The first zero of the dither rate strictly after `t_s` within the known drive, with its
    /// kind (`Plus`: the angle at a minimum): bracketed on a grid of 1/64 of the nominal period,
    /// then bisected to the last bit.
    pub fn pickoff_turnaround_after(&self, t_s: f64) -> Option<(f64, TurnaroundKind)> {
        let rate = |t: f64| {
            let mut j = [0.0; 2];
            self.response(self.index_at(t)).angle_jet(t, 1.0, &mut j);
            j[1]
        };
        let h = 1.0 / (64.0 * self.nominal_hz);
        let (mut a, mut ra) = (t_s, rate(t_s));
        while a < self.known_until_s {
            let b = (a + h).min(self.known_until_s);
            let rb = rate(b);
            if (ra >= 0.0) != (rb >= 0.0) {
                let rising = rb >= 0.0;
                let (mut lo, mut hi) = (a, b);
                loop {
                    let m = 0.5 * (lo + hi);
                    if m <= lo || m >= hi {
                        break;
                    }
                    if (rate(m) >= 0.0) == rising {
                        hi = m;
                    } else {
                        lo = m;
                    }
                }
                let kind = if rising {
                    TurnaroundKind::Plus
                } else {
                    TurnaroundKind::Minus
                };
                return Some((hi, kind));
            }
            (a, ra) = (b, rb);
        }
        None
    }
}
