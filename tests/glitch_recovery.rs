//! Faults injected into the simulated board, through the whole chain (hal-sim's `SimBoard` and
//! the firmware's `Readout`): each must be flagged on the cycles it touches, counted, and left
//! behind once it is gone.
//!
//! Scenario: the gyro of docs/physics.md at 10 deg/h (outside the dead band), compensation on
//! with the exact a, b, 1.7 s of gyro time. A fault starts at the latch of half cycle 540
//! (0.696 s, after two Lissajous fits) and lasts `FAULT_LATCHES` latches. Every scenario is
//! compared with the same run without the fault: the noise streams are the same (a fault does
//! not change the draws), so any difference is the fault's.
//!
//! | fault | hook | expected flags | counters |
//! | --- | --- | --- | --- |
//! | register jump (EMI burst, corrupted read) of 10^6 counts | `QuadratureCounter::inject_counts` | COUNTER_GLITCH on every cycle holding one of the 3 glitched latches | 3 counter glitches (2 rejected reads, then the resync) |
//! | a missed turnaround interrupt | the latch is not delivered | TURNAROUND_MISSED on the next cycle | 1 turnaround, 2 cycles fewer |
//! | ADC saturated (both codes at full scale) for 4 latches | `Photodiodes::set_fault` | SIGNAL_LOST on every cycle holding one of them, no correction | 4 signal-lost readings |
//! | photodiode light lost (both channels at their DC level) for 4 latches | `Photodiodes::set_fault` | as saturation | as saturation |
//!
//! Recovery: no flags from the end of the fault on; every unflagged cycle within
//! [`CYCLE_TOLERANCE_DEG_H`] of the fault-free run's cycle ending at the same latch (except,
//! for the saturation, until the Lissajous windows that took in the saturated samples are
//! replaced, see below); and the rate over the last 100 cycles within
//! [`MEAN_TOLERANCE_DEG_H`] of the input rate.
//!
//! Known limits, measured here and not asserted as good behaviour:
//! - The ADC-saturation samples (about 60 conversions at the corner (4095, 4095)) enter the
//!   Lissajous window open at the time, and its fit is accepted: the normalisation is biased
//!   until the next fit replaces it, one window later (4096 conversions, 0.33 s). In that
//!   window unflagged cycles are off by up to 21 deg/h (0.015 fringe) against the fault-free
//!   run. Recovery is asserted after that window, [`SATURATION_RECOVERY_S`]; a fit that skipped
//!   conversions at the rails would recover at once.
//! - Slips of 2 or 3 counts (half or three quarters of a fringe, `miss_next_edges(2)`,
//!   `inject_counts(3)`) are not covered: the count extension accepts them as motion, and the
//!   fractional fringe either flags every later turnaround (2 counts: the disagreement stays at
//!   half a turn and the learned quadrant offset is never moved) or reads one fringe too many,
//!   unflagged (3 counts). Both are firmware changes (the fractional-fringe resolver), not
//!   test matters.
//! - A single lost channel (hal-sim's `PhotodiodeFault::ChannelBLost`) is flagged only at the
//!   latches where the normalised radius |cos psi_H| falls below 0.5; elsewhere the fractional
//!   fringe is off by up to 1/8 fringe, unflagged (measured: one cycle off by 87 deg/h among
//!   four faulty latches). Not asserted either.

mod common;

use std::collections::BTreeMap;

use common::{paper_gyro, TAU};
use firmware::readout::{ReadoutConfig, ReadoutCounters};
use firmware::signal::compensation::{Coefficients, CompensationSettings};
use firmware::signal::lockin::{CycleFlags, CycleRecord};
use firmware::units::PhaseDelta;
use hal_sim::board::SimBoard;
use hal_sim::harness::{Feed, HarnessOptions};
use hal_sim::input::InputProfile;
use hal_sim::params::GyroParams;
use hal_sim::photodiode::PhotodiodeFault;

const INPUT_DEG_H: f64 = 10.0;
const RUN_S: f64 = 1.7;
/// The half cycle (turnaround latch) at which each fault starts.
const FAULT_AT: usize = 540;
/// Latches an ADC fault lasts.
const FAULT_LATCHES: usize = 4;
/// Cycles after the last faulty latch from which the output must be back: a cycle's increment
/// spans five latches (the 1-2-1 averages centred on two "-" turnarounds a period apart), so the
/// third cycle closed after a latch is the first clear of it.
const RECOVERY_CYCLES: usize = 3;
/// Per cycle, against the fault-free run: 0.05 deg/h over one cycle (2.6 ms) is 7e-5 fringe,
/// 4e-4 rad, about half the photodiode noise of one latch (7.6e-4 rad). Measured (seed 51): 0
/// after the counter glitch and the missed turnaround, 5e-7 after the saturation, 1.6e-4 deg/h
/// after the dark photodiodes (their conversions moved the next Lissajous fit a little).
const CYCLE_TOLERANCE_DEG_H: f64 = 0.05;
/// The rate over the last 100 cycles (0.26 s) against the input: the phase noise at the two
/// ends (1.2e-4 fringe each) gives 1e-3 deg/h, the compensation's residual less. Measured:
/// 1.7e-3 deg/h in every scenario.
const MEAN_TOLERANCE_DEG_H: f64 = 0.01;
/// After the ADC saturation: the end of the Lissajous window after the one that took in the
/// saturated conversions (windows of 4096 conversions at 12 345 Hz end at 0.995 s and 1.327 s;
/// the first cycle wholly after the second ends at 1.332 s).
const SATURATION_RECOVERY_S: f64 = 1.335;

