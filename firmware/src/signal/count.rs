//! Stage 1, the count: extends the hardware x4 encoder register to a 64-bit fringe count, with
//! glitch detection.
//!
//! The encoder timer counts x4 edges (quarter fringes) up and down in a 16- or 32-bit register
//! that wraps. Between two reads the difference `raw - previous_raw`, taken modulo 2^width and
//! interpreted as **signed** in the register width, is the motion; it is exact as long as the
//! true motion between reads stays below half the register range (2^15 counts for a 16-bit
//! timer: at 2.4 M edges/s, read at least every 13 ms; a 32-bit timer allows 14 min).
//!
//! # Glitch policy
//!
//! A step larger than physically possible, `|step| > max_step_counts` (the maximum edge rate
//! times the read interval, with margin, see [`FringeCountConfig::max_step_for`]), is a
//! glitch (a corrupted read, a counter reset, a missed read). Then:
//! - the step is **rejected**: the 64-bit count is held, and the previous raw value stays the
//!   reference, so a single corrupted read costs nothing once the next good read arrives;
//! - [`CountUpdate::Glitch`] is returned and the glitch counter is incremented (saturating);
//! - after [`FringeCountConfig::resync_after`] consecutive glitches the register is taken to
//!   have really jumped (e.g. reset): the raw value becomes the new reference with the count
//!   still held ([`CountUpdate::Resynced`]). The motion during the glitch is lost; the fractional
//!   fringe of [`crate::signal::fringe`] then flags the quadrant disagreement.
//!
//! Never panics: all arithmetic is wrapping on `u32`/`i64`.
//!
//! Sign: the count goes up when psi_H increases if the encoder inputs are wired A -> TI1,
//! B -> TI2 in the timer's default polarity; the count sign is a board convention handled in
//! [`crate::signal::fringe::FringeConvention`].

/// Width of the hardware encoder register.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum CounterWidth {
    /// 16-bit timer (TIM3/TIM4 on the STM32F405): bits 16..32 of the raw value are ignored.
    Bits16,
    /// 32-bit timer (TIM2/TIM5).
    Bits32,
}

impl CounterWidth {
    /// Mask of the register's bits: 0xFFFF or 0xFFFF_FFFF.
    pub const fn mask(self) -> u32 {
        match self {
            CounterWidth::Bits16 => 0xFFFF,
            CounterWidth::Bits32 => u32::MAX,
        }
    }

    /// Largest step magnitude that is unambiguous in this width: 2^(width-1) - 1.
    pub const fn max_unambiguous_step(self) -> u32 {
        match self {
            CounterWidth::Bits16 => (1 << 15) - 1,
            CounterWidth::Bits32 => (1 << 31) - 1,
        }
    }

    /// The register difference `raw - previous` interpreted as signed in this width.
    #[inline]
    pub const fn signed_step(self, previous: u32, raw: u32) -> i32 {
        let d = raw.wrapping_sub(previous);
        match self {
            CounterWidth::Bits16 => d as u16 as i16 as i32,
            CounterWidth::Bits32 => d as i32,
        }
    }

    /// The raw value sign-extended from this width (the initial 64-bit count).
    #[inline]
    const fn sign_extend(self, raw: u32) -> i64 {
        match self {
            CounterWidth::Bits16 => raw as u16 as i16 as i64,
            CounterWidth::Bits32 => raw as i32 as i64,
        }
    }
}

/// Settings of the count extension (immutable, `Copy`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FringeCountConfig {
    /// Register width.
    pub width: CounterWidth,
    /// Largest accepted |step| between two reads, in x4 counts. Values above the width's
    /// [`CounterWidth::max_unambiguous_step`] act as that bound.
    pub max_step_counts: u32,
    /// Consecutive glitches after which the register is resynchronised (0 and 1: at once).
    pub resync_after: u8,
}

impl FringeCountConfig {
    /// The step bound from the physics: `ceil(max_edge_rate_hz * read_interval_ticks /
    /// tick_hz)`, doubled for margin (jitter of the read instant), at least 1, saturating.
    ///
    /// Example: 2.4 M edges/s peak, reads every half dither cycle at 389 Hz (1.285 ms at a 1 MHz tick):
    /// 3084 edges, bound 6168.
    pub const fn max_step_for(
        max_edge_rate_hz: u32,
        read_interval_ticks: u32,
        tick_hz: u32,
    ) -> u32 {
        let tick_hz = if tick_hz == 0 { 1 } else { tick_hz as u64 };
        let edges = (max_edge_rate_hz as u64 * read_interval_ticks as u64).div_ceil(tick_hz);
        let bound = edges.saturating_mul(2);
        if bound == 0 {
            1
        } else if bound > u32::MAX as u64 {
            u32::MAX
        } else {
            bound as u32
        }
    }

