//! Cycle assembly: the readings at alternating turnarounds become one record per dither cycle.
//!
//! # The increment: between smoothed "-" turnarounds, not between "+" turnarounds
//!
//! A dither cycle closes at every "+" turnaround. Its increment is not the difference of the
//! total phases latched at two "+" turnarounds, because those hold the dither angle there,
//! -A(t), and a dither whose amplitude wanders (every drive leaves some: docs/physics.md
//! pitfall 8) puts A(t_start) - A(t_end) into it: 0.1 % of wander at 0.1-2 Hz is as large as
//! the lock-in error the calibration fits. The increment runs instead between 1-2-1 averages
//! centred on consecutive "-" turnarounds, x_j = (psi_{j-1} + 2 psi_j + psi_{j+1}) / 4: the
//! dither enters x_j as minus a quarter of the amplitude's second difference, so a linear and
//! a quadratic amplitude change both cancel, and what a drive's steps of slope leave is a
//! sixth of what a "+"-to-"+" difference keeps of them. The photodiode noise of the increment
//! is 0.625 of a latch's variance (the middle "+" cancels), against 2 for "+" to "+"
//! (docs/physics.md section 8, the derivation and the measurements).
//!
//! The latch sits in the middle of a traversal of the lock-in zone, so the phase latched at a
//! turnaround holds half of that traversal's error (exactly half in the parabolic
//! approximation: the error integral is symmetric about the turnaround). The increment from
//! x_j to x_{j+2} therefore holds the traversals j-1 .. j+3 with the weights 1/8, 1/2, 3/4,
//! 1/2, 1/8, and P1/P2 are formed with the same weights (pitfall 5, the latch split). Each
//! traversal is in up to three consecutive cycles with weights that add up to one, so the
//! corrections of a run of cycles sum to each traversal's error once.
//!
//! k = sqrt(2 pi / |psi_ddot|) comes from the measured dither, not a constant: the amplitude is a
//! quarter of the sum of the last two half-cycle excursions (the input rate adds to one and takes
//! from the other, so it cancels), the half period is half the time between the turnarounds two
//! apart. It is causal (from the half-cycles before the turnaround), which the slowly changing
//! amplitude of a high-Q dither resonator allows.
//!
//! A reading out of sequence (two turnarounds of one kind in a row, or a half period far from
//! the dither's) means a turnaround was missed or a spurious one seen; a paused readout (a flash
//! store's stall, [`CycleAssembler::gap`]) means the same for every turnaround of the pause.
//! Assembly restarts, but no angle is lost: the next cycle starts where the last closed one
//! ended (its midpoint phase and its timestamp), so its increment and duration span the gap,
//! and it carries [`CycleFlags::TURNAROUND_MISSED`]. Its P1/P2 hold only the dither cycle after
//! the gap (the lock-in error during the gap was not observed). This needs a count that runs on
//! through the gap (`crate::signal::count`: the encoder counts in hardware).
//!
//! The assembler does not compensate: a closed [`CycleRecord`] leaves with its output increment
//! equal to the raw one and a zero correction, and the compensation stage
//! (`crate::signal::compensation`, called by `crate::readout`) subtracts a P1 + b P2 from cycles
//! whose flags allow it ([`CycleFlags::compensable`]).

use super::terms::{
    sine_dither_accel_rad_per_s2, traversal_terms, traversal_time_s, LevelPair, LockinTerms,
};
use crate::sample::TurnaroundKind;
use crate::units::{PhaseDelta, TotalPhase, Q32_PER_FRINGE};

/// Flags raised during a cycle (bit set; OR-ed over an averaging window).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CycleFlags(pub u8);

crate::flags::flag_set_ops!(CycleFlags);

