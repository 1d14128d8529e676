//! The board's output (issue 13): dither stripping with the pick-off, the fixed-rate output on a
//! sync, under a wandering dither, a pick-off gain error and a lost pick-off. Seeded runs; each
//! bound is the acceptance, with the measured figure beside it.

mod common;

use firmware::dither::DitherState;
use firmware::signal::output::record::OutputStatus;
use hal_sim::dither::resonator::ResonatorParams;
use hal_sim::harness::{DriveSource, Harness, HarnessOptions};
use hal_sim::input::InputProfile;
use hal_sim::params::{AmplitudeModulation, GyroParams};
use hal_sim::pickoff::PickoffConfig;
use rlg_sim::experiment::BoardSetup;
use rlg_sim::record_run::{self, RecordRow};
use std::ops::ControlFlow;

/// The docs/physics.md set with the dither amplitude wandering 0.1 % rms at 0.1-2 Hz.
fn jittered() -> GyroParams {
    GyroParams {
        amplitude_jitter: AmplitudeModulation::jitter(0.001),
        ..GyroParams::default()
    }
}

/// `rlg-sim sweep --amplitude-jitter 0.001 --rate-min-deg-h -6 --rate-max-deg-h 6 --points 13
/// --seconds-per-point 10` (calibration as the CLI's: +-13.888 deg/h, 20 s each).
fn worst_compensated_deg_h(setup: BoardSetup) -> f64 {
    let rates: Vec<f64> = (0..13).map(|i| -6.0 + i as f64).collect();
    common::sweep_worst_deg_h(&jittered(), setup, &rates, 10.0).1
}

/// The paper's idealised dither (prescribed sine, exact latch) with amplitude jitter: the
/// stripped output's compensated deviation <= 0.01 deg/h (measured 0.0004; regression bound
/// 0.002).
#[test]
fn sweep_with_a_wandering_ideal_dither_is_within_0_01_deg_h() {
    let setup = BoardSetup {
        sync_hz: Some(1000.0),
        ..BoardSetup::IDEAL
    };
    let worst = worst_compensated_deg_h(setup);
    eprintln!("ideal dither, exact latch: worst {worst:.5} deg/h");
    assert!(worst <= 0.01, "{worst}");
    assert!(worst <= 0.002, "regression: {worst}");
}

/// The realistic board (the firmware's drive, scheduled latch, 1 kHz sync), its drive's gain
/// wandering 0.1 % rms at 0.1-2 Hz (the same jitter, which the amplitude loop holds the
/// amplitude against): <= 0.01 deg/h (measured 0.0004; regression bound 0.002).
#[test]
fn sweep_on_the_realistic_board_is_within_0_01_deg_h() {
    let worst = worst_compensated_deg_h(BoardSetup::board(0.0, 1000.0));
    eprintln!("closed-loop drive, scheduled latch: worst {worst:.5} deg/h");
    assert!(worst <= 0.01, "{worst}");
    assert!(worst <= 0.002, "regression: {worst}");
}

/// `rlg-sim record --sync-hz 1000` on the realistic board (not commensurate with the 389 Hz
/// dither): the dither tone in the stripped output >= 60 dB below the unstripped output's
/// (measured: see the test's output), and the rms of (board - true) per record far below the
/// floor one pick-off conversion per latch would set.
#[test]
fn record_strips_the_dither_tone_and_sits_at_the_noise_floor() {
    let params = GyroParams::default();
    let setup = BoardSetup::board(0.0, 1000.0);
    let mut rows: Vec<RecordRow> = Vec::new();
    let summary = record_run::record(&params, setup, 5.0, 0.5, 10.0, Default::default(), |r| {
        rows.push(*r);
        ControlFlow::Continue(())
    })
    .expect("record");
    assert_eq!(summary.invalid_rows, 0);
    assert!(rows.len() >= 9990, "{} rows", rows.len());
    let stripped: Vec<f64> = rows.iter().map(|r| r.delta_angle_arcsec).collect();
    let truth: Vec<f64> = rows.iter().map(|r| r.true_delta_angle_arcsec).collect();
    // The unstripped output's tone: the count follows the dither angle, so its increments at
    // 1 kHz carry the dither's increment, 2 A sin(pi f / f_sync) (A = 450 arcsec held by the
    // drive, f = 389 Hz).
    let dither_tone_arcsec = 2.0 * 450.0 * (std::f64::consts::PI * 389.0 / 1000.0).sin();
    let residual: Vec<f64> = stripped.iter().zip(&truth).map(|(s, t)| s - t).collect();
    let stripped_tone = common::tone_amplitude(&residual, 1000.0, 389.0);
    let ratio_db = 20.0 * (dither_tone_arcsec / stripped_tone).log10();
    // One conversion per latch would set the floor: 1 mV rms noise on 0.806 mV codes, plus
    // the code's quantisation (1/12 LSB^2), at 0.4 arcsec per code; a record is the difference
    // of two latches: sqrt(2) x, 0.72 arcsec. The model of the 40 kHz stream (384 samples per
    // fit) takes sqrt(2 / 384) of a conversion's noise at each latch; consecutive latches share
    // most of a fit. Measured: 0.072 arcsec; bound 0.1 (a tenth of the one-conversion floor
    // with room), regression 0.08.
    let lsb_v = 3.3 / 4096.0;
    let pickoff = PickoffConfig::default();
    let codes_rms = ((pickoff.noise_rms_v / lsb_v).powi(2) + 1.0 / 12.0).sqrt();
    let one_conversion = 2f64.sqrt() * codes_rms * 0.4;
    eprintln!(
        "dither tone: unstripped {dither_tone_arcsec:.1} arcsec, stripped {stripped_tone:.4} arcsec \
         ({ratio_db:.1} dB); rms(board - true) {:.4} arcsec (one conversion per latch: \
         {one_conversion:.4}); K {:?}",
        summary.rms_error_arcsec, summary.strip
    );
    assert!(ratio_db >= 60.0, "{ratio_db} dB");
    assert!(ratio_db >= 90.0, "regression: {ratio_db} dB");
    assert!(
        summary.rms_error_arcsec <= 0.1,
        "{}",
        summary.rms_error_arcsec
    );
    assert!(
        summary.rms_error_arcsec <= 0.08,
        "regression: {}",
        summary.rms_error_arcsec
    );
    assert!(summary.strip.converged);
}

