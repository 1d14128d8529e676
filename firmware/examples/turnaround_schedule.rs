//! Self-check of the turnaround prediction on the MCU in QEMU:
//! `cargo fw-run --example turnaround_schedule` (exit status 0 = all checks pass).
//!
//! The scheduler is plain logic (`signal::turnaround`, unit-tested on the host); this
//! checks the same code compiled for the M4F with the board's settings
//! (`profile::BoardProfile::scheduler_config`: its delays and pick-off polarity) and its counters,
//! on synthetic pick-off edges in 84 MHz ticks:
//! - a comparator threshold offset (rising edges late, falling edges early by the same amount)
//!   and the fixed pick-off delay cancel: the compare lands on the true extremum minus the ADC
//!   aperture delay, to a tick, across the 32-bit wrap of the timer;
//! - the input-rate shift moves "+" turnarounds earlier and "-" turnarounds later;
//! - a slowly drifting dither period costs only a few ticks;
//! - a lost edge or an implausible interval yields no compare until the history is rebuilt, and
//!   the board's wrapper counts the implausible one in `IMPLAUSIBLE`;
//! - `rate_shift_ticks` for 1 deg/s at the docs/physics.md parameter set (~1.34 us = 112 ticks), from
//!   a cycle record as the cycle task computes it.
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
mod app {
    use core::sync::atomic::Ordering;
    use firmware::board::turnaround::{self, IMPLAUSIBLE};
    use firmware::profile::BoardProfile;
    use firmware::sample::TurnaroundKind;
    use firmware::signal::lockin::{CycleOutput, CycleRecord};
    use firmware::signal::output::rate_shift_ticks;
    use firmware::signal::turnaround::{opposite, Edge, Scheduler, SchedulerConfig};
    use firmware::units::{PhaseDelta, Q32_PER_FRINGE};

    const TIMER_HZ: u32 = 84_000_000;
    const CONFIG: SchedulerConfig = BoardProfile::F405.scheduler_config();
    /// One dither period at 389 Hz, ticks (rounded to even, so T/4 is exact).
    const PERIOD: u32 = 215_936;
    /// Comparator threshold offset as a time shift of the edges, ticks (8.3 us).
    const OFFSET: u32 = 700;

    struct Checks {
        failed: u32,
        run: u32,
    }

    impl Checks {
        fn check(&mut self, name: &str, ok: bool, got: i64, want: i64) {
            self.run += 1;
            if ok {
                defmt::info!("ok    {=str}: {=i64} (want {=i64})", name, got, want);
            } else {
                self.failed += 1;
                defmt::error!("FAIL  {=str}: {=i64} (want {=i64})", name, got, want);
            }
        }
    }

    /// Feeds `cycles` full dither cycles starting at `t0` (true rising zero crossing), with the
    /// threshold offset and pick-off delay applied; returns the largest error of the compares
    /// against the true extrema, and how many compares there were.
    fn run_cycles(
        s: &mut Scheduler,
        t0: u32,
        cycles: u32,
        drift_per_cycle: i32,
        shift: i32,
    ) -> (i64, u32, u32) {
        let (mut worst, mut n) = (0i64, 0u32);
        let mut t = t0;
        let mut period = PERIOD as i32;
        for _ in 0..cycles {
            let half = (period / 2) as u32;
            let rise = t.wrapping_add(OFFSET + CONFIG.pickoff_delay_ticks);
            let fall = t.wrapping_add(half - OFFSET + CONFIG.pickoff_delay_ticks);
            for (edge, at, extremum) in [
                (Edge::Rising, rise, t.wrapping_add(half / 2)),
                (Edge::Falling, fall, t.wrapping_add(half + half / 2)),
            ] {
                if let Some(c) = s.on_edge(&CONFIG, edge, at, shift, 0).schedule {
                    let expect_kind = if edge == Edge::Rising {
                        CONFIG.after_rising_edge
                    } else {
                        opposite(CONFIG.after_rising_edge)
                    };
                    let sign = if c.kind == TurnaroundKind::Plus {
                        -1
                    } else {
                        1
                    };
                    let want = extremum
                        .wrapping_sub(CONFIG.aperture_delay_ticks)
                        .wrapping_add_signed(sign * shift);
                    let err = c.compare_ticks.wrapping_sub(want) as i32 as i64;
                    if c.kind != expect_kind {
                        worst = i64::MAX;
                    } else if err.abs() > worst.abs() {
                        worst = err;
                    }
                    n += 1;
                }
            }
            t = t.wrapping_add(period as u32);
            period += drift_per_cycle;
        }
        (worst, n, t)
    }

