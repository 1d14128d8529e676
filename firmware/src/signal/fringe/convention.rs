//! How the board's photodiode channels and encoder count relate to psi_H (docs/physics.md
//! pitfall 4).
//!
//! psi_H is defined as in the simulator: channel A ~ cos psi_H, channel B ~ sin psi_H, and the
//! count increases with psi_H. With ideal comparators (A high when cos psi_H > 0, B high when
//! sin psi_H > 0, counted x4 by the encoder timer) `count = floor(psi_H / (pi/2)) + const`. A
//! board that swaps or inverts channels or counts down declares it in [`FringeConvention`]; the
//! orientation is an exact integer swap/negation of the normalised levels, so the levels handed
//! to P1/P2 ([`FringeConvention::orient`]) and the phase agree. A wrong convention shows up as
//! permanent disagreement glitches (count direction) or cannot be seen here at all (a reflected
//! pair of channels together with a reversed count): validate against the simulator's truth, as
//! docs/physics.md says.

use super::levels::NormalisedLevels;

/// How the board's channels and counter relate to psi_H (see the module docs).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FringeConvention {
    /// Photodiode channels A and B are swapped (A ~ sin psi_H, B ~ cos psi_H). Applied first.
    pub swap_channels: bool,
    /// Channel A (after the swap) is inverted: A ~ -cos psi_H.
    pub invert_a: bool,
    /// Channel B (after the swap) is inverted: B ~ -sin psi_H.
    pub invert_b: bool,
    /// The counter counts down when psi_H increases.
    pub count_down: bool,
}

impl FringeConvention {
    /// The simulator's convention: nothing swapped or inverted, counting up.
    pub const STANDARD: Self = Self {
        swap_channels: false,
        invert_a: false,
        invert_b: false,
        count_down: false,
    };

    /// Board levels -> (cos psi_H, sin psi_H): exact integer swap and negation.
    #[inline]
    pub const fn orient(&self, levels: NormalisedLevels) -> NormalisedLevels {
        let (mut c, mut s) = if self.swap_channels {
            (levels.sin_q30, levels.cos_q30)
        } else {
            (levels.cos_q30, levels.sin_q30)
        };
        if self.invert_a {
            c = c.saturating_neg();
        }
        if self.invert_b {
            s = s.saturating_neg();
        }
        NormalisedLevels {
            cos_q30: c,
            sin_q30: s,
        }
    }

    /// Board count -> count increasing with psi_H (wrapping negation).
    #[inline]
    pub const fn orient_count(&self, count: i64) -> i64 {
        if self.count_down {
            count.wrapping_neg()
        } else {
            count
        }
    }
}