/// A pick-off that lags the dither by 5 us (0.7 deg at 389 Hz) and reads 5 % low: one K would
/// leave the quadrature, 2 A sin(pi f/f_s) w tau = 10 arcsec of tone (-38 dB); the quadrature
/// tap takes it out (>= 60 dB below the unstripped output, measured: see the output), the rms
/// stays at the model's floor, and the tap gives back the lag (to 0.05 us; measured 5.00 us)
/// that the turnaround schedule subtracts.
#[test]
fn a_lagging_pickoff_with_a_gain_error_is_stripped_too() {
    let params = GyroParams::default();
    let setup = BoardSetup {
        pickoff_lag_s: 5e-6,
        pickoff_gain_error: -0.05,
        ..BoardSetup::board(0.0, 1000.0)
    };
    let mut rows: Vec<RecordRow> = Vec::new();
    let summary = record_run::record(&params, setup, 5.0, 0.5, 10.0, Default::default(), |r| {
        rows.push(*r);
        ControlFlow::Continue(())
    })
    .expect("record");
    let residual: Vec<f64> = rows
        .iter()
        .map(|r| r.delta_angle_arcsec - r.true_delta_angle_arcsec)
        .collect();
    let dither_tone_arcsec = 2.0 * 450.0 * (std::f64::consts::PI * 389.0 / 1000.0).sin();
    let stripped_tone = common::tone_amplitude(&residual, 1000.0, 389.0);
    let ratio_db = 20.0 * (dither_tone_arcsec / stripped_tone).log10();
    eprintln!(
        "lagging pick-off: tone {stripped_tone:.4} arcsec ({ratio_db:.1} dB), rms {:.4}, {:?}",
        summary.rms_error_arcsec, summary.strip
    );
    assert!(ratio_db >= 60.0, "{ratio_db} dB");
    // The floor scales with the pick-off's codes per arcsec: 5 % fewer codes, 5 % more arcsec
    // per code of noise (measured 0.076 arcsec).
    assert!(
        summary.rms_error_arcsec < 0.1,
        "{}",
        summary.rms_error_arcsec
    );
    let lag_s = summary
        .strip
        .pickoff_lag_s((std::f64::consts::TAU * 389.0) as f32)
        .expect("converged");
    assert!((lag_s as f64 - 5e-6).abs() < 5e-8, "{lag_s} s");
    assert!(
        summary.strip.k_quadrature.abs() > 1e-4,
        "{:?}",
        summary.strip
    );
}

/// A board whose pick-off reads 5 % off its nominal sensitivity: K starts 5 % wrong and is
/// within 0.05 % of the truth in <= 10 s (measured: see the output; the fit replaces the
/// starting K after 64 latches).
#[test]
fn k_converges_from_a_five_percent_error() {
    let params = GyroParams::default();
    let mut options =
        HarnessOptions::new(params, InputProfile::constant(5.0)).sync_hz(Some(1000.0));
    // True sensitivity k (1 + g): K_true = nominal / (1 + g) = 1.05 nominal.
    options.board.pickoff.gain_error = 1.0 / 1.05 - 1.0;
    let mut h = options.build().expect("harness");
    let config = *h.config();
    let k_true = config.output.strip.initial_k as f64 * 1.05;
    let mut within_since: Option<f64> = None;
    h.run_until(12.0, |h, _| {
        let k = h.readout().strip_status(&config).k as f64;
        let ok = (k / k_true - 1.0).abs() <= 5e-4;
        match (ok, within_since) {
            (true, None) => within_since = Some(h.time_s()),
            (false, Some(_)) => within_since = None,
            _ => {}
        }
    });
    let status = h.readout().strip_status(&config);
    eprintln!("K within 0.05 % from {within_since:?} s on; {status:?}, truth {k_true}");
    let t = within_since.expect("converges");
    assert!(t <= 10.0, "{t}");
    assert!(t <= 0.5, "regression: {t}");
    assert!(status.converged);
    assert!((status.k as f64 / k_true - 1.0).abs() < 1e-4, "{status:?}");
}