/// What one run produced.
struct Run {
    /// Completed cycles with the time of their last latch, s.
    cycles: Vec<(f64, CycleRecord)>,
    /// Latch time of every half cycle, s (delivered or not).
    latches_s: Vec<f64>,
    counters: ReadoutCounters,
    config: ReadoutConfig,
}

impl Run {
    fn rate_deg_h(&self, record: &CycleRecord) -> f64 {
        let fringes = record.output.increment.fringes_f64();
        fringes / record.duration_s(&self.config.cycle) * paper_gyro(0).scale_factor_arcsec
    }

    /// The cycle's first latch, s: its increment starts from the 1-2-1 average centred on the
    /// "-" turnaround before its opening "+", which holds the "+" a period before that.
    fn start_s(&self, end_s: f64, record: &CycleRecord) -> f64 {
        end_s - 2.0 * record.duration_s(&self.config.cycle)
    }
}

/// The firmware in the loop (hal-sim's harness) with the exact a, b. `inject(board, half_cycle)`
/// runs before each latch and returns whether the latch reaches the readout (the conversions
/// always do).
fn run_chain(params: &GyroParams, mut inject: impl FnMut(&mut SimBoard, usize) -> bool) -> Run {
    let omega_l = params.derive().unwrap().omega_l_rad_per_s;
    let phase = params.eps_rad + TAU / 8.0;
    let settings = CompensationSettings {
        coefficients: Coefficients::from_rad_per_s(
            (omega_l * phase.cos()) as f32,
            (omega_l * phase.sin()) as f32,
        )
        .unwrap(),
        enabled: true,
    };
    let mut harness = HarnessOptions::new(*params, InputProfile::constant(INPUT_DEG_H))
        .compensation(settings)
        .build()
        .unwrap();
    let (mut cycles, mut latches_s) = (Vec::new(), Vec::new());
    while harness.time_s() < RUN_S {
        let feed = if inject(harness.board_mut(), latches_s.len()) {
            Feed::Everything
        } else {
            Feed::MissTurnaround
        };
        let half = harness.step_with(feed);
        latches_s.push(half.latch_s());
        if let Some(record) = half.record {
            cycles.push((half.latch_s(), record));
        }
    }
    Run {
        cycles,
        latches_s,
        counters: harness.readout().counters(),
        config: *harness.config(),
    }
}

/// Checks a faulty run against the fault-free one: flags exactly on the cycles holding a latch
/// in `faulty_s` (with `flag`), none after, and the recovery of the output from `recovered_s`.
fn check(name: &str, clean: &Run, run: &Run, faulty_s: &[f64], flag: CycleFlags, recovered_s: f64) {
    let clean_by_end: BTreeMap<u64, f64> = clean
        .cycles
        .iter()
        .map(|(t, c)| (t.to_bits(), clean.rate_deg_h(c)))
        .collect();
    let mut worst_after = 0.0f64;
    for (end_s, record) in &run.cycles {
        let start_s = run.start_s(*end_s, record);
        let touched = faulty_s
            .iter()
            .any(|&t| t >= start_s - 1e-6 && t <= end_s + 1e-6);
        let flags = record.output.flags;
        if *end_s < 0.01 {
            continue; // the first cycle: no dither measured yet (DITHER_INVALID)
        }
        if touched {
            assert!(
                flags.contains(flag),
                "{name}: cycle ending at {end_s:.4} s holds a faulty latch, flags {flags:?}"
            );
            if flag == CycleFlags::SIGNAL_LOST {
                assert_eq!(
                    record.output.correction,
                    PhaseDelta::ZERO,
                    "{name}: compensated"
                );
            }
        } else if flag != CycleFlags::TURNAROUND_MISSED {
            assert!(
                flags.is_empty(),
                "{name}: cycle ending at {end_s:.4} s flagged {flags:?}"
            );
        }
        if *end_s >= recovered_s {
            assert!(flags.is_empty(), "{name}: flags {flags:?} at {end_s:.4} s");
            let clean_rate = clean_by_end[&end_s.to_bits()];
            worst_after = worst_after.max((run.rate_deg_h(record) - clean_rate).abs());
        }
    }
    let last: Vec<_> = run.cycles[run.cycles.len() - 100..].iter().collect();
    let fringes: f64 = last
        .iter()
        .map(|(_, c)| c.output.increment.fringes_f64())
        .sum();
    let seconds: f64 = last
        .iter()
        .map(|(_, c)| c.duration_s(&run.config.cycle))
        .sum();
    let mean = fringes / seconds * paper_gyro(0).scale_factor_arcsec;
    eprintln!(
        "{name}: {:?}; after {recovered_s:.4} s worst cycle {worst_after:.2e} deg/h off the \
         fault-free run; last 100 cycles {mean:.4} deg/h",
        run.counters
    );
    assert!(
        worst_after < CYCLE_TOLERANCE_DEG_H,
        "{name}: worst recovered cycle off by {worst_after} deg/h"
    );
    assert!(
        (mean - INPUT_DEG_H).abs() < MEAN_TOLERANCE_DEG_H,
        "{name}: mean rate {mean} deg/h"
    );
}

