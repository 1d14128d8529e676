//! The phase between TIM2 (the latch timer) and TIM4 (the drive tick), across TIM2's wraps.
//!
//! Both count the same 84 MHz APB1 timer clock: TIM2 over 32 bits (it wraps every 51 s), TIM4
//! from 0 to 2099 (an update, the drive tick, every 25 us). Their phase is fixed while both
//! run, but it cannot be kept as "a TIM2 count modulo 2100": 2^32 is not a multiple of 2100
//! (2^32 mod 2100 = 1096), so after each wrap of TIM2 such a phase is 1096 ticks off the real
//! TIM4 update (a window measured at offset 125 sits at 1129, 33, 1037, ... after the first,
//! second, third wrap).
//!
//! So the phase is never stored: the two counters are read together (inside the critical
//! section that also writes the compare, a few timer clocks apart) and every instant is
//! placed relative to that pair by a signed difference of at most half a wrap (25 s), which
//! needs no knowledge of how many times TIM2 has wrapped.

use crate::signal::output::latch_plan::KeepOut;

/// The TIM4 count (0..period) at TIM2 instant `at_ticks`, from the two counters read together
/// (`tim2_now`, `tim4_now`). Valid for `at` within half a TIM2 wrap (25.6 s) of `tim2_now`,
/// before or after, whatever the number of wraps since start.
pub fn drive_phase_at(at_ticks: u32, tim2_now: u32, tim4_now: u32, period_ticks: u32) -> u32 {
    let offset = i64::from(at_ticks.wrapping_sub(tim2_now) as i32);
    (i64::from(tim4_now) + offset).rem_euclid(i64::from(period_ticks.max(1))) as u32
}

/// The keep-out window around the drive tick's conversion, anchored at the pair read now: it
/// opens `before_ticks` before a TIM4 update (count 0) and is `width_ticks` wide. Its start is
/// a TIM2 instant within a period of `tim2_now`, so the plan may place any instant within
/// half a wrap of now against it ([`KeepOut::clear_of`]); re-anchor at every use.
pub fn keep_out_now(
    tim2_now: u32,
    tim4_now: u32,
    period_ticks: u32,
    before_ticks: u32,
    width_ticks: u32,
) -> KeepOut {
    KeepOut {
        period_ticks,
        start_ticks: tim2_now.wrapping_sub(tim4_now).wrapping_sub(before_ticks),
        width_ticks,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::signal::output::latch_plan::LatchPlan;
    use crate::test_rng::XorShift;

    const P: u32 = 2100;
    const HALF: u32 = 125;

    /// The two counters at true time `t` (ticks since both started, 64 bits): TIM2 wraps at
    /// 2^32, TIM4 counts 0..P from `tim4_start` (its count at t = 0).
    fn counters(t: u64, tim4_start: u32) -> (u32, u32) {
        (
            t as u32,
            ((t + u64::from(tim4_start)) % u64::from(P)) as u32,
        )
    }

    /// The TIM4 count at any instant within +-20 s of the pair, the pair read before, at or
    /// after a wrap of TIM2, and the instant on either side of it.
    #[test]
    fn the_drive_tick_phase_is_right_across_tim2_wraps() {
        let wrap = 1u64 << 32;
        for tim4_start in [0, 1, 1096, 2099] {
            for wraps in 0..4u64 {
                for from_wrap in [-1_000_000i64, -3, -1, 0, 1, 2, 1_000_000] {
                    let t_now = (wraps * wrap + 10 * wrap) as i64 + from_wrap;
                    let (t2, t4) = counters(t_now as u64, tim4_start);
                    for d in [
                        -1_680_000_000i64,
                        -84_000,
                        -1,
                        0,
                        1,
                        1095,
                        84_000,
                        1_680_000_000,
                    ] {
                        let t_at = (t_now + d) as u64;
                        let (at, truth) = counters(t_at, tim4_start);
                        assert_eq!(
                            drive_phase_at(at, t2, t4, P),
                            truth,
                            "tim4 start {tim4_start}, wraps {wraps}, {from_wrap} from the wrap, d {d}"
                        );
                    }
                }
            }
        }
    }

    /// Property: random start phases, pair times over 10 wraps, offsets within +-25 s.
    #[test]
    fn property_phase_over_random_pairs_and_offsets() {
        let mut rng = XorShift(0x9A5E_0002);
        for _ in 0..200_000 {
            let tim4_start = (rng.next() % u64::from(P)) as u32;
            let t_now = rng.next() % (10 << 32) + (1 << 31);
            let d = (rng.next() % (1 << 31)) as i64 - (1 << 30);
            let (t2, t4) = counters(t_now, tim4_start);
            let (at, truth) = counters((t_now as i64 + d) as u64, tim4_start);
            assert_eq!(drive_phase_at(at, t2, t4, P), truth);
        }
    }

    /// As the board uses it: the plan re-anchored from the counters at every placement, over
    /// four wraps of TIM2 (a sync edge every ~1 ms, jumps of up to 6 s, a turnaround close by
    /// now and then): no output latch lands in a real drive tick's conversion window (from 125
    /// ticks before the TIM4 update to 125 after).
    #[test]
    fn output_latches_keep_out_of_the_real_windows_over_four_wraps() {
        use crate::sample::TurnaroundKind;
        use crate::signal::output::latch_plan::LatchKind;
        let mut rng = XorShift(0x9A5E_0003);
        let tim4_start = 733;
        let mut plan = LatchPlan::new();
        let end = 4 * (1u64 << 32) + 84_000_000;
        let (mut t, mut checked) = (0u64, 0u32);
        while t < end {
            let (t2, t4) = counters(t, tim4_start);
            plan.set_keep_out(keep_out_now(t2, t4, P, HALF, 2 * HALF));
            if rng.next().is_multiple_of(3) {
                let at = t2.wrapping_add(168 + (rng.next() % 1000) as u32);
                plan.on_turnaround(TurnaroundKind::Plus, at);
            }
            plan.on_sync(t2, t2);
            while let Some((kind, at)) = plan.armed() {
                if kind == LatchKind::Output {
                    let true_t = t + u64::from(at.wrapping_sub(t2));
                    let (_, count) = counters(true_t, tim4_start);
                    assert!(
                        (HALF..P - HALF).contains(&count),
                        "t {t}: latch at TIM4 count {count}, inside the conversion window"
                    );
                    checked += 1;
                }
                plan.on_fired();
            }
            t += 84_000 + rng.next() % 2000;
            if rng.next().is_multiple_of(4096) {
                t += rng.next() % 500_000_000;
            }
        }
        assert!(checked > 50_000, "{checked}");
    }
}
