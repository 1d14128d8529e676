//! The cycle assembly's tests, on the synthetic readings of [`super::synthetic`].

use super::synthetic::{assemble, readings, readings_with_amplitude, DITHER_HZ, TIMER_HZ};
use super::*;

/// Each cycle's increment is rate x period plus the errors of its five traversals weighted
/// 1/8, 1/2, 3/4, 1/2, 1/8; measured amplitude and frequency match the dither. Tolerances:
/// Q32 rounding of the phase (1e-9 fringe) and f32 for amplitude/frequency (1e-5 relative).
#[test]
fn increments_amplitude_and_frequency() {
    let amp = core::f64::consts::TAU * 450.0 / 1.8655;
    let rate = 46.8;
    let err = |i: usize| 0.01 * ((i as f64) * 0.7).sin();
    let cycles = assemble(&readings(amp, rate, 41, |i, _| err(i)));
    // The first smoothed phase needs turnarounds 0-2; cycles close at 4, 6, .., 40.
    assert_eq!(cycles.len(), 19);
    for (c, record) in cycles.iter().enumerate() {
        let start = 2 * c;
        let want = rate / DITHER_HZ
            + (0..5)
                .map(|k| [0.125, 0.5, 0.75, 0.5, 0.125][k] * err(start + k))
                .sum::<f64>();
        assert!(
            (record.raw_increment_rad() - want).abs() < 1e-8,
            "cycle {c}"
        );
        assert_eq!(
            record.output.increment, record.raw_increment,
            "not compensated here"
        );
        assert_eq!(record.output.correction, PhaseDelta::ZERO);
        if c > 0 {
            assert!(record.output.flags.is_empty(), "{:?}", record.output.flags);
            assert!((record.dither_amplitude_rad as f64 / amp - 1.0).abs() < 1e-5);
            assert!((record.dither_hz as f64 / DITHER_HZ - 1.0).abs() < 1e-5);
        }
    }
    // The first cycle has no measured dither for its opening traversals.
    assert!(cycles[0].output.flags.contains(CycleFlags::DITHER_INVALID));
}

/// The increments do not see the dither's amplitude change: a linear ramp and a parabola
/// (10 % and 1 % over the 0.4 s run, far beyond any drive) leave them where a steady dither
/// puts them, to the Q32 rounding (a few 1.5e-9 rad steps: bound 1e-8); a 0.1 % wander at 2 Hz leaves A''' h^3 / 2 =
/// 3.2e-6 rad (bound 5e-6), where the difference of two "+" turnarounds would carry
/// A' T = 0.048 rad (asserted > 0.02: the effect the increment removes).
#[test]
fn increments_ignore_the_amplitude_change() {
    let amp = core::f64::consts::TAU * 450.0 / 1.8655;
    // The same traversal errors in every case (they depend on the phase, which the
    // amplitude moves: here only the increment's handling of the dither is under test).
    let err = |i: usize, _| 0.0177 * (1.3 * i as f64).cos();
    let steady = assemble(&readings(amp, 46.8, 301, err));
    let ramp = |t: f64| amp * (1.0 + 0.25 * t);
    let parabola = |t: f64| amp * (1.0 - 0.06 * t * t);
    let w = core::f64::consts::TAU * 2.0;
    let wander = |t: f64| amp * (1.0 + 1e-3 * (w * t + 0.4).sin());
    type AmplitudeAt<'a> = &'a dyn Fn(f64) -> f64;
    let cases: [(&str, f64, AmplitudeAt); 3] = [
        ("ramp", 1e-8, &ramp),
        ("parabola", 1e-8, &parabola),
        ("wander", 5e-6, &wander),
    ];
    for (name, tolerance_rad, amp_at) in cases {
        let rs = readings_with_amplitude(amp_at, 46.8, 301, err);
        let cycles = assemble(&rs);
        assert_eq!(cycles.len(), steady.len());
        let worst = cycles
            .iter()
            .zip(&steady)
            .map(|(c, s)| (c.raw_increment_rad() - s.raw_increment_rad()).abs())
            .fold(0.0, f64::max);
        assert!(worst < tolerance_rad, "{name}: {worst:e} rad");
        if name == "wander" {
            assert!(worst > 2e-6, "{name}: {worst:e} rad (the bound is near it)");
            let plus_to_plus_rad = rs
                .windows(3)
                .step_by(2)
                .map(|w| {
                    let naive = (w[2].phase - w[0].phase).fringes_f64();
                    (naive - 46.8 / DITHER_HZ / core::f64::consts::TAU).abs()
                        * core::f64::consts::TAU
                })
                .fold(0.0, f64::max);
            assert!(plus_to_plus_rad > 0.02, "{plus_to_plus_rad}");
        }
    }
}