/// The cycle end `cycles` cycles after latch `latch` of `run`, s.
fn cycles_after(run: &Run, latch: usize, cycles: usize) -> f64 {
    run.latches_s[latch + 2 * cycles]
}

#[test]
fn faults_are_flagged_counted_and_recovered_from() {
    let params = paper_gyro(51);
    let clean = run_chain(&params, |_, _| true);
    let c = clean.counters;
    assert_eq!(
        (c.counter_glitches, c.phase_glitches, c.signal_lost),
        (0, 0, 0)
    );
    assert!(clean.cycles[1..]
        .iter()
        .all(|(_, r)| r.output.flags.is_empty()));

    // A register jump: two reads rejected, the third resynchronises.
    let run = run_chain(&params, |board, i| {
        if i == FAULT_AT {
            board.counter_mut().inject_counts(1_000_000);
        }
        true
    });
    let faulty = &run.latches_s[FAULT_AT..FAULT_AT + 3];
    assert_eq!(run.counters.counter_glitches, 3);
    assert!(run.counters.phase_glitches <= 1);
    assert_eq!(run.counters.cycles, c.cycles);
    let recovered = cycles_after(&run, FAULT_AT + 2, RECOVERY_CYCLES);
    check(
        "counter glitch",
        &clean,
        &run,
        faulty,
        CycleFlags::COUNTER_GLITCH,
        recovered,
    );

    // A missed turnaround: the open cycle is dropped, the next one flagged.
    let run = run_chain(&params, |_, i| i != FAULT_AT);
    assert_eq!(run.counters.turnarounds, c.turnarounds - 1);
    assert_eq!(run.counters.cycles, c.cycles - 2);
    let missed: Vec<_> = run
        .cycles
        .iter()
        .filter(|(_, r)| r.output.flags.contains(CycleFlags::TURNAROUND_MISSED))
        .collect();
    assert_eq!(missed.len(), 1, "flagged cycles: {}", missed.len());
    let first_after = run
        .cycles
        .iter()
        .find(|(t, _)| *t > run.latches_s[FAULT_AT])
        .unwrap();
    assert_eq!(missed[0].0, first_after.0, "the flag is on the next cycle");
    let recovered = cycles_after(&run, FAULT_AT, RECOVERY_CYCLES + 1);
    check(
        "missed turnaround",
        &clean,
        &run,
        &[],
        CycleFlags::TURNAROUND_MISSED,
        recovered,
    );

    // Photodiode faults for FAULT_LATCHES latches.
    for (fault, recovered_from_s) in [
        (PhotodiodeFault::AdcSaturated, Some(SATURATION_RECOVERY_S)),
        (PhotodiodeFault::Dark, None),
    ] {
        let run = run_chain(&params, |board, i| {
            if i == FAULT_AT {
                board.photodiodes_mut().set_fault(Some(fault));
            }
            if i == FAULT_AT + FAULT_LATCHES {
                board.photodiodes_mut().set_fault(None);
            }
            true
        });
        assert_eq!(run.counters.signal_lost, FAULT_LATCHES as u32, "{fault:?}");
        assert_eq!(run.counters.counter_glitches, 0, "{fault:?}");
        let last_faulty = FAULT_AT + FAULT_LATCHES - 1;
        let recovered =
            recovered_from_s.unwrap_or_else(|| cycles_after(&run, last_faulty, RECOVERY_CYCLES));
        check(
            &format!("{fault:?}"),
            &clean,
            &run,
            &run.latches_s[FAULT_AT..=last_faulty],
            CycleFlags::SIGNAL_LOST,
            recovered,
        );
    }
}