impl CycleFlags {
    /// Photodiode amplitude too small to normalise (fractional fringe unavailable).
    pub const SIGNAL_LOST: Self = Self(1 << 0);
    /// The encoder count jumped by more than physically possible, or disagreed with the levels.
    pub const COUNTER_GLITCH: Self = Self(1 << 1);
    /// A turnaround was not seen when expected (the cycle spans more than one dither period).
    pub const TURNAROUND_MISSED: Self = Self(1 << 2);
    /// No compensation time constant could be formed (no dither, or an implausible one).
    pub const DITHER_INVALID: Self = Self(1 << 3);
    /// The dither drive was not locked at a turnaround of the cycle (starting, off, or in a
    /// fault: `crate::dither`): the dither is not what the board holds it to, so the cycle's
    /// output is invalid. Its P1/P2 are still measured (compensable as far as they go).
    pub const DRIVE_UNLOCKED: Self = Self(1 << 4);

    /// Every flag with its name, in bit order: the stream's flag table (docs/protocol.md,
    /// checked against this list by `hal-sim/tests/protocol_doc.rs`).
    pub const NAMED: [(&'static str, Self); 5] = [
        ("SIGNAL_LOST", Self::SIGNAL_LOST),
        ("COUNTER_GLITCH", Self::COUNTER_GLITCH),
        ("TURNAROUND_MISSED", Self::TURNAROUND_MISSED),
        ("DITHER_INVALID", Self::DITHER_INVALID),
        ("DRIVE_UNLOCKED", Self::DRIVE_UNLOCKED),
    ];

    /// The cycle's P1/P2 can be trusted for compensation: the levels were seen at every
    /// turnaround and k was measured (neither [`Self::SIGNAL_LOST`] nor
    /// [`Self::DITHER_INVALID`]). A counter glitch or a missed turnaround leaves P1/P2 valid.
    pub const fn compensable(self) -> bool {
        !self.contains(Self::SIGNAL_LOST) && !self.contains(Self::DITHER_INVALID)
    }
}

/// One dither cycle's output.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CycleOutput {
    /// Beat-phase increment over the cycle: compensated by the compensation stage (the raw
    /// increment as the assembler hands it over).
    pub increment: PhaseDelta,
    /// The lock-in correction subtracted from it (zero with compensation off).
    pub correction: PhaseDelta,
    /// Cycle duration in capture-timer ticks.
    pub duration_ticks: u32,
    /// What went wrong during the cycle (the union of its turnarounds' flags).
    pub flags: CycleFlags,
}

/// What the turnaround front end hands over for one turnaround.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TurnaroundReading {
    /// The turnaround's kind (the assembler checks that kinds alternate).
    pub kind: TurnaroundKind,
    /// Total beat phase at the turnaround (count plus fractional fringe): its differences are
    /// the increments.
    pub phase: TotalPhase,
    /// Normalised photodiode levels; `None` when the signal is lost.
    pub levels: Option<LevelPair>,
    /// Capture-timer value at the latch (wrapping).
    pub timestamp_ticks: u32,
    /// Problems the front end saw (counter glitch, signal lost).
    pub flags: CycleFlags,
}

/// Settings of the assembly (immutable).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CycleConfig {
    /// Capture-timer frequency, Hz.
    pub timer_hz: f32,
    /// Accepted range of one half period, ticks: outside it a turnaround counts as missed or
    /// spurious. Wide, because an input rate splits the dither period unequally: the
    /// turnarounds are where `input + dither rate` crosses zero, so the halves are
    /// `T/2 (1 +- (2/pi) asin(input / peak dither rate))`: 0.79 and 1.21 of nominal at
    /// 100 deg/s with the docs/physics.md set (peak 305 deg/s).
    pub min_half_period_ticks: u32,
    /// Upper end of the accepted half-period range, ticks.
    pub max_half_period_ticks: u32,
    /// Accepted range of a whole period (two consecutive halves), ticks: the input rate moves
    /// the turnarounds but not the period, so this is what holds the dither frequency.
    pub min_period_ticks: u32,
    /// Upper end of the accepted period range, ticks.
    pub max_period_ticks: u32,
}

