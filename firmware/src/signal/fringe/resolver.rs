//! Total beat phase with sub-pulse resolution: the x4 count fixes the quadrant, the fractional
//! fringe (atan2 of the normalised photodiode levels) the position inside the fringe.
//!
//! # Representation: [`FringePhase`], a 96-bit fixed point
//!
//! `turns: i64` whole fringes plus `fraction` (a [`Phase`], Q32 turns), i.e. psi_H / 2 pi =
//! `turns + fraction / 2^32`. Resolution 2^-32 fringe; range 2^63 fringes (at the
//! 590 kHz peak beat rate of the docs/physics.md set, 5e5 years): nothing is lost over days of
//! running. The difference of two readings, [`FringePhase::delta`], is a [`PhaseDelta`] (Q32
//! fringes in an `i64`, [`crate::units`]), exact for |delta| < 2^31 fringes (one hour at the peak beat rate; a dither cycle is < 10^3 fringes)
//! and saturating beyond.
//!
//! The board's wiring (swapped or inverted channels, a down-counting register) is undone
//! first by its [`FringeConvention`] (`convention.rs`, docs/physics.md pitfall 4).
//!
//! # Resolving the turn
//!
//! With `m = sign * count + quadrant_offset`, the count places psi_H in the quadrant
//! `[m, m + 1) / 4` fringes, centred at `c = (m + 1/2) / 4`. The fractional fringe `phi` (in
//! [0, 1) turn) is exact inside the fringe but ambiguous by whole turns; the reading is the
//! value `T + phi` nearest to `c`. The **disagreement** `d = T + phi - c` lies in
//! [-1/2, 1/2) turn:
//! - |d| <= 1/8 turn: phase and count agree exactly;
//! - comparator offsets, hysteresis or a latch skew move the count's edges away from the
//!   quadrant boundaries of phi by some angle delta: |d| <= 1/8 turn + delta. The reading is
//!   still correct (phi decides) as long as |d| < 1/2 turn;
//! - |d| > 3/8 turn (phi lies more than one whole quadrant outside the count's quadrant) is a
//!   **glitch**: a lost count (illegal transition, counter glitch) or a corrupted level. The
//!   nearest-turn reading is still returned, but flagged and counted; it may be off by a turn.
//!
//! `quadrant_offset` is the register's relation to psi_H (the hardware timer starts at an
//! arbitrary value). It is configured, or learned at the first reading with a good signal
//! (the quadrant containing phi). A first reading between a quadrant boundary of phi and the
//! (offset) count edge learns an offset one quadrant off, so the learned offset follows the
//! mean disagreement ([`FringeResolver::mean_disagreement_q32`], an average over about 256
//! good readings, which estimates the comparator offset delta): when the mean leaves
//! +-1/8 turn the offset moves by one quadrant (readings near the mean keep their value: `m`
//! and `d` change by a quadrant in opposite directions).
//! After that, `|d| <= 1/8 turn + |delta|` for comparator offsets |delta| < 1/8 turn.
//!
//! # Signal lost
//!
//! If the normalised radius is outside the configured bounds the fractional fringe is noise:
//! the reading falls back to the centre of the count's quadrant (error <= 1/8 turn) and is
//! flagged.

use super::convention::FringeConvention;
use super::levels::NormalisedLevels;
use crate::units::{Phase, PhaseDelta, TotalPhase, Q32_PER_FRINGE};

/// Disagreement beyond which a reading is a glitch: 3/8 turn (more than a quadrant outside).
pub const GLITCH_DISAGREEMENT_Q32: u32 = 3 << 29;

/// Settings of the resolver (immutable, `Copy`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FringePhaseConfig {
    /// The board's channel and count wiring.
    pub convention: FringeConvention,
    /// `(count + quadrant_offset) mod 4` is psi_H's quadrant (ideal comparators); `None`:
    /// learn it at the first reading with a good signal.
    pub quadrant_offset: Option<u8>,
    /// Smallest accepted normalised radius^2, Q30 (default 0.25: radius 0.5).
    pub min_radius_sq_q30: u32,
    /// Largest accepted normalised radius^2, Q30 (default 2.25: radius 1.5).
    pub max_radius_sq_q30: u32,
}

