//! The units of the signal chain, defined once.
//!
//! Phase is counted in fringes: one fringe is one period of the beat signal, 2 pi rad of beat
//! phase psi_H, four x4 counts of the encoder, SF arcsec of rotation. Inside the chain phases
//! are fixed point in **Q32 fringes** (2^32 per fringe): [`Phase`] (`u32`) for a phase within
//! one fringe (so wrapping arithmetic is fringe arithmetic), [`TotalPhase`] and [`PhaseDelta`]
//! (`i64`, 2^31 fringes of range) for totals and for increments, their differences. Radians
//! appear only where the physics needs them (P1/P2, the compensation); deg/h only at the rate
//! output. Wire formats keep the raw Q32 integers and convert where they are built.

/// One turn of a [`Phase`] in Q32 (a fractional fringe, a dither or oscillator cycle, any full
/// turn): 2^32, as `f64` for conversions. Defined once; [`Q32_PER_FRINGE`] is the same turn.
pub const Q32_PER_TURN: f64 = 4_294_967_296.0;
/// [`Q32_PER_TURN`] as `f32` (exact: a power of two), for the f32 paths of the M4F.
pub const Q32_PER_TURN_F32: f32 = Q32_PER_TURN as f32;
/// One fringe (2 pi rad of beat phase) in Q32 fringes: one turn.
pub const Q32_PER_FRINGE: f64 = Q32_PER_TURN;

/// A phase angle in **Q32 turns**: a full turn (2 pi rad; in the chain one fringe) is 2^32, so
/// the wrapping arithmetic of the operators is turn arithmetic; one LSB is 2^-32 turn =
/// 1.46e-9 rad. The fractional fringe (`math::atan2_q32` of the normalised levels) is one.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Phase(u32);

impl Phase {
    /// 0 (along +x).
    pub const ZERO: Self = Self(0);
    /// 1/8 turn: half a quadrant (45 deg).
    pub const EIGHTH_TURN: Self = Self(1 << 29);
    /// 1/4 turn (90 deg, one x4 count).
    pub const QUARTER_TURN: Self = Self(1 << 30);
    /// 1/2 turn (180 deg).
    pub const HALF_TURN: Self = Self(1 << 31);

    /// The phase whose Q32 value (turns * 2^32, modulo 2^32) is `bits`.
    #[inline]
    pub const fn from_bits(bits: u32) -> Self {
        Self(bits)
    }

    /// The Q32 value in [0, 2^32): [0, 1) turn.
    #[inline]
    pub const fn to_bits(self) -> u32 {
        self.0
    }

    /// The same angle as a signed Q32 value in [-2^31, 2^31): [-1/2, 1/2) turn.
    #[inline]
    pub const fn to_signed(self) -> i32 {
        self.0 as i32
    }

    /// The quadrant, 0..=3: the angle's two top bits.
    #[inline]
    pub const fn quadrant(self) -> u32 {
        self.0 >> 30
    }
}

impl core::ops::Add for Phase {
    type Output = Self;
    /// Wrapping: modulo a turn.
    #[inline]
    fn add(self, other: Self) -> Self {
        Self(self.0.wrapping_add(other.0))
    }
}

impl core::ops::Sub for Phase {
    type Output = Self;
    /// Wrapping: modulo a turn ([`Phase::to_signed`] reads it as the signed difference).
    #[inline]
    fn sub(self, other: Self) -> Self {
        Self(self.0.wrapping_sub(other.0))
    }
}

impl core::ops::Neg for Phase {
    type Output = Self;
    /// Wrapping: the angle mirrored about +x.
    #[inline]
    fn neg(self) -> Self {
        Self(self.0.wrapping_neg())
    }
}

/// A total beat phase in Q32 fringes: an `i64` of 2^32 per fringe that wraps at 2^32 fringes,
/// as latched at a turnaround (count plus fractional fringe). Only differences mean anything:
/// `later - earlier` is the increment in Q32 fringes, exact (wrapping) while it is below 2^31
/// fringes (one hour at the 590 kHz peak beat rate; a dither cycle is < 10^3 fringes).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TotalPhase(i64);

impl TotalPhase {
    /// The total phase whose Q32 value (fringes * 2^32, modulo 2^64) is `q32`.
    #[inline]
    pub const fn from_q32(q32: i64) -> Self {
        Self(q32)
    }

    /// The Q32 value (fringes * 2^32), wrapped to `i64`.
    #[inline]
    pub const fn to_q32(self) -> i64 {
        self.0
    }

    /// The 1-2-1 average of three latches with `self` in the middle, `(before + 2 self +
    /// after) / 4`, rounded down to the Q32 step: `self + floor(((before - self) + (after -
    /// self)) / 4)` (wrapping, exact while the neighbours are within 2^61 Q32 of `self`).
    /// Differences of such averages telescope exactly, whatever the rounding.
    #[inline]
    pub const fn smoothed_121(self, before: Self, after: Self) -> Self {
        let spread = before.0.wrapping_sub(self.0) + after.0.wrapping_sub(self.0);
        Self(self.0.wrapping_add(spread >> 2))
    }
}

impl core::ops::Sub for TotalPhase {
    type Output = PhaseDelta;
    /// The increment `self - earlier` (wrapping).
    #[inline]
    fn sub(self, earlier: Self) -> PhaseDelta {
        PhaseDelta(self.0.wrapping_sub(earlier.0))
    }
}

impl core::ops::Add<PhaseDelta> for TotalPhase {
    type Output = Self;
    /// The total phase `delta` later (wrapping).
    #[inline]
    fn add(self, delta: PhaseDelta) -> Self {
        Self(self.0.wrapping_add(delta.0))
    }
}