    /// Effective bound: configured bound clipped to the unambiguous range.
    #[inline]
    pub const fn effective_max_step(&self) -> u32 {
        let m = self.width.max_unambiguous_step();
        if self.max_step_counts < m {
            self.max_step_counts
        } else {
            m
        }
    }
}

/// What one read did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum CountUpdate {
    /// The first read: the count is the sign-extended register value.
    Initialised,
    /// Accepted step (x4 counts).
    Step(i32),
    /// Rejected step: count and reference held.
    Glitch(i32),
    /// Rejected step after `resync_after` consecutive glitches: count held, reference moved.
    Resynced(i32),
}

/// State of the count extension.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FringeCounter {
    /// `None` until the first read.
    reference_raw: Option<u32>,
    count: i64,
    glitches: u32,
    consecutive_glitches: u8,
    /// The next step may be as large as the register allows (after a pause of the readout).
    jump_expected: bool,
}

impl FringeCounter {
    /// Not yet initialised; the first [`update`](Self::update) sets the count.
    pub const fn new() -> Self {
        Self {
            reference_raw: None,
            count: 0,
            glitches: 0,
            consecutive_glitches: 0,
            jump_expected: false,
        }
    }

    /// The reads stopped for a while (a flash store's stall) while the register counted on:
    /// the next step is accepted up to the register's unambiguous range (32-bit: 2^31 x4
    /// counts, 14 min at the peak edge rate) instead of the one-read bound, so the count runs
    /// on through the pause and no angle is lost.
    pub fn expect_jump(&mut self) {
        self.jump_expected = true;
    }

    /// The extended x4 count (quarter fringes). Until a glitch, `count mod 2^width` equals the
    /// register, so `count mod 4` keeps the register's relation to the comparator quadrant.
    #[inline]
    pub const fn count(&self) -> i64 {
        self.count
    }

    /// Glitches (rejected reads) since construction, saturating.
    #[inline]
    pub const fn glitches(&self) -> u32 {
        self.glitches
    }

