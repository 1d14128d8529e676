//! Random-noise dither, the industry's alternative to lock-in compensation: the drive's peak
//! amplitude is multiplied by `1 + depth * r` at every half cycle, r uniform in [-1, 1) from a
//! seeded xorshift32, so the turnaround phases do not repeat from cycle to cycle. The
//! amplitude loop runs on the unmodulated drive and holds the *mean* amplitude; the
//! mechanical amplitude follows the noisy drive through the resonator (a high-Q low-pass: at
//! Q = 1000 a 50 % drive jump moves the amplitude by ~0.1 % per half cycle, enough to move the
//! turnaround phase by ~0.5 rad at 1.9 arcsec per fringe).
//!
//! Deterministic: the same seed gives the same sequence on every target (integer arithmetic
//! only). Depth is in Q16 (65 536 = 100 %); [`MAX_DEPTH_PERCENT`] bounds it.

/// The largest settable depth, percent of the drive amplitude.
pub const MAX_DEPTH_PERCENT: f32 = 50.0;

/// The noise generator and its depth (the state; depth and seed are commands).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct NoiseDither {
    depth_q16: u32,
    state: u32,
    seed: u32,
}

impl Default for NoiseDither {
    fn default() -> Self {
        Self::new(1)
    }
}

impl NoiseDither {
    /// Off (depth 0), seeded with `seed` (0 is replaced by 1: xorshift's state must not be 0).
    pub const fn new(seed: u32) -> Self {
        let seed = if seed == 0 { 1 } else { seed };
        Self {
            depth_q16: 0,
            state: seed,
            seed,
        }
    }

    /// Restarts the sequence from `seed` (0 is replaced by 1), keeping the depth.
    pub fn reseed(&mut self, seed: u32) {
        *self = Self {
            depth_q16: self.depth_q16,
            ..Self::new(seed)
        };
    }

    /// Sets the depth, Q16 fraction of the drive amplitude.
    pub fn set_depth_q16(&mut self, depth_q16: u32) {
        self.depth_q16 = depth_q16;
    }

    /// The depth, Q16 fraction.
    pub fn depth_q16(&self) -> u32 {
        self.depth_q16
    }

    /// The seed of the current sequence.
    pub fn seed(&self) -> u32 {
        self.seed
    }

    /// The next uniform value in [-1, 1) as Q31 (xorshift32, Marsaglia 13/17/5).
    fn next_q31(&mut self) -> i32 {
        let mut x = self.state;
        x ^= x << 13;
        x ^= x >> 17;
        x ^= x << 5;
        self.state = x;
        x as i32
    }

    /// The drive amplitude of the next half cycle (Q16 codes) for the loop's `drive_q16`:
    /// `drive * (1 + depth * r)`. Depth 0 returns the drive unchanged (and draws nothing).
    pub fn apply(&mut self, drive_q16: i32) -> i32 {
        if self.depth_q16 == 0 {
            return drive_q16;
        }
        let r = self.next_q31() as i64;
        let swing = (drive_q16 as i64 * self.depth_q16 as i64) >> 16;
        (drive_q16 as i64 + ((swing * r) >> 31)) as i32
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(seed: u32, n: usize) -> Vec<i32> {
        let mut d = NoiseDither::new(seed);
        d.set_depth_q16(65_536 / 5); // 20 %
        (0..n).map(|_| d.apply(1000 << 16)).collect()
    }

    #[test]
    fn seeded_sequences_repeat_and_differ_by_seed() {
        assert_eq!(run(42, 1000), run(42, 1000));
        assert_ne!(run(42, 1000), run(43, 1000));
        let mut d = NoiseDither::new(42);
        d.set_depth_q16(65_536 / 5);
        let first: Vec<i32> = (0..10).map(|_| d.apply(1000 << 16)).collect();
        d.reseed(42);
        let again: Vec<i32> = (0..10).map(|_| d.apply(1000 << 16)).collect();
        assert_eq!(first, again);
        assert_eq!(NoiseDither::new(0).seed(), 1);
    }

    /// Mean 1000 codes within 0.3 % over 100 000 half cycles (the uniform's standard error is
    /// 0.2 / sqrt(3 * 1e5) = 0.04 %), spread +-20 %, every value inside it.
    #[test]
    fn mean_is_the_loop_drive_and_the_spread_is_the_depth() {
        let v = run(7, 100_000);
        let codes: Vec<f64> = v.iter().map(|&q| q as f64 / 65_536.0).collect();
        let mean = codes.iter().sum::<f64>() / codes.len() as f64;
        assert!((mean - 1000.0).abs() < 3.0, "{mean}");
        let (lo, hi) = codes
            .iter()
            .fold((f64::MAX, f64::MIN), |(lo, hi), &c| (lo.min(c), hi.max(c)));
        assert!(
            lo >= 800.0 && hi < 1200.0 && lo < 801.0 && hi > 1199.0,
            "{lo} {hi}"
        );
        let mut off = NoiseDither::new(7);
        assert_eq!(off.apply(1234), 1234);
    }
}
