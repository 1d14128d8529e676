//! A 64-bit monotonic millisecond clock from 32-bit atomics (the Cortex-M4 has no 64-bit
//! atomics): one writer (the 1 ms SysTick) and readers at lower priority (the main loop).
//!
//! The writer increments the low word and, when it wraps, the high word; a reader reads high,
//! low, high again and retries when the two highs differ (a wrap happened between its reads).
//! Because the writer preempts the reader and runs to completion, a reader never sees a
//! half-done wrap: the retry loop runs at most twice. (This relies on a single core, where the
//! writer preempts readers; it is not a lock-free clock for threads running in parallel.) No critical section, so the
//! tick never waits for a reader. Never wraps (584 million years), so every deadline derived
//! from it (the protocol's unlock and its wrong-key windows, `protocol::access`) compares plainly.

use core::sync::atomic::{AtomicU32, Ordering};

/// Milliseconds since start, 64 bits (see the module docs).
pub struct Millis {
    low: AtomicU32,
    high: AtomicU32,
}

impl Default for Millis {
    fn default() -> Self {
        Self::new()
    }
}

impl Millis {
    /// Zero.
    pub const fn new() -> Self {
        Self::starting_at(0)
    }

    /// Starting at `ms` (tests: just before the 32-bit wrap).
    pub const fn starting_at(ms: u64) -> Self {
        Self {
            low: AtomicU32::new(ms as u32),
            high: AtomicU32::new((ms >> 32) as u32),
        }
    }

    /// One millisecond passed (the single writer only).
    pub fn tick(&self) {
        let low = self.low.load(Ordering::Relaxed).wrapping_add(1);
        self.low.store(low, Ordering::Release);
        if low == 0 {
            let high = self.high.load(Ordering::Relaxed).wrapping_add(1);
            self.high.store(high, Ordering::Release);
        }
    }

    /// Milliseconds since start.
    pub fn now_ms(&self) -> u64 {
        loop {
            let high = self.high.load(Ordering::Acquire);
            let low = self.low.load(Ordering::Acquire);
            if self.high.load(Ordering::Acquire) == high {
                return (high as u64) << 32 | low as u64;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Across the 32-bit wrap (49.7 days) the clock goes on counting: no jump back to 0.
    #[test]
    fn counts_across_the_32_bit_wrap() {
        let start = (1u64 << 32) - 3;
        let clock = Millis::starting_at(start);
        let mut last = clock.now_ms();
        assert_eq!(last, start);
        for _ in 0..10 {
            clock.tick();
            let now = clock.now_ms();
            assert_eq!(now, last + 1);
            last = now;
        }
        assert_eq!(last, (1u64 << 32) + 7);
    }
}