    /// One register read.
    pub fn update(&mut self, config: &FringeCountConfig, raw: u32) -> CountUpdate {
        let width = config.width;
        let Some(previous) = self.reference_raw else {
            self.reference_raw = Some(raw);
            self.count = width.sign_extend(raw);
            return CountUpdate::Initialised;
        };
        let step = width.signed_step(previous, raw);
        let bound = if core::mem::take(&mut self.jump_expected) {
            width.max_unambiguous_step()
        } else {
            config.effective_max_step()
        };
        if step.unsigned_abs() <= bound {
            self.reference_raw = Some(raw);
            self.count = self.count.wrapping_add(step as i64);
            self.consecutive_glitches = 0;
            return CountUpdate::Step(step);
        }
        self.glitches = self.glitches.saturating_add(1);
        self.consecutive_glitches = self.consecutive_glitches.saturating_add(1);
        if self.consecutive_glitches >= config.resync_after {
            self.reference_raw = Some(raw);
            self.consecutive_glitches = 0;
            CountUpdate::Resynced(step)
        } else {
            CountUpdate::Glitch(step)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::test_rng::XorShift;

    fn config(width: CounterWidth, max_step: u32) -> FringeCountConfig {
        FringeCountConfig {
            width,
            max_step_counts: max_step,
            resync_after: 3,
        }
    }

    /// Register value of a 64-bit true count in the given width.
    fn register(width: CounterWidth, count: i64) -> u32 {
        match width {
            CounterWidth::Bits16 => count as u16 as u32 | 0xABCD_0000, // junk upper half
            CounterWidth::Bits32 => count as u32,
        }
    }

    /// Random walks with steps up to the bound across many wraps: exact (integer) agreement.
    #[test]
    fn extends_across_wraps_exactly() {
        for width in [CounterWidth::Bits16, CounterWidth::Bits32] {
            let bound = match width {
                CounterWidth::Bits16 => 30_000,
                CounterWidth::Bits32 => 2_000_000_000,
            };
            let cfg = config(width, bound);
            let mut rng = XorShift(42);
            let mut truth: i64 = -5;
            let mut c = FringeCounter::new();
            assert_eq!(
                c.update(&cfg, register(width, truth)),
                CountUpdate::Initialised
            );
            assert_eq!(c.count(), truth);
            for _ in 0..200_000 {
                let step = (rng.next() % (2 * bound as u64 + 1)) as i64 - bound as i64;
                truth += step;
                assert_eq!(
                    c.update(&cfg, register(width, truth)),
                    CountUpdate::Step(step as i32)
                );
                assert_eq!(c.count(), truth);
            }
            assert_eq!(c.glitches(), 0);
        }
    }

    #[test]
    fn half_range_steps_at_the_edge() {
        let cfg = config(CounterWidth::Bits16, u32::MAX);
        let mut c = FringeCounter::new();
        c.update(&cfg, 0);
        assert_eq!(c.update(&cfg, 32_767), CountUpdate::Step(32_767));
        // Exactly half the range is ambiguous: rejected, not guessed.
        assert!(matches!(
            c.update(&cfg, 32_767 + 32_768),
            CountUpdate::Glitch(_)
        ));
        assert_eq!(c.count(), 32_767);
    }

    /// A single corrupted read is rejected and costs nothing; a real jump resyncs after
    /// `resync_after` reads with the count held.
    #[test]
    fn glitch_policy() {
        let cfg = config(CounterWidth::Bits32, 100);
        let mut c = FringeCounter::new();
        c.update(&cfg, 1000);
        assert_eq!(c.update(&cfg, 1050), CountUpdate::Step(50));
        assert_eq!(
            c.update(&cfg, 0xDEAD_BEEF),
            CountUpdate::Glitch(0xDEAD_BEEFu32.wrapping_sub(1050) as i32)
        );
        assert_eq!(c.count(), 1050);
        assert_eq!(c.update(&cfg, 1100), CountUpdate::Step(50));
        assert_eq!(c.count(), 1100);
        assert_eq!(c.glitches(), 1);
        // Counter reset to 0: three rejected reads, then the new reference.
        assert!(matches!(c.update(&cfg, 0), CountUpdate::Glitch(_)));
        assert!(matches!(c.update(&cfg, 10), CountUpdate::Glitch(_)));
        assert!(matches!(c.update(&cfg, 20), CountUpdate::Resynced(_)));
        assert_eq!(c.count(), 1100);
        assert_eq!(c.update(&cfg, 30), CountUpdate::Step(10));
        assert_eq!(c.count(), 1110);
        assert_eq!(c.glitches(), 4);
    }

    #[test]
    fn step_bound_from_rate() {
        // 2.4 M edges/s, 1.285 ms at a 1 MHz tick: 3084 edges, doubled.
        assert_eq!(
            FringeCountConfig::max_step_for(2_400_000, 1285, 1_000_000),
            6168
        );
        assert_eq!(FringeCountConfig::max_step_for(0, 0, 0), 1);
        assert_eq!(
            FringeCountConfig::max_step_for(u32::MAX, u32::MAX, 1),
            u32::MAX
        );
    }

    /// Random configurations and raw values: never panics, count moves only by accepted steps.
    #[test]
    fn property_random_inputs_never_panic() {
        let mut rng = XorShift(7);
        for _ in 0..2000 {
            let cfg = FringeCountConfig {
                width: if rng.next() & 1 == 0 {
                    CounterWidth::Bits16
                } else {
                    CounterWidth::Bits32
                },
                max_step_counts: rng.next() as u32 >> (rng.next() % 32),
                resync_after: (rng.next() % 5) as u8,
            };
            let mut c = FringeCounter::new();
            for _ in 0..200 {
                let before = c.count();
                match c.update(&cfg, rng.next() as u32) {
                    CountUpdate::Step(s) => assert_eq!(c.count(), before + s as i64),
                    CountUpdate::Initialised => {}
                    CountUpdate::Glitch(_) | CountUpdate::Resynced(_) => {
                        assert_eq!(c.count(), before)
                    }
                }
            }
        }
    }

    /// After a pause one large step is taken in full (the register counted on meanwhile), and
    /// only one: the bound applies again to the next read.
    #[test]
    fn a_pause_accepts_one_large_step() {
        let cfg = config(CounterWidth::Bits32, 6_000);
        let mut c = FringeCounter::new();
        c.update(&cfg, 1_000);
        assert_eq!(c.update(&cfg, 101_000), CountUpdate::Glitch(100_000));
        let mut c = FringeCounter::new();
        c.update(&cfg, 1_000);
        c.expect_jump();
        assert_eq!(c.update(&cfg, 101_000), CountUpdate::Step(100_000));
        assert_eq!(c.count(), 101_000);
        assert_eq!(c.update(&cfg, 201_000), CountUpdate::Glitch(100_000));
    }
}