fn locked_board() -> Harness {
    let params = GyroParams::default().with_steady_driven_dither(ResonatorParams::default());
    let mut h = HarnessOptions::new(params, InputProfile::constant(13.888))
        .drive(DriveSource::firmware(&params).unwrap())
        .sync_hz(Some(1000.0))
        .build()
        .unwrap();
    while h.firmware_drive().unwrap().controller().state() != DitherState::Locked {
        assert!(h.time_s() < 3.0, "locks");
        h.step();
    }
    h.run_until(h.time_s() + 0.5, |_, _| {});
    h
}

/// The pick-off lost: every record after the dither supervisor's detection (3 periods) is
/// invalid, and no record is valid with an error beyond the innovation gate's 100 fringes
/// (187 arcsec) in between; the records before the loss are valid.
#[test]
fn a_lost_pickoff_marks_the_records_invalid() {
    let mut h = locked_board();
    let sf = h.gyro().params().scale_factor_arcsec;
    let lost_at = h.time_s();
    let mut last_truth = None;
    let (mut valid_before, mut invalid_after, mut valid_after_detection) = (0, 0, 0);
    h.run_until(lost_at + 0.1, |h, _| {
        valid_before += h.outputs().iter().filter(|(_, r)| r.is_valid()).count();
        last_truth = h
            .outputs()
            .last()
            .map(|(l, _)| l.true_angle_arcsec)
            .or(last_truth);
    });
    let lost_at = h.time_s();
    let mut worst_valid_error_arcsec: f64 = 0.0;
    let mut run = |h: &mut Harness, lost: bool, until: f64| {
        h.board_mut().pickoff_mut().set_lost(lost);
        let lost_at = h.time_s();
        h.run_until(until, |h, _| {
            for (latch, r) in h.outputs() {
                let truth = latch.true_angle_arcsec - last_truth.unwrap_or(latch.true_angle_arcsec);
                last_truth = Some(latch.true_angle_arcsec);
                if latch.t_s < lost_at {
                    valid_before += usize::from(r.is_valid());
                    continue;
                }
                if r.is_valid() {
                    let e = (r.delta_angle_fringes() * sf - truth).abs();
                    worst_valid_error_arcsec = worst_valid_error_arcsec.max(e);
                    if latch.t_s > lost_at + 3.0 / 389.0 {
                        valid_after_detection += 1;
                    }
                } else {
                    invalid_after += 1;
                }
            }
        });
    };
    run(&mut h, true, lost_at + 0.5);
    eprintln!(
        "valid before {valid_before}, invalid after {invalid_after}, valid after detection \
         {valid_after_detection}, worst valid error after the loss {worst_valid_error_arcsec:.1} arcsec"
    );
    assert!(valid_before >= 95, "{valid_before}");
    assert_eq!(valid_after_detection, 0);
    assert!(invalid_after > 490, "{invalid_after}");
    assert!(
        worst_valid_error_arcsec <= 100.0 * sf,
        "{worst_valid_error_arcsec}"
    );
}

/// The encoder register jumps: a jump beyond what the count can move between reads is a
/// counter glitch (stage 1); a smaller one, indistinguishable from motion at the count, breaks
/// the innovation gate. Either way the period is invalid, the integrated angle holds, and the
/// chain restarts at the next latch.
#[test]
fn a_counter_jump_invalidates_its_period_and_holds_the_angle() {
    for (jump, expected) in [
        (100_000, OutputStatus::COUNTER_GLITCH),
        (1_000, OutputStatus::PICKOFF_FAULT),
    ] {
        let mut h = locked_board();
        h.run_until(h.time_s() + 0.1, |_, _| {});
        let angle_before = h.outputs().last().map(|(_, r)| r.angle_q16).unwrap();
        h.board_mut().counter_mut().inject_counts(jump);
        let mut seen = Vec::new();
        h.run_until(h.time_s() + 0.05, |h, _| {
            seen.extend(h.outputs().iter().map(|(_, r)| (r.status, r.angle_q16)));
        });
        let (status, angle) = seen[0];
        assert!(
            status.contains(expected) && !status.contains(OutputStatus::VALID),
            "jump {jump}: {:?}",
            &seen[..3]
        );
        assert_eq!(angle, angle_before, "jump {jump}");
        // The count resynchronises within its 3 reads; the chain restarts after it: at most
        // three periods are lost (measured: 3 for the big jump, 2 for the small one), each
        // holding the angle.
        let lost = seen
            .iter()
            .take_while(|(s, _)| !s.contains(OutputStatus::VALID));
        assert!(lost.clone().all(|&(_, a)| a == angle_before), "jump {jump}");
        assert!(lost.count() <= 3, "jump {jump}: {:?}", &seen[..5]);
        assert!(
            seen.iter()
                .skip(3)
                .all(|(s, _)| s.contains(OutputStatus::VALID)),
            "jump {jump}: {seen:?}"
        );
    }
}