    /// A cycle record of `fringes` per 389 Hz cycle with the measured dither `amplitude_rad`.
    fn record(fringes: f32, amplitude_rad: f32) -> CycleRecord {
        CycleRecord {
            output: CycleOutput {
                increment: PhaseDelta::from_q32((fringes as f64 * Q32_PER_FRINGE) as i64),
                duration_ticks: TIMER_HZ / 389,
                ..Default::default()
            },
            raw_increment: PhaseDelta::ZERO,
            terms: Default::default(),
            end_phase: Default::default(),
            dither_amplitude_rad: amplitude_rad,
            dither_hz: 389.0,
        }
    }

    #[cortex_m_rt::entry]
    fn main() -> ! {
        let mut c = Checks { failed: 0, run: 0 };
        let new = Scheduler::new;

        // Threshold offset and pick-off delay cancel, across the 32-bit wrap.
        let mut s = new();
        let (worst, n, _) = run_cycles(&mut s, u32::MAX - 3 * PERIOD, 8, 0, 0);
        c.check(
            "offset cancels (max error, ticks)",
            worst.abs() <= 1,
            worst,
            0,
        );
        // The first rising edge has no history, nor has the first falling edge: 16 - 2.
        c.check("compares after the first cycle", n == 14, n as i64, 14);

        // Input-rate shift: "+" earlier, "-" later (the expectation applies the sign).
        let mut s = new();
        let (worst, _, _) = run_cycles(&mut s, 1_000, 8, 0, 500);
        c.check(
            "rate shift applied with the right sign",
            worst.abs() <= 1,
            worst,
            0,
        );

        // A dither period drifting by 20 ticks (93 ppm) per cycle.
        let mut s = new();
        let (worst, _, _) = run_cycles(&mut s, 1_000, 8, 20, 0);
        c.check("period drift 93 ppm/cycle", worst.abs() <= 20, worst, 0);

        // A lost falling edge: two rising edges in a row give nothing, then it recovers.
        let mut s = new();
        let (_, _, t) = run_cycles(&mut s, 1_000, 3, 0, 0);
        let r1 = s.on_edge(&CONFIG, Edge::Rising, t + OFFSET, 0, 0).schedule;
        let r2 = s
            .on_edge(&CONFIG, Edge::Rising, t + PERIOD + OFFSET, 0, 0)
            .schedule;
        c.check(
            "no compare after a lost edge",
            r2.is_none(),
            r2.is_some() as i64,
            0,
        );
        let _ = r1;
        let (worst, n, _) = run_cycles(&mut s, t + PERIOD + PERIOD / 2, 3, 0, 0);
        c.check(
            "recovers after a lost edge",
            n >= 3 && worst.abs() <= 1,
            worst,
            0,
        );

        // A glitch: an interval of 10 ticks is implausible; the board's wrapper counts it.
        let mut s = new();
        let (_, _, t) = run_cycles(&mut s, 1_000, 3, 0, 0);
        let _ = s.on_edge(&CONFIG, Edge::Rising, t + OFFSET, 0, 0);
        let g = s.on_edge(&CONFIG, Edge::Falling, t + OFFSET + 10, 0, 0);
        c.check(
            "no compare after a glitch",
            g.implausible && g.schedule.is_none(),
            g.schedule.is_some() as i64,
            0,
        );
        let mut board = turnaround::Scheduler::new();
        let before = IMPLAUSIBLE.load(Ordering::Relaxed);
        let _ = board.on_edge(Edge::Rising, 1_000, 0, 0);
        let b = board.on_edge(Edge::Falling, 1_010, 0, 0);
        let counted = IMPLAUSIBLE.load(Ordering::Relaxed).wrapping_sub(before) as i64;
        c.check(
            "board counts the implausible edge",
            b.is_none() && counted == 1,
            counted,
            1,
        );

        // 1 deg/s of input at SF 1.8655 arcsec/pulse, 450 arcsec amplitude, 389 Hz.
        let per_cycle = 3600.0 / 1.8655 / 389.0;
        let amplitude = 450.0 / 1.8655 * core::f32::consts::TAU;
        let shift = rate_shift_ticks(&record(per_cycle, amplitude), TIMER_HZ) as i64;
        c.check(
            "rate shift, 1 deg/s (ticks)",
            (110..=115).contains(&shift),
            shift,
            112,
        );
        let none = rate_shift_ticks(&record(per_cycle, 0.0), TIMER_HZ) as i64;
        c.check("no dither: no shift", none == 0, none, 0);

        defmt::info!(
            "turnaround schedule: {=u32} passed, {=u32} failed",
            c.run - c.failed,
            c.failed
        );
        semihosting::process::exit(if c.failed == 0 { 0 } else { 1 })
    }
}

#[cfg(not(target_os = "none"))]
fn main() {
    println!("turnaround_schedule: an MCU example (cargo fw-run --example turnaround_schedule)");
}
