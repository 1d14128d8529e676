//! Supervision: the states a status reports, the faults, their limits and detection, the safe
//! reaction and the retry back-off.
//!
//! # Faults and when they are detected
//! Every check runs on a closed half-cycle window (at most 72 samples, 1.8 ms at 280 Hz), so a
//! condition present for a whole window is seen at that window's end: at most two half cycles
//! after it starts (one period), or, for the conditions that must persist
//! ([`FaultLimits::out_of_range_half_cycles`], [`FaultLimits::saturated_half_cycles`]), that
//! many half cycles later. All limits keep detection within 3 dither periods (6 half cycles).
//!
//! | fault | condition (per half-cycle window) | in |
//! |---|---|---|
//! | `PickoffSaturated` | at least [`FaultLimits::rail_samples`] samples at 0 or full scale (pinned, or a clipped sine) | every driven state |
//! | `PickoffLost` | peak-to-peak range at most [`FaultLimits::flat_codes`] (a constant code: a broken pick-off, a dead ADC) | ring-up, locked |
//! | `NoOscillation` | fitted amplitude below [`FaultLimits::lost_amplitude_codes`] while the pick-off is alive; no resonance found by the start-up; a plant gain below the plausible | ring-up, locked, start-up |
//! | `DriveSaturated` | the amplitude loop at the drive limit for more than [`FaultLimits::saturated_half_cycles`] (locked) or [`FaultLimits::ramp_saturated_ticks`] (ring-up) | ring-up, locked |
//! | `AmplitudeOutOfRange` | above [`FaultLimits::max_amplitude_codes`] (at once, any state), or off the setpoint by more than [`FaultLimits::band`] for [`FaultLimits::out_of_range_half_cycles`] (locked), or not locked within [`FaultLimits::acquire_timeout_ticks`] | every driven state |
//!
//! # Safe reaction
//! Drive off at the next tick (the DAC at mid-scale), the state `Fault(kind)`, the fault's
//! counter incremented, every output record (the [`super::DitherEstimate`]s) invalid; after a
//! back-off the start-up begins again (listening first: a dither still ringing is caught
//! without a sweep). The back-off doubles with every fault in a row, from
//! [`FaultLimits::backoff_initial_ticks`] (0.5 s) to [`FaultLimits::backoff_max_ticks`] (32 s),
//! and is reset after [`FaultLimits::stable_ticks`] (10 s) locked.

/// Why the drive was switched off.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FaultKind {
    /// The pick-off shows a constant code (broken pick-off or ADC).
    PickoffLost,
    /// The pick-off reaches an ADC rail (0 or full scale): pinned there, or clipped.
    PickoffSaturated,
    /// No oscillation: none found at start-up, or it vanished (pick-off alive, no sine).
    NoOscillation,
    /// The amplitude loop has been at the drive limit for too long.
    DriveSaturated,
    /// The amplitude is outside its allowed range.
    AmplitudeOutOfRange,
}

impl FaultKind {
    /// Every kind, in counter order.
    pub const ALL: [Self; 5] = [
        Self::PickoffLost,
        Self::PickoffSaturated,
        Self::NoOscillation,
        Self::DriveSaturated,
        Self::AmplitudeOutOfRange,
    ];

    /// The kind's index in [`FaultCounters`].
    pub const fn index(self) -> usize {
        self as usize
    }
}

/// The controller's state as a status reports it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum DitherState {
    /// Disabled: drive off.
    Off,
    /// Finding the resonance and bringing the amplitude to the setpoint.
    Starting,
    /// At resonance and at the setpoint: the dither estimates are valid.
    Locked,
    /// Drive off after a fault; a retry follows after the back-off.
    Fault(FaultKind),
    /// Drive off until a reset: the board's power-up self-test or its clock failed
    /// (`DitherController::inhibit`; the pick-off check inhibits by itself).
    Inhibited,
}

/// The fault limits (immutable; part of the controller's configuration).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FaultLimits {
    /// A window whose peak-to-peak range is at most this is flat (pick-off lost), codes.
    pub flat_codes: u16,
    /// The ADC code counted as the upper rail (and 0 as the lower).
    pub rail_code: u16,
    /// A half cycle with this many samples at a rail is saturated (a sine inside the ADC's
    /// range never touches a rail; 2 ignores a single glitch).
    pub rail_samples: u32,
    /// Below this fitted amplitude (codes) the oscillation is lost.
    pub lost_amplitude_codes: f32,
    /// Above this amplitude (codes) at once: out of range (mechanical safety).
    pub max_amplitude_codes: f32,
    /// Allowed relative deviation from the setpoint while locked.
    pub band: f32,
    /// Half cycles in a row outside the band that make the fault (at the last of them).
    pub out_of_range_half_cycles: u16,
    /// Half cycles in a row at the drive limit, while locked, that are still allowed (the
    /// fault comes with the next one).
    pub saturated_half_cycles: u16,
    /// Time at the drive limit allowed during the ring-up, ticks.
    pub ramp_saturated_ticks: u32,
    /// The ring-up must lock within this, ticks.
    pub acquire_timeout_ticks: u32,
    /// First back-off, ticks.
    pub backoff_initial_ticks: u32,
    /// Largest back-off, ticks.
    pub backoff_max_ticks: u32,
    /// Time locked after which the back-off starts again from the first, ticks.
    pub stable_ticks: u32,
}