/// A missing "-" turnaround: assembly restarts and the next cycle, flagged, spans the gap
/// from the last closed end, so no time and no angle are lost (zero rate: every increment
/// is the dither-free 0; the durations add up to whole periods, 1e-4 period).
#[test]
fn a_missed_turnaround_is_flagged_and_bridged() {
    let amp = 1500.0;
    let mut rs = readings(amp, 0.0, 30, |_, _| 0.0);
    rs.remove(11); // a "-" turnaround
    let cycles = assemble(&rs);
    let flagged: Vec<_> = cycles
        .iter()
        .filter(|c| c.output.flags.contains(CycleFlags::TURNAROUND_MISSED))
        .collect();
    assert_eq!(flagged.len(), 1);
    let mut periods = 0.0;
    for c in &cycles {
        assert!(c.raw_increment_rad().abs() < 1e-6, "{c:?}");
        let d = c.output.duration_ticks as f64 / TIMER_HZ as f64 * DITHER_HZ;
        assert!((d - d.round()).abs() < 1e-4 && d.round() >= 1.0, "{d}");
        periods += d;
    }
    let bridged = flagged[0].output.duration_ticks as f64 / TIMER_HZ as f64 * DITHER_HZ;
    assert!(
        bridged.round() >= 2.0,
        "the flagged cycle spans the gap: {bridged}"
    );
    assert!((periods - (cycles.len() as f64 + bridged - 1.0)).abs() < 1e-3);
}

/// A large input rate splits each period into unequal halves (here 1.4 and 0.6 of
/// nominal, as at ~180 deg/s with the docs/physics.md dither): every cycle is kept, since
/// the period is unchanged. (The old half-period window of +-20 % refused them all.) A
/// spurious pair of turnarounds inside a half (halves alternate, but no period fits) is
/// refused and bridged.
#[test]
fn unequal_halves_are_kept_and_a_spurious_pair_is_not() {
    let half_ticks = TIMER_HZ as f64 / (2.0 * DITHER_HZ);
    let mut rs = readings(1500.0, 0.0, 41, |_, _| 0.0);
    for r in rs.iter_mut().filter(|r| r.kind == TurnaroundKind::Minus) {
        r.timestamp_ticks += (0.4 * half_ticks) as u32;
    }
    let cycles = assemble(&rs);
    assert_eq!(cycles.len(), 19);
    assert!(cycles[1..].iter().all(|c| c.output.flags.is_empty()));
    // A "-" then "+" 100 and 200 us after turnaround 20 (a "+"): alternating kinds, but
    // the period up to each is far off.
    let t20 = rs[20].timestamp_ticks;
    let mut spurious = rs[19];
    spurious.timestamp_ticks = t20 + 8_400;
    let mut spurious_plus = rs[20];
    spurious_plus.timestamp_ticks = t20 + 16_800;
    rs.insert(21, spurious);
    rs.insert(22, spurious_plus);
    let cycles = assemble(&rs);
    let flagged = cycles
        .iter()
        .filter(|c| c.output.flags.contains(CycleFlags::TURNAROUND_MISSED))
        .count();
    assert_eq!(flagged, 1);
    assert!(cycles.len() >= 17, "{}", cycles.len());
}

/// A pause (`gap`): the count ran on; the first cycle after it carries the whole angle
/// since the last closed cycle (rate 10 rad/s, 1e-6 rad).
#[test]
fn a_pause_is_bridged_by_the_next_cycle() {
    let rs = readings(1500.0, 10.0, 40, |_, _| 0.0);
    let config = CycleConfig::for_dither(TIMER_HZ, DITHER_HZ as f32, 0.2);
    let mut a = CycleAssembler::new();
    let mut cycles = Vec::new();
    for (i, r) in rs.iter().enumerate() {
        if (11..17).contains(&i) {
            continue; // the readout is paused: six turnarounds unseen
        }
        if i == 17 {
            a.gap();
        }
        cycles.extend(a.on_turnaround(&config, *r));
    }
    let first_end = cycles[0].end_phase;
    let last_end = cycles.last().unwrap().end_phase;
    let summed: PhaseDelta = cycles[1..].iter().map(|c| c.raw_increment).sum();
    assert_eq!(summed, last_end - first_end, "no angle lost over the pause");
    assert_eq!(
        cycles
            .iter()
            .filter(|c| c.output.flags.contains(CycleFlags::TURNAROUND_MISSED))
            .count(),
        1
    );
}

/// A reading without levels flags the cycles that hold its traversal SIGNAL_LOST: not
/// compensable. Turnaround 9 (a "-") is the middle of the cycle from 5 to 9 and the start
/// of the one from 9 to 13 (the smoothed "-" turnarounds).
#[test]
fn lost_signal_is_flagged() {
    let mut rs = readings(1500.0, 10.0, 20, |_, _| 0.0);
    rs[9].levels = None;
    let cycles = assemble(&rs);
    let lost: Vec<_> = cycles
        .iter()
        .filter(|c| c.output.flags.contains(CycleFlags::SIGNAL_LOST))
        .collect();
    assert_eq!(lost.len(), 2);
    assert!(lost.iter().all(|c| !c.output.flags.compensable()));
    assert!(cycles[1].output.flags.compensable());
    assert!(
        !cycles[0].output.flags.compensable(),
        "no dither measured yet"
    );
}
