//! The boundary between the simulator and the firmware, `firmware::sample::TurnaroundSample`:
//! what hal-sim latches must mean what the firmware's signal chain assumes it means.
//!
//! The firmware reads raw codes only; its conventions (docs/physics.md, "Sign conventions") are
//! that the "+" turnaround is a minimum of the beat phase, channel A ~ cos psi_H and channel
//! B ~ sin psi_H, the x4 count increases with psi_H, and the timestamp is the capture timer's
//! register at the latch. A simulator that swapped the channels, counted down, labelled the
//! turnarounds the other way round or stamped the wrong instant would still run, and the
//! signal chain would quietly form the wrong P1/P2 (a steady dither hides a wrong sign
//! pattern). This test checks each convention against the gyro's truth, turnaround by
//! turnaround, on the default (realistic) board with an exact latch.

mod common;

use common::{paper_gyro, TAU};
use firmware::sample::{TurnaroundKind, TurnaroundSample};
use hal_sim::counter::ideal_quadrant_index;
use hal_sim::gyro::Turnaround;
use hal_sim::harness::{Harness, HarnessOptions};
use hal_sim::input::InputProfile;
use std::collections::BTreeMap;

/// The latched samples and the gyro's true turnarounds (by time), over `seconds`.
fn latches(
    seconds: f64,
) -> (
    Harness,
    Vec<(f64, TurnaroundSample)>,
    BTreeMap<u64, Turnaround>,
) {
    let params = paper_gyro(31);
    let mut harness = HarnessOptions::new(params, InputProfile::constant(10.0))
        .build()
        .unwrap();
    let (mut samples, mut truth) = (Vec::new(), BTreeMap::new());
    harness.run_until(seconds, |h, half| {
        samples.push((half.latch_s(), half.sample));
        for tr in h.take_traversals() {
            truth.insert(tr.turnaround.time_s.to_bits(), tr.turnaround);
        }
    });
    (harness, samples, truth)
}

#[test]
fn turnaround_samples_follow_the_firmware_conventions() {
    let (harness, samples, truth) = latches(0.3);
    let config = harness.board().config();
    let pd = config.photodiodes;
    let eps_rad = harness.gyro().params().eps_rad;
    // 1 mV of noise on a 1.32 V amplitude is 7.6e-4 rad per channel: 0.01 rad is 13 sigma.
    const PHASE_TOLERANCE_RAD: f64 = 0.01;

    let mut checked = 0;
    let mut previous: Option<(TurnaroundSample, f64)> = None;
    for &(latch_s, sample) in &samples {
        // The exact latch sits on the true turnaround; the last one may not be logged yet.
        let Some(turn) = truth.get(&latch_s.to_bits()) else {
            continue;
        };
        assert_eq!(sample.kind, turn.kind, "kind at {latch_s} s");
        // "+": the lock-in-free rate goes from negative to positive, psi at a minimum.
        let expected_sign = match turn.kind {
            TurnaroundKind::Plus => 1.0,
            TurnaroundKind::Minus => -1.0,
        };
        assert_eq!(turn.psi_ddot_rad_per_s2.signum(), expected_sign);

        // Timestamp: the 84 MHz capture register at the latch (whole ticks, wrapping).
        let ticks = (latch_s * config.timer_hz).floor() as u64 as u32;
        assert!(
            sample.timestamp_ticks.wrapping_sub(ticks).wrapping_add(1) <= 2,
            "timestamp {} vs {ticks} ticks",
            sample.timestamp_ticks
        );

        // ADC: A ~ cos psi_H, B ~ sin psi_H around the channels' mid levels.
        let psi_h = turn.psi_rad - eps_rad;
        let lsb_v = pd.adc.lsb_v();
        let cos = (sample.adc_a_code.to_f64() * lsb_v - pd.a.mid_level_v) / pd.a.amplitude_v;
        let sin = (sample.adc_b_code.to_f64() * lsb_v - pd.b.mid_level_v) / pd.b.amplitude_v;
        let phase_error = (sin.atan2(cos) - psi_h + TAU / 2.0).rem_euclid(TAU) - TAU / 2.0;
        assert!(
            phase_error.abs() < PHASE_TOLERANCE_RAD,
            "photodiode phase off by {phase_error} rad at {latch_s} s"
        );

        // Count: up with psi_H, one count per quarter fringe. The comparators' 20 mV
        // hysteresis moves the edges by up to 1 % of a fringe, so the count may lag the ideal
        // quadrant index by one: allow +-1 between two latches.
        if let Some((before, psi_h_before)) = previous {
            let counted = sample.encoder_count.wrapping_sub(before.encoder_count) as i32 as i64;
            let ideal = ideal_quadrant_index(psi_h) - ideal_quadrant_index(psi_h_before);
            assert!(
                (counted - ideal).abs() <= 1,
                "counted {counted}, ideal {ideal} quarter fringes at {latch_s} s"
            );
        }
        previous = Some((sample, psi_h));
        checked += 1;
    }
    // 0.3 s at 389 Hz: 233 turnarounds, of which the last may still be unlogged.
    assert!(checked >= 230, "checked {checked} turnarounds");
}
