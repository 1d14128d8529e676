//! The dither drive's acceptance (issue 12) against hal-sim's driven resonator, the firmware's
//! controller in the loop: start from rest, holding through a resonance drift, cold starts at
//! the ends of the range, a lost pick-off (fault, invalid records, drive safe), random-noise
//! dither, and the paper's sweep with the closed-loop drive.
//!
//! Each bound is the acceptance, with a regression bound near the measured value where
//! that is far inside (seeded runs: the figures are reproducible; the margins cover seeds).

use firmware::dither::{DitherState, FaultKind};
use firmware::signal::lockin::CycleFlags;
use hal_sim::dither::resonator::ResonatorParams;
use hal_sim::harness::{DriveSource, HarnessOptions};
use hal_sim::input::InputProfile;
use hal_sim::params::GyroParams;
use rlg_sim::dither_run::{self, DitherRow, DitherRunOptions};
use rlg_sim::experiment::{calibrate, measure_rate, settings_from_fit, DitherDrive, RunLength};

fn run(options: DitherRunOptions) -> (dither_run::DitherSummary, Vec<DitherRow>) {
    let mut rows = Vec::new();
    let summary = dither_run::run(&options, |r| rows.push(*r)).expect("run");
    (summary, rows)
}

/// From rest at 389 Hz: within 1 % of the setpoint in <= 2 s, overshoot <= 5 % (measured:
/// 0.60 s, 0.40 %; the drive at its limit, the DAC's linear range, 0.88 of its half range, is
/// 3.8x what 450 arcsec needs at Q = 1000); and it settles for Q = 5000 too (0.56 s: the
/// ring-up at the limit is independent of Q, the loop measures the plant's gain).
#[test]
fn from_rest_it_settles_within_two_seconds_without_overshoot() {
    for (q, settle_regression_s) in [(1000.0, 1.0), (5000.0, 1.0)] {
        let (s, _) = run(DitherRunOptions {
            q_factor: q,
            seconds: 4.0,
            ..DitherRunOptions::default()
        });
        let settle = s.settle_s.expect("settles");
        eprintln!(
            "Q {q}: settled at {settle:.3} s, overshoot {:.2} %, locked at {:?}",
            s.overshoot_percent, s.locked_s
        );
        assert!(settle <= 2.0, "Q {q}: {settle}");
        assert!(settle <= settle_regression_s, "Q {q}: regression, {settle}");
        assert!(s.overshoot_percent <= 5.0, "Q {q}: {}", s.overshoot_percent);
        assert!(
            s.overshoot_percent <= 1.0,
            "Q {q}: regression, {}",
            s.overshoot_percent
        );
        assert!(
            s.locked_s.is_some_and(|t| t < 2.0),
            "Q {q}: {:?}",
            s.locked_s
        );
        assert_eq!(s.fault, None);
    }
}

/// f0 drifting 0.5 Hz in 60 s: amplitude rms error <= 0.05 % of the setpoint (measured 0.048 %,
/// the settling included: the amplitude passes the setpoint by 0.3 % after the hand-over to the
/// slow locked loop and takes 2 s back; 0.002 % rms from 10 s on), |drive - resonance|
/// <= 0.015 Hz while locked (measured 0.0095 Hz at the lock itself, when the frequency loop is
/// still pulling in; 0.0020 Hz from 5 s on: the amplifier's lag compensated, the frequency
/// loop's integral follows the ramp).
#[test]
fn locked_through_a_resonance_drift() {
    let (s, rows) = run(DitherRunOptions {
        resonance_drift_hz: 0.5,
        seconds: 60.0,
        ..DitherRunOptions::default()
    });
    eprintln!(
        "drift: amplitude {:.4} % rms, |drive - f0| max {:.5} Hz",
        s.amplitude_rms_error_percent, s.max_frequency_error_hz
    );
    assert!(
        (rows.last().unwrap().resonance_hz - 389.5).abs() < 1e-6,
        "the drift happened"
    );
    assert_eq!(rows.last().unwrap().state, DitherState::Locked);
    assert!(
        s.amplitude_rms_error_percent <= 0.05,
        "{}",
        s.amplitude_rms_error_percent
    );
    assert!(
        s.max_frequency_error_hz <= 0.015,
        "{}",
        s.max_frequency_error_hz
    );
    assert!(
        s.max_frequency_error_hz <= 0.011,
        "regression: {}",
        s.max_frequency_error_hz
    );
}