impl FringePhaseConfig {
    /// Standard convention, learned quadrant offset, radius in [0.5, 1.5].
    pub const DEFAULT: Self = Self {
        convention: FringeConvention::STANDARD,
        quadrant_offset: None,
        min_radius_sq_q30: 1 << 28,
        max_radius_sq_q30: 9 << 28,
    };
}

impl Default for FringePhaseConfig {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// psi_H / 2 pi = `turns + fraction / 2^32` fringes (96-bit fixed point), ordered by value.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FringePhase {
    /// Whole fringes.
    pub turns: i64,
    /// Position inside the fringe, Q32 turns.
    pub fraction: Phase,
}

impl FringePhase {
    /// The phase at quarter-fringe count `m` plus `offset_q32` (Q32 turns, signed).
    #[inline]
    fn from_quarters(m: i64, offset_q32: i64) -> Self {
        // m = 4 k + q; value = k turns + q/4 + offset.
        let k = m >> 2;
        let within = ((m & 3) << 30) + offset_q32; // in (-2^32, 2^33)
        Self {
            turns: k.wrapping_add(within >> 32),
            fraction: Phase::from_bits(within as u32),
        }
    }

    /// `self - earlier`, saturating at the range of a [`PhaseDelta`] (|delta| >= 2^31
    /// fringes).
    #[inline]
    pub fn delta(&self, earlier: &FringePhase) -> PhaseDelta {
        let d = self.as_q32_i128() - earlier.as_q32_i128();
        PhaseDelta::from_q32(d.clamp(i64::MIN as i128, i64::MAX as i128) as i64)
    }

    /// `self - earlier` in fringes, rounded once to `f64` (exact below 2^21 fringes).
    #[inline]
    pub fn delta_fringes_f64(&self, earlier: &FringePhase) -> f64 {
        let d = self.as_q32_i128() - earlier.as_q32_i128();
        d as f64 * (1.0 / Q32_PER_FRINGE)
    }

    /// The whole value in Q32 fringes (96 significant bits in an `i128`).
    #[inline]
    pub fn as_q32_i128(&self) -> i128 {
        ((self.turns as i128) << 32) + self.fraction.to_bits() as i128
    }

    /// The value as a [`TotalPhase`] (Q32 fringes wrapped to 64 bits): what the cycle
    /// assembler takes differences of.
    #[inline]
    pub fn total(&self) -> TotalPhase {
        TotalPhase::from_q32(self.as_q32_i128() as i64)
    }
}

impl Ord for FringePhase {
    fn cmp(&self, other: &Self) -> core::cmp::Ordering {
        self.as_q32_i128().cmp(&other.as_q32_i128())
    }
}

impl PartialOrd for FringePhase {
    fn partial_cmp(&self, other: &Self) -> Option<core::cmp::Ordering> {
        Some(self.cmp(other))
    }
}

/// One resolved reading.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FringeReading {
    /// The total beat phase: count plus fractional fringe.
    pub phase: FringePhase,
    /// The normalised levels in the psi_H orientation (for P1/P2).
    pub levels: NormalisedLevels,
    /// Disagreement `d` of phase and count, Q32 turns (0 when the signal is lost).
    pub disagreement_q32: i32,
    /// Phi more than a quadrant outside the count's quadrant: see the module docs.
    pub glitch: bool,
    /// Radius out of bounds: the phase is the centre of the count's quadrant.
    pub signal_lost: bool,
}

/// Resolver state: the learned quadrant offset and counters.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FringeResolver {
    /// Learned offset in quarters; not reduced mod 4, so that moving it by one quadrant never
    /// moves the phase by a turn.
    learned_offset: Option<i64>,
    glitches: u32,
    signal_lost: u32,
    /// Average of d, Q32 turns * 2^MEAN_SHIFT.
    mean_disagreement_scaled: i64,
    /// Good readings averaged so far (saturating): sets the averaging weight.
    averaged: u32,
}

/// Time constant of the mean disagreement, in readings: 2^MEAN_SHIFT. The first readings after
/// start or [`FringeResolver::realign`] are averaged with weights 1, 1/2, 1/2, 1/4, ... (the
/// shift grows with log2 of their number), so a wrongly learned offset is corrected within a
/// few readings rather than 2^MEAN_SHIFT.
const MEAN_SHIFT: u32 = 8;