impl FaultLimits {
    /// The limits at tick rate `tick_hz` for a pick-off of full scale `rail_code`, a largest
    /// amplitude of `max_amplitude_codes`.
    pub fn new(tick_hz: f32, rail_code: u16, max_amplitude_codes: f32) -> Self {
        let ticks = |s: f32| (s * tick_hz) as u32;
        Self {
            flat_codes: 2,
            rail_code,
            rail_samples: 2,
            lost_amplitude_codes: 8.0,
            max_amplitude_codes,
            band: 0.1,
            out_of_range_half_cycles: 2,
            saturated_half_cycles: 4,
            ramp_saturated_ticks: ticks(3.0),
            acquire_timeout_ticks: ticks(6.0),
            backoff_initial_ticks: ticks(0.5),
            backoff_max_ticks: ticks(32.0),
            stable_ticks: ticks(10.0),
        }
    }
}

/// Faults counted since start, one counter per [`FaultKind`] (saturating).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FaultCounters(pub [u32; 5]);

impl FaultCounters {
    /// One more of `kind`.
    pub fn count(&mut self, kind: FaultKind) {
        if let Some(c) = self.0.get_mut(kind.index()) {
            *c = c.saturating_add(1);
        }
    }

    /// Faults of `kind` so far.
    pub fn of(&self, kind: FaultKind) -> u32 {
        self.0.get(kind.index()).copied().unwrap_or(0)
    }

    /// All faults so far.
    pub fn total(&self) -> u32 {
        self.0.iter().fold(0u32, |a, &c| a.saturating_add(c))
    }
}

/// The retry back-off: doubles with each fault in a row, reset by a stable lock.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Backoff {
    /// Faults in a row (since the last stable lock).
    pub in_a_row: u32,
}

impl Backoff {
    /// A fault: the wait before the retry, ticks.
    pub fn on_fault(&mut self, limits: &FaultLimits) -> u32 {
        let shift = self.in_a_row.min(16);
        self.in_a_row = self.in_a_row.saturating_add(1);
        limits
            .backoff_initial_ticks
            .saturating_mul(1 << shift)
            .min(limits.backoff_max_ticks)
    }

    /// Locked long enough: the next fault waits the first back-off again.
    pub fn on_stable(&mut self) {
        self.in_a_row = 0;
    }

    /// The wait the next fault would get, ticks.
    pub fn next_wait(&self, limits: &FaultLimits) -> u32 {
        let mut copy = *self;
        copy.on_fault(limits)
    }
}

/// A run of consecutive half cycles meeting a condition.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Run(u16);

impl Run {
    /// Feeds one half cycle; true once the condition has held for more than `limit` in a row
    /// (`limit` 0: at the first).
    pub fn exceeds(&mut self, condition: bool, limit: u16) -> bool {
        self.0 = if condition {
            self.0.saturating_add(1)
        } else {
            0
        };
        self.0 > limit
    }

    /// Forgets the run.
    pub fn clear(&mut self) {
        self.0 = 0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn backoff_doubles_caps_and_resets() {
        let l = FaultLimits::new(40_000.0, 4095, 1875.0);
        let mut b = Backoff::default();
        let waits: Vec<u32> = (0..10).map(|_| b.on_fault(&l)).collect();
        assert_eq!(waits[0], 20_000);
        assert_eq!(waits[1], 40_000);
        assert_eq!(waits[5], 640_000);
        assert_eq!(waits[6], 1_280_000); // 32 s, the cap
        assert_eq!(waits[9], 1_280_000);
        assert_eq!(b.next_wait(&l), 1_280_000);
        b.on_stable();
        assert_eq!(b.next_wait(&l), 20_000);
        for _ in 0..100 {
            b.on_fault(&l);
        }
        assert_eq!(b.next_wait(&l), 1_280_000);
    }

    #[test]
    fn counters_and_runs() {
        let mut c = FaultCounters::default();
        c.count(FaultKind::DriveSaturated);
        c.count(FaultKind::DriveSaturated);
        c.count(FaultKind::PickoffLost);
        assert_eq!(c.of(FaultKind::DriveSaturated), 2);
        assert_eq!(c.total(), 3);
        let mut r = Run::default();
        assert!(!r.exceeds(true, 2));
        assert!(!r.exceeds(true, 2));
        assert!(r.exceeds(true, 2));
        assert!(!r.exceeds(false, 2));
        assert!(Run::default().exceeds(true, 0));
    }
}