/// Cold starts at the ends of the stated range find the resonance and lock (the sweep covers
/// 280-620 Hz at 300 Hz/s); once locked the drive is within 0.015 Hz of the resonance.
#[test]
fn cold_starts_at_300_and_600_hz_find_the_resonance() {
    for hz in [300.0, 600.0] {
        let (s, rows) = run(DitherRunOptions {
            resonance_hz: hz,
            seconds: 5.0,
            ..DitherRunOptions::default()
        });
        eprintln!(
            "{hz} Hz: locked at {:?}, settled at {:?}",
            s.locked_s, s.settle_s
        );
        assert!(
            s.locked_s.is_some_and(|t| t < 3.0),
            "{hz}: {:?}",
            s.locked_s
        );
        let last = rows.last().unwrap();
        assert_eq!(last.state, DitherState::Locked, "{hz}");
        assert!(
            (last.drive_hz - hz).abs() < 0.015,
            "{hz}: {}",
            last.drive_hz
        );
        assert!(
            s.max_frequency_error_hz <= 0.015,
            "{hz}: {}",
            s.max_frequency_error_hz
        );
    }
}

/// The pick-off lost at 3 s: `fault` within 3 dither periods (measured: the next period), the
/// drive off at once, and the dither not driven up afterwards (the retries listen, then sweep
/// at 300 Hz/s, too fast to ring the resonator up).
#[test]
fn a_lost_pickoff_is_a_fault_within_three_periods_and_the_drive_is_safe() {
    let lost_at = 3.0;
    let (s, rows) = run(DitherRunOptions {
        pickoff_lost_at_s: Some(lost_at),
        seconds: 8.0,
        ..DitherRunOptions::default()
    });
    let period = 1.0 / 389.0;
    let fault_s = s.fault_s.expect("a fault");
    eprintln!(
        "fault {:?} {:.2} periods after the loss",
        s.fault,
        (fault_s - lost_at) / period
    );
    assert!(fault_s - lost_at <= 3.0 * period, "{fault_s}");
    assert_eq!(s.fault, Some(FaultKind::NoOscillation));
    let after: Vec<&DitherRow> = rows.iter().filter(|r| r.t_s > fault_s).collect();
    assert_eq!(after[0].drive_hz, 0.0, "drive off at the fault");
    assert!(after.iter().all(|r| r.state != DitherState::Locked));
    // Never driven above the amplitude it had at the fault; two seconds on (the natural ring
    // down, tau = 0.82 s, and the retries' fast sweeps) below a third of the setpoint.
    let at_fault = after[0].amplitude_arcsec;
    let peak_after = after.iter().map(|r| r.amplitude_arcsec).fold(0.0, f64::max);
    let peak_late = after
        .iter()
        .filter(|r| r.t_s > fault_s + 2.0)
        .map(|r| r.amplitude_arcsec)
        .fold(0.0, f64::max);
    eprintln!("amplitude at the fault {at_fault:.1}, highest after {peak_after:.1}, 2 s on {peak_late:.1} arcsec");
    assert!(peak_after <= at_fault, "{peak_after} > {at_fault}");
    assert!(peak_late < 450.0 / 3.0, "{peak_late}");
}

/// Through the whole board: every cycle latched after the loss (and its 3-period detection)
/// is flagged invalid (`DRIVE_UNLOCKED`), none before it.
#[test]
fn records_after_a_lost_pickoff_are_flagged_invalid() {
    let params = GyroParams::default().with_steady_driven_dither(ResonatorParams::default());
    let mut h = HarnessOptions::new(params, InputProfile::constant(13.888))
        .drive(DriveSource::firmware(&params).unwrap())
        .build()
        .unwrap();
    let locked = |h: &hal_sim::harness::Harness| {
        h.firmware_drive().unwrap().controller().state() == DitherState::Locked
    };
    while !locked(&h) {
        assert!(h.time_s() < 3.0, "locks");
        h.step();
    }
    h.run_until(h.time_s() + 0.5, |_, _| {});
    let lost_at = h.time_s();
    h.board_mut().pickoff_mut().set_lost(true);
    let (mut clean_before, mut flagged_after, mut clean_after) = (0, 0, 0);
    h.run_until(lost_at + 0.5, |_, half| {
        let Some(r) = half.record else { return };
        let unlocked = r.output.flags.contains(CycleFlags::DRIVE_UNLOCKED);
        if half.latch_s() < lost_at + 3.0 / 389.0 {
            clean_before += usize::from(!unlocked);
        } else if unlocked {
            flagged_after += 1;
        } else {
            clean_after += 1;
        }
    });
    eprintln!("clean before detection {clean_before}, flagged after {flagged_after}, clean after {clean_after}");
    assert_eq!(clean_after, 0);
    assert!(flagged_after > 150, "{flagged_after}");
}