impl CycleConfig {
    /// How unequal the two halves of a period may be: each within `1 +- HALF_SPLIT` of half
    /// the nominal period, i.e. inputs up to `sin(0.9 pi / 2)` = 0.99 of the peak dither rate.
    pub const HALF_SPLIT: f32 = 0.9;

    /// Periods within +-`tolerance` (relative) of the nominal dither frequency's, halves
    /// within [`Self::HALF_SPLIT`] of half of it.
    pub fn for_dither(timer_hz: f32, dither_hz: f32, tolerance: f32) -> Self {
        let period = timer_hz / dither_hz;
        let half = 0.5 * period;
        Self {
            timer_hz,
            min_half_period_ticks: (half * (1.0 - Self::HALF_SPLIT)) as u32,
            max_half_period_ticks: (half * (1.0 + Self::HALF_SPLIT)) as u32,
            min_period_ticks: (period * (1.0 - tolerance)) as u32,
            max_period_ticks: (period * (1.0 + tolerance)) as u32,
        }
    }
}

/// One dither cycle, everything the output, the calibration and the stream need.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CycleRecord {
    /// The increment, its correction (none until the compensation stage), duration and flags.
    pub output: CycleOutput,
    /// Measured increment before compensation.
    pub raw_increment: PhaseDelta,
    /// P1 and P2 of the cycle (latch split: 1/8, 1/2, 3/4, 1/2, 1/8 of its five traversals).
    pub terms: LockinTerms,
    /// Total phase at the cycle's end: the 1-2-1 average of the phases latched at the "-"
    /// turnaround before its closing "+" and at the "+" turnarounds on either side of it. The
    /// raw increments are the differences of these.
    pub end_phase: TotalPhase,
    /// Measured dither amplitude (beat phase, rad) and frequency (Hz) at the closing turnaround.
    pub dither_amplitude_rad: f32,
    /// Measured dither frequency at the closing turnaround, Hz.
    pub dither_hz: f32,
}

impl CycleRecord {
    /// The raw increment in rad of beat phase.
    pub fn raw_increment_rad(&self) -> f64 {
        self.raw_increment.rad_f64()
    }
    /// Cycle duration in seconds.
    pub fn duration_s(&self, config: &CycleConfig) -> f64 {
        self.output.duration_ticks as f64 / config.timer_hz as f64
    }
}

/// A turnaround remembered for the excursion and the sequence checks.
#[derive(Clone, Copy, Debug)]
struct Seen {
    kind: TurnaroundKind,
    phase: TotalPhase,
    timestamp_ticks: u32,
}

/// A turnaround's phase with its traversal's share of (P1, P2) and its flags: what the cycles
/// that hold the traversal need of it.
#[derive(Clone, Copy, Debug)]
struct Share {
    phase: TotalPhase,
    terms: LockinTerms,
    flags: CycleFlags,
}

/// The open cycle: its starting smoothed phase and the shares gathered so far.
#[derive(Clone, Copy, Debug)]
struct OpenCycle {
    start_phase: TotalPhase,
    start_ticks: u32,
    terms: LockinTerms,
    have_minus: bool,
    flags: CycleFlags,
}

/// The weights of a cycle's five traversals (docs/physics.md section 8), in order: the "+"
/// before its starting "-", the starting "-", the "+" at which it opens, the "-" in the
/// middle, the closing "+".
const WEIGHTS: [f32; 5] = [0.125, 0.5, 0.75, 0.5, 0.125];

/// State of the assembly.
#[derive(Clone, Debug, Default)]
pub struct CycleAssembler {
    previous: Option<Seen>,
    before_previous: Option<Seen>,
    /// The last "+" turnaround before `last_minus`, and the last "-" in sequence: with the
    /// next "+" they give the smoothed phase that ends one cycle and starts the next.
    plus_before: Option<Share>,
    last_minus: Option<Share>,
    open: Option<OpenCycle>,
    pending_flags: CycleFlags,
    dither_amplitude_rad: f32,
    dither_hz: f32,
    /// Smoothed phase and timestamp at the last closed cycle's end.
    last_end: Option<(TotalPhase, u32)>,
    /// Set by a restart: where the next opened cycle starts (the last closed end).
    bridge: Option<(TotalPhase, u32)>,
}

