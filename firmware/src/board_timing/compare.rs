//! The next compare of a periodic timer event: the board's internal output rate (TIM2 CC2, one
//! compare every output period) after its handler ran late, by microseconds or by a whole flash
//! store.
//!
//! A compare must always be set to an instant still ahead of the counter: one already passed
//! matches only after the 32-bit counter has come round again (51 s at 84 MHz). A store masks
//! TIM2's interrupt for milliseconds (seconds with an erase), so the handler that finally runs
//! sees a compare that fired long ago; adding one period to it would land in the past. The next
//! compare is therefore the first instant of the event's grid (`fired + n * period`, n >= 1)
//! that lies at least a lead after the counter now, and the grid instants passed over on the
//! way are counted: they are the missed periods, which the output record after the gap spans
//! (its `period_ticks` shows it) and the board counts.
//!
//! Keeping to the grid (rather than restarting it from `now`) keeps the output's phase: the
//! output latches after a pause fall where they would have fallen without it.
//!
//! All times are 32-bit counter values (wrapping); the late handler's delay must be below one
//! wrap (51 s), which every masked interval on the board is by far (a store: at most 2.1 s).

/// Where the next compare of a periodic event goes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PeriodCompare {
    /// The compare instant, counter ticks (wrapping).
    pub at_ticks: u32,
    /// Grid instants between the fired compare and this one that had no compare of their own.
    pub missed_periods: u32,
}

/// The next compare after the compare at `fired_ticks` matched, seen at `now_ticks`: the first
/// `fired + n * period` (n >= 1) at least `min_lead_ticks` after `now`; `missed_periods` is
/// n - 1. `period_ticks` must exceed `min_lead_ticks` (else every instant is "too close" and the
/// grid point after the next is taken, still correct but one period later than needed).
///
/// Valid while `now - fired` is below 2^32 ticks (51 s at 84 MHz).
pub fn next_period_compare(
    fired_ticks: u32,
    period_ticks: u32,
    now_ticks: u32,
    min_lead_ticks: u32,
) -> PeriodCompare {
    let period = u64::from(period_ticks.max(1));
    let elapsed = u64::from(now_ticks.wrapping_sub(fired_ticks));
    // The first grid point strictly after now, then as many more as the lead needs.
    let mut n = elapsed / period + 1;
    while n * period - elapsed < u64::from(min_lead_ticks) {
        n += 1;
    }
    PeriodCompare {
        at_ticks: fired_ticks.wrapping_add((n * period) as u32),
        missed_periods: (n - 1).min(u64::from(u32::MAX)) as u32,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_rng::XorShift;

    const TIMER_HZ: u32 = 84_000_000;
    const PERIOD_1KHZ: u32 = 84_000;
    const LEAD: u32 = 168;

    /// On time (the handler a few microseconds after the match): one period on, nothing missed.
    #[test]
    fn on_time_the_next_compare_is_one_period_on() {
        for late in [0, 1, 100, 10_000, PERIOD_1KHZ - LEAD] {
            let c = next_period_compare(5_000, PERIOD_1KHZ, 5_000 + late, LEAD);
            assert_eq!(
                c,
                PeriodCompare {
                    at_ticks: 5_000 + PERIOD_1KHZ,
                    missed_periods: 0
                },
                "late {late}"
            );
        }
        // Too close to the next grid point to arm it safely: the one after.
        let c = next_period_compare(5_000, PERIOD_1KHZ, 5_000 + PERIOD_1KHZ - LEAD + 1, LEAD);
        assert_eq!(c.at_ticks, 5_000 + 2 * PERIOD_1KHZ);
        assert_eq!(c.missed_periods, 1);
    }

    /// After a pause of 1 ms to 3 s (a store masks TIM2 for up to 2.1 s), at any phase and
    /// across the 32-bit wrap: the compare is ahead of the counter by at least the lead and at
    /// most a period plus the lead, it stays on the grid, and the periods in between are
    /// counted exactly.
    #[test]
    fn after_a_pause_the_compare_is_ahead_on_the_grid_and_the_gap_counted() {
        let pauses_ms = [1u64, 2, 10, 49, 500, 1_000, 2_100, 3_000];
        for &fired in &[0u32, 1_000, u32::MAX - 40_000, u32::MAX - 84_000 * 1_500] {
            for &pause_ms in &pauses_ms {
                for extra in [0u64, 1, 777, 83_999] {
                    let elapsed = pause_ms * u64::from(TIMER_HZ) / 1000 + extra;
                    let now = fired.wrapping_add(elapsed as u32);
                    let c = next_period_compare(fired, PERIOD_1KHZ, now, LEAD);
                    let ahead = c.at_ticks.wrapping_sub(now);
                    assert!(
                        (LEAD..=PERIOD_1KHZ + LEAD).contains(&ahead),
                        "fired {fired} pause {pause_ms} ms: {ahead} ticks ahead"
                    );
                    let offset = u64::from(c.at_ticks.wrapping_sub(fired));
                    assert_eq!(offset % u64::from(PERIOD_1KHZ), 0, "off the grid");
                    let n = offset / u64::from(PERIOD_1KHZ);
                    assert_eq!(u64::from(c.missed_periods), n - 1);
                    // Every grid point passed over lay before now + lead: none skipped needlessly.
                    assert!((n - 1) * u64::from(PERIOD_1KHZ) < elapsed + u64::from(LEAD));
                }
            }
        }
        // A 2 s store at 1 kHz: 1999 or 2000 periods without their own compare.
        let c = next_period_compare(10, PERIOD_1KHZ, 10 + 2 * TIMER_HZ + 5, LEAD);
        assert_eq!(c.missed_periods, 2000);
    }

    /// Property: random periods (100 Hz..100 kHz), start phases and delays below a wrap.
    #[test]
    fn property_random_periods_phases_and_delays() {
        let mut rng = XorShift(0x5EED_0001);
        for _ in 0..200_000 {
            let period = 840 + (rng.next() % (840_000 - 840)) as u32;
            let fired = rng.next() as u32;
            let elapsed = rng.next() % (1u64 << 32);
            let now = fired.wrapping_add(elapsed as u32);
            let lead = (rng.next() % u64::from(period / 2)) as u32;
            let c = next_period_compare(fired, period, now, lead);
            let ahead = c.at_ticks.wrapping_sub(now);
            assert!(
                ahead >= lead && ahead < period + lead,
                "{period} {fired} {elapsed} {lead}"
            );
            let offset = u64::from(c.at_ticks.wrapping_sub(fired));
            // The true distance may exceed the 32-bit offset by a wrap when now is near one.
            let true_offset = if offset <= elapsed {
                offset + (1 << 32)
            } else {
                offset
            };
            assert_eq!(true_offset % u64::from(period), 0);
            assert_eq!(
                u64::from(c.missed_periods),
                true_offset / u64::from(period) - 1
            );
        }
    }
}