/// Random-noise dither at 20 %: the drive's amplitude randomised every half cycle, its mean held
/// by the loop (mean amplitude within 0.1 % of the setpoint), the dither's amplitude moving
/// from cycle to cycle by far more than without (the resonator's Q filters the drive: 0.03 to
/// 0.1 arcsec per cycle), and the same seed gives the same run.
#[test]
fn noise_dither_randomises_the_amplitude_and_holds_its_mean() {
    let options = |noise_percent, seed| DitherRunOptions {
        noise_percent,
        seed,
        seconds: 6.0,
        ..DitherRunOptions::default()
    };
    let steps = |rows: &[DitherRow]| -> f64 {
        let locked: Vec<f64> = rows
            .iter()
            .filter(|r| r.t_s > 3.0)
            .map(|r| r.amplitude_arcsec)
            .collect();
        let d: Vec<f64> = locked.windows(2).map(|w| (w[1] - w[0]).abs()).collect();
        d.iter().sum::<f64>() / d.len() as f64
    };
    let (_, quiet) = run(options(0.0, 5));
    let (_, noisy) = run(options(20.0, 5));
    let (_, again) = run(options(20.0, 5));
    assert_eq!(noisy, again, "seeded");
    let mean = noisy
        .iter()
        .filter(|r| r.t_s > 3.0)
        .map(|r| r.amplitude_arcsec)
        .sum::<f64>()
        / noisy.iter().filter(|r| r.t_s > 3.0).count() as f64;
    let (q, n) = (steps(&quiet), steps(&noisy));
    eprintln!("mean {mean:.3} arcsec; mean |change| per cycle: quiet {q:.4}, noise {n:.4} arcsec");
    assert!((mean / 450.0 - 1.0).abs() < 0.001, "{mean}");
    assert!(n > 5.0 * q, "{n} vs {q}");
}

/// The paper's experiment with the closed-loop drive (a short version of `rlg-sim sweep
/// --dither-drive closed-loop`): the calibration still finds Omega_L and eps within 1 %, and
/// compensation still removes most of the dead band; what is left (0.085 deg/h at 10 s per point
/// in the CLI's full sweep) is the amplitude wander the output issue strips. Bound:
/// 0.2 deg/h at 5 s per point, against 2.8 deg/h uncompensated at the band's edge.
#[test]
fn the_sweep_with_the_closed_loop_drive() {
    let params = GyroParams::default();
    let drive = DitherDrive::ClosedLoop { noise_percent: 0.0 };
    let cal = RunLength {
        warmup_s: 0.5,
        record_s: 10.0,
    };
    let fit = calibrate(&params, drive, &[-13.888, 13.888], cal).expect("fit");
    let sf = params.scale_factor_arcsec;
    let omega_l = fit.lock_in_rad_per_s * sf / std::f64::consts::TAU;
    eprintln!(
        "closed-loop fit: Omega_L {omega_l:.3} deg/h, eps {:.5} rad",
        fit.eps_rad
    );
    assert!((omega_l / 200.0 - 1.0).abs() < 0.01, "{omega_l}");
    assert!((fit.eps_rad / 0.3 - 1.0).abs() < 0.01, "{}", fit.eps_rad);
    let settings = settings_from_fit(&fit).unwrap();
    let record = RunLength {
        warmup_s: 0.5,
        record_s: 5.0,
    };
    for rate in [-2.0, 1.0, 6.0] {
        let m = measure_rate(&params, drive, rate, record, settings).expect("run");
        let ideal = rate / sf;
        let (u, c) = (
            (m.uncompensated_hz - ideal) * sf,
            (m.compensated_hz - ideal) * sf,
        );
        eprintln!("{rate:+} deg/h: uncompensated {u:+.4}, compensated {c:+.4} deg/h");
        assert!(c.abs() < 0.2, "{rate}: {c}");
    }
}