impl CycleAssembler {
    /// No turnaround seen yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// The readout was paused (turnarounds missed, the count ran on): restarts the assembly
    /// like a reading out of sequence; the next cycle spans the gap from the last closed end.
    pub fn gap(&mut self) {
        self.before_previous = None;
        self.previous = None;
        self.plus_before = None;
        self.last_minus = None;
        self.open = None;
        self.pending_flags = CycleFlags::TURNAROUND_MISSED;
        self.bridge = self.last_end;
    }

    /// Measured dither amplitude, beat-phase rad (0 until two half-cycles have been seen).
    pub fn dither_amplitude_rad(&self) -> f32 {
        self.dither_amplitude_rad
    }

    /// Measured dither frequency, Hz (0 until two half-cycles have been seen).
    pub fn dither_hz(&self) -> f32 {
        self.dither_hz
    }

    /// Takes one turnaround; returns the cycle it closes, if any.
    pub fn on_turnaround(
        &mut self,
        config: &CycleConfig,
        reading: TurnaroundReading,
    ) -> Option<CycleRecord> {
        if !self.in_sequence(config, &reading) {
            self.restart(reading);
            return None;
        }
        let k_s = self.time_constant_s(config, &reading);
        self.before_previous = self.previous;
        self.previous = Some(Seen {
            kind: reading.kind,
            phase: reading.phase,
            timestamp_ticks: reading.timestamp_ticks,
        });
        let mut flags = reading.flags;
        let share = match (reading.levels, k_s) {
            (Some(levels), Some(k)) => traversal_terms(reading.kind, levels, k),
            (None, _) => {
                flags = flags.union(CycleFlags::SIGNAL_LOST);
                LockinTerms::default()
            }
            (_, None) => {
                flags = flags.union(CycleFlags::DITHER_INVALID);
                LockinTerms::default()
            }
        };
        let this = Share {
            phase: reading.phase,
            terms: share,
            flags,
        };
        match reading.kind {
            TurnaroundKind::Minus => {
                if let Some(open) = self.open.as_mut() {
                    open.terms = open.terms + share.scaled(WEIGHTS[3]);
                    open.have_minus = true;
                    open.flags = open.flags.union(flags);
                }
                self.last_minus = Some(this);
                None
            }
            TurnaroundKind::Plus => {
                let closed = self.close_and_open(this, reading.timestamp_ticks);
                self.plus_before = Some(this);
                self.last_minus = None;
                closed
            }
        }
    }

    /// At a "+" turnaround: the smoothed phase of the "-" before it ends the open cycle and
    /// starts the next (when the "+" before that "-" was seen too).
    fn close_and_open(&mut self, plus: Share, ticks: u32) -> Option<CycleRecord> {
        let (Some(before), Some(minus)) = (self.plus_before, self.last_minus) else {
            return None;
        };
        let smoothed = minus.phase.smoothed_121(before.phase, plus.phase);
        let closed = self
            .open
            .take()
            .and_then(|open| self.close(open, plus, smoothed, ticks));
        // After a gap the cycle starts at the last closed end: no angle is dropped.
        let (start_phase, start_ticks) = self.bridge.take().unwrap_or((smoothed, ticks));
        self.open = Some(OpenCycle {
            start_phase,
            start_ticks,
            terms: before.terms.scaled(WEIGHTS[0])
                + minus.terms.scaled(WEIGHTS[1])
                + plus.terms.scaled(WEIGHTS[2]),
            have_minus: false,
            flags: before
                .flags
                .union(minus.flags)
                .union(plus.flags)
                .union(self.pending_flags),
        });
        self.pending_flags = CycleFlags::empty();
        closed
    }