impl core::ops::Sub<PhaseDelta> for TotalPhase {
    type Output = Self;
    /// The total phase `delta` earlier (wrapping).
    #[inline]
    fn sub(self, delta: PhaseDelta) -> Self {
        Self(self.0.wrapping_sub(delta.0))
    }
}

/// A phase increment in Q32 fringes: an `i64` of 2^32 per fringe, the difference of two
/// [`TotalPhase`]s (a cycle's increment, its lock-in correction, the dither taken out of a
/// latch). Wrapping like the totals it comes from; exact while below 2^31 fringes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PhaseDelta(i64);

impl PhaseDelta {
    /// No change of phase.
    pub const ZERO: Self = Self(0);

    /// The increment whose Q32 value (fringes * 2^32) is `q32`.
    #[inline]
    pub const fn from_q32(q32: i64) -> Self {
        Self(q32)
    }

    /// The Q32 value (fringes * 2^32).
    #[inline]
    pub const fn to_q32(self) -> i64 {
        self.0
    }

    /// The increment in fringes (`q32 / 2^32`, rounded to `f64`).
    #[inline]
    pub fn fringes_f64(self) -> f64 {
        self.0 as f64 / Q32_PER_FRINGE
    }

    /// The increment in rad of beat phase (`q32 * 2 pi / 2^32`, rounded to `f64`).
    #[inline]
    pub fn rad_f64(self) -> f64 {
        self.0 as f64 * core::f64::consts::TAU / Q32_PER_FRINGE
    }
}

impl core::ops::Add for PhaseDelta {
    type Output = Self;
    /// Wrapping.
    #[inline]
    fn add(self, other: Self) -> Self {
        Self(self.0.wrapping_add(other.0))
    }
}

impl core::ops::AddAssign for PhaseDelta {
    /// Wrapping.
    #[inline]
    fn add_assign(&mut self, other: Self) {
        *self = *self + other;
    }
}

impl core::ops::Sub for PhaseDelta {
    type Output = Self;
    /// Wrapping.
    #[inline]
    fn sub(self, other: Self) -> Self {
        Self(self.0.wrapping_sub(other.0))
    }
}

impl core::ops::Neg for PhaseDelta {
    type Output = Self;
    /// Wrapping.
    #[inline]
    fn neg(self) -> Self {
        Self(self.0.wrapping_neg())
    }
}

impl core::iter::Sum for PhaseDelta {
    /// Wrapping: the increments of a chain sum to its end minus its start.
    fn sum<I: Iterator<Item = Self>>(iter: I) -> Self {
        iter.fold(Self::ZERO, |a, b| a + b)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn phase_wraps_by_the_turn() {
        let three_quarters = Phase::HALF_TURN + Phase::QUARTER_TURN;
        assert_eq!(three_quarters.quadrant(), 3);
        assert_eq!(three_quarters + Phase::QUARTER_TURN, Phase::ZERO);
        assert_eq!((Phase::ZERO - Phase::QUARTER_TURN).to_signed(), -(1 << 30));
        assert_eq!(-Phase::QUARTER_TURN, three_quarters);
        assert_eq!(Phase::HALF_TURN.to_signed(), i32::MIN);
        assert_eq!(Phase::from_bits(7).to_bits(), 7);
        assert_eq!(Q32_PER_FRINGE, (1u64 << 32) as f64);
    }

    #[test]
    fn total_phase_differences_wrap() {
        let a = TotalPhase::from_q32(i64::MAX);
        let b = TotalPhase::from_q32(i64::MIN);
        let one = PhaseDelta::from_q32(1);
        assert_eq!(b - a, one);
        assert_eq!(a - b, -one);
        assert_eq!(a + one, b);
        assert_eq!(b - one, a);
        let two_fringes = TotalPhase::from_q32(5 << 32) - TotalPhase::from_q32(3 << 32);
        assert_eq!(two_fringes.to_q32(), 2 << 32);
        assert_eq!(two_fringes.fringes_f64(), 2.0);
        assert_eq!(two_fringes.rad_f64(), 2.0 * core::f64::consts::TAU);
    }

    #[test]
    fn phase_deltas_sum_and_wrap() {
        let max = PhaseDelta::from_q32(i64::MAX);
        let one = PhaseDelta::from_q32(1);
        assert_eq!((max + one).to_q32(), i64::MIN);
        assert_eq!((PhaseDelta::from_q32(i64::MIN) - one), max);
        let mut acc = PhaseDelta::ZERO;
        acc += one;
        assert_eq!(acc, one);
        let steps = [3, -7, 11].map(PhaseDelta::from_q32);
        assert_eq!(steps.into_iter().sum::<PhaseDelta>().to_q32(), 7);
        assert_eq!(
            [max, one].into_iter().sum::<PhaseDelta>().to_q32(),
            i64::MIN
        );
    }

    #[test]
    fn smoothed_121_rounds_down_and_wraps() {
        let m = |a: i64, b: i64, c: i64| {
            TotalPhase::from_q32(b)
                .smoothed_121(TotalPhase::from_q32(a), TotalPhase::from_q32(c))
                .to_q32()
        };
        assert_eq!(m(4, 8, 16), 9);
        assert_eq!(m(16, 8, 4), 9);
        assert_eq!(m(0, 0, 5), 1);
        assert_eq!(m(0, 0, -5), -2);
        assert_eq!(m(-8, 0, -8), -4);
        assert_eq!(m(i64::MAX - 3, i64::MAX, i64::MIN + 3), i64::MAX);
        assert_eq!(m(i64::MAX, i64::MIN + 1, i64::MIN + 6), i64::MIN + 1);
    }
}