impl FringeResolver {
    /// No offset learned, counters at zero.
    pub const fn new() -> Self {
        Self {
            learned_offset: None,
            glitches: 0,
            signal_lost: 0,
            mean_disagreement_scaled: 0,
            averaged: 0,
        }
    }

    /// Glitch readings since start (saturating).
    pub const fn glitches(&self) -> u32 {
        self.glitches
    }

    /// Signal-lost readings since start (saturating).
    pub const fn signal_lost(&self) -> u32 {
        self.signal_lost
    }

    /// The quadrant offset in use, in quarters (configured, or learned; a learned offset is
    /// only meaningful mod 4, but is kept as an integer so that its moves are continuous).
    pub const fn quadrant_offset(&self, config: &FringePhaseConfig) -> Option<i64> {
        match config.quadrant_offset {
            Some(o) => Some((o & 3) as i64),
            None => self.learned_offset,
        }
    }

    /// Mean disagreement over about the last 256 good readings, Q32 turns (an estimate of the
    /// comparator edges' offset from the quadrant boundaries of phi).
    pub const fn mean_disagreement_q32(&self) -> i32 {
        (self.mean_disagreement_scaled >> MEAN_SHIFT) as i32
    }

    /// Forgets the learned offset (e.g. after a counter resync); the next good reading
    /// learns it again.
    pub fn realign(&mut self) {
        self.learned_offset = None;
        self.mean_disagreement_scaled = 0;
        self.averaged = 0;
    }

    /// Updates the mean disagreement; a learned offset whose mean disagreement leaves
    /// +-1/8 turn is moved by one quadrant towards it (readings with `d` near the mean keep
    /// their value: `m` and `d` change by a quadrant in opposite directions).
    fn track_mean(&mut self, config: &FringePhaseConfig, d: i32) {
        self.averaged = self.averaged.saturating_add(1);
        // log2 of the readings averaged, capped: 0 for the first (mean = d), then 1, 1, 2, ...
        let shift = (31 - self.averaged.leading_zeros()).min(MEAN_SHIFT);
        let old = self.mean_disagreement_scaled;
        // |d| < 2^31, |old| < 2^(31 + MEAN_SHIFT): no overflow.
        let mean = old + ((((d as i64) << MEAN_SHIFT) - old) >> shift);
        self.mean_disagreement_scaled = mean;
        let limit = (Phase::EIGHTH_TURN.to_bits() as i64) << MEAN_SHIFT;
        let quadrant = 1i64 << (30 + MEAN_SHIFT);
        if let (None, Some(o)) = (config.quadrant_offset, self.learned_offset) {
            if mean > limit {
                self.learned_offset = Some(o.wrapping_add(1));
                self.mean_disagreement_scaled = mean - quadrant;
            } else if mean < -limit {
                self.learned_offset = Some(o.wrapping_sub(1));
                self.mean_disagreement_scaled = mean + quadrant;
            }
        }
    }