    fn close(
        &mut self,
        open: OpenCycle,
        plus: Share,
        end_phase: TotalPhase,
        end_ticks: u32,
    ) -> Option<CycleRecord> {
        if !open.have_minus {
            return None;
        }
        let terms = open.terms + plus.terms.scaled(WEIGHTS[4]);
        let flags = open.flags.union(plus.flags);
        let raw_increment = end_phase - open.start_phase;
        self.last_end = Some((end_phase, end_ticks));
        Some(CycleRecord {
            output: CycleOutput {
                // Uncompensated: the compensation stage subtracts its correction.
                increment: raw_increment,
                correction: PhaseDelta::ZERO,
                duration_ticks: end_ticks.wrapping_sub(open.start_ticks),
                flags,
            },
            raw_increment,
            terms,
            end_phase,
            dither_amplitude_rad: self.dither_amplitude_rad,
            dither_hz: self.dither_hz,
        })
    }

    /// Kinds must alternate, the half period must be plausible and the period (the two halves
    /// up to this turnaround) close to the dither's. (A half-period window alone refused every
    /// cycle above ~90 deg/s of input: the halves split unequally, see [`CycleConfig`].)
    fn in_sequence(&self, config: &CycleConfig, reading: &TurnaroundReading) -> bool {
        let Some(previous) = self.previous else {
            return true;
        };
        let half = reading
            .timestamp_ticks
            .wrapping_sub(previous.timestamp_ticks);
        let period_ok = self.before_previous.is_none_or(|b| {
            let period = reading.timestamp_ticks.wrapping_sub(b.timestamp_ticks);
            (config.min_period_ticks..=config.max_period_ticks).contains(&period)
        });
        previous.kind != reading.kind
            && (config.min_half_period_ticks..=config.max_half_period_ticks).contains(&half)
            && period_ok
    }

    /// Starts over from `reading`, which can still be the first turnaround of the next
    /// cycle's smoothed phase (its share unmeasured: that cycle is flagged
    /// [`CycleFlags::DITHER_INVALID`]).
    fn restart(&mut self, reading: TurnaroundReading) {
        self.before_previous = None;
        self.previous = Some(Seen {
            kind: reading.kind,
            phase: reading.phase,
            timestamp_ticks: reading.timestamp_ticks,
        });
        let unmeasured = Share {
            phase: reading.phase,
            terms: LockinTerms::default(),
            flags: reading.flags.union(CycleFlags::DITHER_INVALID),
        };
        (self.plus_before, self.last_minus) = match reading.kind {
            TurnaroundKind::Plus => (Some(unmeasured), None),
            TurnaroundKind::Minus => (None, Some(unmeasured)),
        };
        self.open = None;
        self.pending_flags = CycleFlags::TURNAROUND_MISSED;
        self.bridge = self.last_end;
    }

    /// k of the traversal at `reading`, from the two half-cycles before it.
    fn time_constant_s(
        &mut self,
        config: &CycleConfig,
        reading: &TurnaroundReading,
    ) -> Option<f32> {
        let (previous, before) = (self.previous?, self.before_previous?);
        let excursion_q32 = (reading.phase - previous.phase).to_q32().unsigned_abs()
            + (previous.phase - before.phase).to_q32().unsigned_abs();
        // Sum of two half-cycle excursions = 4 x amplitude.
        let amplitude_rad =
            (excursion_q32 as f64 / Q32_PER_FRINGE * core::f64::consts::TAU / 4.0) as f32;
        let half_period_s = reading.timestamp_ticks.wrapping_sub(before.timestamp_ticks) as f32
            / (2.0 * config.timer_hz);
        self.dither_amplitude_rad = amplitude_rad;
        self.dither_hz = 0.5 / half_period_s;
        traversal_time_s(sine_dither_accel_rad_per_s2(
            2.0 * amplitude_rad,
            half_period_s,
        )?)
    }
}

#[cfg(test)]
pub(crate) mod synthetic;
#[cfg(test)]
mod tests;