    /// Resolves one reading: the extended x4 `count` and the normalised levels latched with it.
    pub fn resolve(
        &mut self,
        config: &FringePhaseConfig,
        count: i64,
        board_levels: NormalisedLevels,
    ) -> FringeReading {
        let levels = config.convention.orient(board_levels);
        let n = config.convention.orient_count(count);
        let r2 = levels.radius_sq_q30();
        if r2 < config.min_radius_sq_q30 || r2 > config.max_radius_sq_q30 {
            self.signal_lost = self.signal_lost.saturating_add(1);
            let offset = self.quadrant_offset(config).unwrap_or(0);
            return FringeReading {
                phase: FringePhase::from_quarters(
                    n.wrapping_add(offset),
                    Phase::EIGHTH_TURN.to_bits() as i64,
                ),
                levels,
                disagreement_q32: 0,
                glitch: false,
                signal_lost: true,
            };
        }
        let phi = levels.fractional_fringe();
        let offset = match self.quadrant_offset(config) {
            Some(o) => o,
            None => {
                // The quadrant containing phi; `& 3` is the Euclidean remainder mod 4.
                let o = (phi.quadrant() as i64).wrapping_sub(n) & 3;
                self.learned_offset = Some(o);
                o
            }
        };
        let m = n.wrapping_add(offset);
        let centre = Phase::from_bits(((m & 3) as u32) << 30) + Phase::EIGHTH_TURN;
        let d = (phi - centre).to_signed();
        let glitch = d.unsigned_abs() > GLITCH_DISAGREEMENT_Q32;
        if glitch {
            self.glitches = self.glitches.saturating_add(1);
        } else {
            self.track_mean(config, d);
        }
        FringeReading {
            phase: FringePhase::from_quarters(m, Phase::EIGHTH_TURN.to_bits() as i64 + d as i64),
            levels,
            disagreement_q32: d,
            glitch,
            signal_lost: false,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::levels::LissajousCoefficients;
    use super::*;
    use crate::math::atan2_q32;
    use crate::sample::AdcCode;
    use std::f64::consts::TAU;

    use crate::test_rng::XorShift;

    const Q30: f64 = (1u64 << 30) as f64;

    fn levels(psi: f64) -> NormalisedLevels {
        NormalisedLevels {
            cos_q30: (psi.cos() * Q30).round() as i32,
            sin_q30: (psi.sin() * Q30).round() as i32,
        }
    }

    /// Count of ideal comparators whose edges sit `delta` rad late, plus a register constant.
    fn count(psi: f64, delta: f64, constant: i64) -> i64 {
        ((psi - delta) / (TAU / 4.0)).floor() as i64 + constant
    }

    /// Error of a reading against the truth psi/2pi (mod the learned constant `base`), turns.
    fn error_turns(reading: &FringeReading, psi: f64, base: f64) -> f64 {
        let got = reading.phase.as_q32_i128() as f64 / Q32_PER_FRINGE;
        got - psi / TAU - base
    }

    /// A random walk over +-10^6 fringes with count edges up to 40 deg off: every reading
    /// equals psi/2pi plus one constant to 1e-8 turn (the atan2 bound of 7.5e-9 turn, Q30
    /// rounding of the levels 1.5e-10, f64 rounding of the truth 1e-10), no glitches.
    #[test]
    fn resolves_exactly_with_comparator_offsets() {
        for (i, &delta_deg) in [0.0f64, 25.0, -25.0, 40.0, -40.0].iter().enumerate() {
            let delta = delta_deg.to_radians();
            let cfg = FringePhaseConfig::DEFAULT;
            let mut r = FringeResolver::new();
            let mut rng = XorShift(11 + i as u64);
            let mut psi = 0.3;
            let first = r.resolve(&cfg, count(psi, delta, 12_345), levels(psi));
            let base = first.phase.as_q32_i128() as f64 / Q32_PER_FRINGE - psi / TAU;
            // The base is a whole number of turns when the count edges are ideal.
            for step in 0..100_000 {
                psi += (rng.uniform() - 0.5) * 2e4;
                psi = psi.clamp(-TAU * 1e6, TAU * 1e6);
                let reading = r.resolve(&cfg, count(psi, delta, 12_345), levels(psi));
                assert!(!reading.glitch && !reading.signal_lost);
                let e = error_turns(&reading, psi, base);
                assert!(
                    e.abs() < 1e-8,
                    "{e} step {step} d {} off {:?} {reading:?}",
                    reading.disagreement_q32 as f64 / crate::units::Q32_PER_TURN * 360.0,
                    r.quadrant_offset(&cfg)
                );
                if step > 5000 {
                    // After the learned offset has settled.
                    let bound = (0.125 + delta.abs() / TAU) * Q32_PER_FRINGE + 64.0;
                    assert!(reading.disagreement_q32.unsigned_abs() as f64 <= bound);
                }
            }
            assert_eq!(r.glitches(), 0);
            // The mean disagreement estimates the comparator offset (uniform phi; EMA noise ~1 deg rms: 8 deg).
            let mean = r.mean_disagreement_q32() as f64 / Q32_PER_FRINGE * TAU;
            println!(
                "delta {delta_deg} deg: mean disagreement {:.1} deg",
                mean.to_degrees()
            );
            assert!(
                (mean - delta).abs() < 15f64.to_radians(),
                "{mean} vs {delta}"
            );
        }
    }

    /// Comparator edges 40 deg late and a first reading between phi's quadrant boundary and
    /// the edge: the offset is learned one quadrant off, then corrected within a few readings
    /// (the early average is fast); no glitch at any time, and the value never jumps.
    #[test]
    fn wrongly_learned_offset_is_corrected_quickly() {
        let delta = 40f64.to_radians();
        let cfg = FringePhaseConfig::DEFAULT;
        let mut r = FringeResolver::new();
        let psi0 = 95f64.to_radians();
        let first = r.resolve(&cfg, count(psi0, delta, 0), levels(psi0));
        assert_eq!(r.quadrant_offset(&cfg), Some(1), "learned one quadrant off");
        let mut rng = XorShift(21);
        for k in 0..2000 {
            let psi = psi0 + (rng.uniform() - 0.5) * 1e3;
            let reading = r.resolve(&cfg, count(psi, delta, 0), levels(psi));
            assert!(!reading.glitch, "reading {k}");
            let got = reading.phase.delta_fringes_f64(&first.phase) * TAU;
            assert!((got - (psi - psi0)).abs() < 1e-6, "reading {k}");
            if k == 30 {
                assert_eq!(r.quadrant_offset(&cfg), Some(0), "corrected by now");
            }
        }
        assert_eq!(r.quadrant_offset(&cfg), Some(0));
    }

    /// A count that lost two quarters (an illegal transition) is a glitch.
    #[test]
    fn lost_half_fringe_is_a_glitch() {
        let cfg = FringePhaseConfig {
            quadrant_offset: Some(0),
            ..FringePhaseConfig::DEFAULT
        };
        let mut r = FringeResolver::new();
        let psi = 100.0 * TAU + 0.2;
        let good = r.resolve(&cfg, count(psi, 0.0, 0), levels(psi));
        assert!(!good.glitch);
        assert_eq!(good.phase.turns, 100);
        let bad = r.resolve(&cfg, count(psi, 0.0, 0) + 2, levels(psi));
        assert!(bad.glitch);
        assert_eq!(r.glitches(), 1);
        // One quarter off is within tolerance (a comparator edge late by up to a quadrant).
        let late = r.resolve(&cfg, count(psi, 0.0, 0) - 1, levels(psi));
        assert!(!late.glitch);
        assert_eq!(late.phase, good.phase);
    }

    /// Every board wiring: swapped, inverted channels and a down-counting register, declared
    /// in the convention, give the same phase as the standard board.
    #[test]
    fn conventions_recover_psi_h() {
        let mut rng = XorShift(3);
        for wiring in 0..16u8 {
            let conv = FringeConvention {
                swap_channels: wiring & 1 != 0,
                invert_a: wiring & 2 != 0,
                invert_b: wiring & 4 != 0,
                count_down: wiring & 8 != 0,
            };
            let cfg = FringePhaseConfig {
                convention: conv,
                quadrant_offset: Some(0),
                ..FringePhaseConfig::DEFAULT
            };
            let std_cfg = FringePhaseConfig {
                quadrant_offset: Some(0),
                ..FringePhaseConfig::DEFAULT
            };
            let mut r = FringeResolver::new();
            let mut r_std = FringeResolver::new();
            for _ in 0..1000 {
                let psi = (rng.uniform() - 0.5) * 1e4;
                // What the board sees: undo the orientation.
                let (c, s) = (psi.cos(), psi.sin());
                let (c, s) = (
                    if conv.invert_a { -c } else { c },
                    if conv.invert_b { -s } else { s },
                );
                let (a, b) = if conv.swap_channels { (s, c) } else { (c, s) };
                let board = NormalisedLevels {
                    cos_q30: (a * Q30).round() as i32,
                    sin_q30: (b * Q30).round() as i32,
                };
                let n = count(psi, 0.0, 0);
                let board_count = if conv.count_down { -n } else { n };
                let got = r.resolve(&cfg, board_count, board);
                let want = r_std.resolve(&std_cfg, n, levels(psi));
                assert_eq!(got.phase, want.phase, "wiring {wiring}");
                assert_eq!(got.levels, want.levels);
            }
        }
    }

    #[test]
    fn signal_lost_falls_back_to_the_count() {
        let cfg = FringePhaseConfig {
            quadrant_offset: Some(1),
            ..FringePhaseConfig::DEFAULT
        };
        let mut r = FringeResolver::new();
        let weak = NormalisedLevels {
            cos_q30: 1 << 20,
            sin_q30: 0,
        };
        let reading = r.resolve(&cfg, 4 * 7 + 2, weak);
        assert!(reading.signal_lost);
        // m = 31 quarters -> 7 turns + 3/4 + 1/8.
        assert_eq!(reading.phase.turns, 7);
        assert_eq!(reading.phase.fraction.to_bits(), (3 << 30) + (1 << 29));
        assert_eq!(r.signal_lost(), 1);
    }

    /// Deltas: exact in Q32 fringes, saturating beyond the i64 range; far from zero (days at a
    /// high rate: 2^40 quarters) the resolution is unchanged.
    #[test]
    fn deltas_and_long_runs() {
        let cfg = FringePhaseConfig {
            quadrant_offset: Some(0),
            ..FringePhaseConfig::DEFAULT
        };
        let mut r = FringeResolver::new();
        let big: i64 = 1 << 40;
        let a = r.resolve(&cfg, big, levels(0.1 + TAU / 4.0 * 0.0));
        let b = r.resolve(&cfg, big + 1, levels(TAU / 4.0 + 0.1));
        assert_eq!(a.phase.turns, big / 4);
        let d = b.phase.delta(&a.phase).to_q32();
        assert!((d - (1i64 << 30)).abs() <= 64, "{d}");
        assert!((b.phase.delta_fringes_f64(&a.phase) - 0.25).abs() < 1e-8);
        let far = FringePhase {
            turns: i64::MAX,
            fraction: Phase::ZERO,
        };
        let near = FringePhase {
            turns: i64::MIN,
            fraction: Phase::ZERO,
        };
        assert_eq!(far.delta(&near).to_q32(), i64::MAX);
        assert_eq!(near.delta(&far).to_q32(), i64::MIN);
    }

    /// Random counts and levels (including extremes): never panics, the fraction always equals
    /// the atan2 of the oriented levels when the signal is good.
    #[test]
    fn property_random_inputs_never_panic() {
        let mut rng = XorShift(99);
        for i in 0..200_000 {
            let cfg = FringePhaseConfig {
                convention: FringeConvention {
                    swap_channels: rng.next() & 1 != 0,
                    invert_a: rng.next() & 1 != 0,
                    invert_b: rng.next() & 1 != 0,
                    count_down: rng.next() & 1 != 0,
                },
                quadrant_offset: if i % 3 == 0 {
                    None
                } else {
                    Some(rng.next() as u8)
                },
                min_radius_sq_q30: rng.next() as u32 >> (rng.next() % 32),
                max_radius_sq_q30: rng.next() as u32,
            };
            let mut r = FringeResolver::new();
            let lv = NormalisedLevels {
                cos_q30: rng.next() as i32,
                sin_q30: rng.next() as i32,
            };
            let count = match i % 4 {
                0 => i64::MIN,
                1 => i64::MAX,
                _ => rng.next() as i64,
            };
            let reading = r.resolve(&cfg, count, lv);
            if !reading.signal_lost {
                let o = cfg.convention.orient(lv);
                assert_eq!(reading.phase.fraction, atan2_q32(o.sin_q30, o.cos_q30));
            }
        }
    }

    /// The chain from raw samples: the count of ideal comparators (what the encoder timer
    /// counts), 12-bit codes through nominal coefficients, into the resolver. Tolerance 2e-3
    /// rad: the 12-bit quantisation of the codes (0.5 code on a 2047-code radius = 2.4e-4 rad)
    /// with margin.
    #[test]
    fn chain_from_samples() {
        let mut rng = XorShift(5);
        let code = |x: f64| AdcCode::new((2048.0 + 2047.0 * x).round() as u16).unwrap();
        let mut psi: f64 = 1.0;
        let coeffs = LissajousCoefficients::NOMINAL;
        let cfg = FringePhaseConfig {
            quadrant_offset: Some(0),
            ..FringePhaseConfig::DEFAULT
        };
        let mut resolver = FringeResolver::new();
        let first = resolver.resolve(
            &cfg,
            count(psi, 0.0, 0),
            coeffs.normalise(code(psi.cos()), code(psi.sin())),
        );
        let psi0 = psi;
        for _ in 0..20_000 {
            psi += (rng.uniform() - 0.45) * 1.5;
            let reading = resolver.resolve(
                &cfg,
                count(psi, 0.0, 0),
                coeffs.normalise(code(psi.cos()), code(psi.sin())),
            );
            assert!(!reading.glitch);
            let got = reading.phase.delta_fringes_f64(&first.phase) * TAU;
            assert!((got - (psi - psi0)).abs() < 2e-3, "{got} vs {}", psi - psi0);
        }
    }
}
