//! The driven dither inside the gyro: the drive horizon, independence of how drive and
//! advancing interleave, and the phase integrator's accuracy against the brute-force reference
//! with drive segments that change at the turnarounds.

use hal_sim::dither::drive::{DriveError, DriveSegment, DriveSink};
use hal_sim::dither::open_loop::OpenLoopDrive;
use hal_sim::dither::resonator::ResonatorParams;
use hal_sim::gyro::{Gyro, Turnaround};
use hal_sim::input::InputProfile;
use hal_sim::params::GyroParams;
use hal_sim::phase::free_phase::FreePhase;
use hal_sim::phase::reference::Reference;

fn driven_params() -> GyroParams {
    GyroParams::default().with_steady_driven_dither(ResonatorParams::default())
}

/// The open-loop drive's segment `k` with the amplitude changed by +-1 % (alternating), so
/// that the jets really jump at every segment start.
fn wobbling(drive: &OpenLoopDrive, k: u64) -> DriveSegment {
    let s = drive.segment(k);
    let gain = if k.is_multiple_of(2) { 1.0 } else { 1.01 };
    DriveSegment {
        amplitude_v: s.amplitude_v * gain,
        ..s
    }
}

/// The gyro never goes beyond the drive it was given, refuses drive in the past, and goes on
/// when more drive comes; the prescribed sine takes no drive.
#[test]
fn the_drive_horizon_is_respected() {
    let p = driven_params();
    let drive = p.open_loop_drive().unwrap();
    let mut g = Gyro::new(p, InputProfile::constant(5.0)).unwrap();
    assert_eq!(g.drive_known_until_s(), 0.0);
    assert!(g.try_advance_to(1e-3).is_err());
    assert!(g.try_upcoming_turnaround().is_none());
    g.advance_to(0.0);
    g.push_drive(drive.segment(0)).unwrap();
    g.extend_drive_until(0.004).unwrap();
    assert!(g.try_advance_to(0.0041).is_err());
    // The turnarounds of the pieces known to their end (a piece lasts at most one nominal
    // period, 2.57 ms: the first, with the turnarounds at 0.08 and 1.36 ms) are reported;
    // the next piece is not complete, so no more (advancing still passes them).
    let mut turns = 0;
    while g.try_next_turnaround().is_some() {
        turns += 1;
    }
    assert_eq!(turns, 2);
    assert!(g.t_s() < 0.004);
    let psi = g.try_advance_to(0.004).unwrap();
    assert!(psi.is_finite() && g.t_s() == 0.004);
    // Drive in the past is refused; at the horizon it is taken.
    let late = drive.segment(5);
    let past = DriveSegment {
        start_s: 0.003,
        ..late
    };
    assert!(matches!(
        g.push_drive(past),
        Err(DriveError::InThePast { .. })
    ));
    assert!(matches!(
        g.push_drive(DriveSegment {
            step_rad: 4.0,
            ..late
        }),
        Err(DriveError::Invalid(_))
    ));
    g.push_drive(DriveSegment {
        start_s: 0.004,
        ..drive.segment(4)
    })
    .unwrap();
    g.extend_drive_until(0.02).unwrap();
    g.advance_to(0.02);
    let mut ideal = Gyro::new(GyroParams::default(), InputProfile::constant(5.0)).unwrap();
    assert_eq!(ideal.push_drive(late), Err(DriveError::NotDriven));
    assert_eq!(ideal.drive_known_until_s(), f64::INFINITY);
}

/// Runs `seconds` of the driven gyro, pushing the wobbling drive `lead_s` ahead (0: the
/// segments started by then, and the last one extended exactly to the time advanced to, so
/// pieces are cut at the horizon), advancing in steps of `step_s`; returns every turnaround
/// (of the traversals completed).
fn run(lead_s: f64, step_s: f64, seconds: f64) -> Vec<Turnaround> {
    let p = driven_params();
    let drive = p.open_loop_drive().unwrap();
    let mut g = Gyro::new(p, InputProfile::constant(5.0)).unwrap();
    let mut k = 0;
    let mut t = 0.0;
    let mut turns: Vec<Turnaround> = Vec::new();
    while t < seconds {
        t = (t + step_s).min(seconds);
        if lead_s == 0.0 {
            while wobbling(&drive, k).start_s <= t {
                g.push_drive(wobbling(&drive, k)).unwrap();
                k += 1;
            }
            g.extend_drive_until(t).unwrap();
        }
        while g.drive_known_until_s() < t + lead_s {
            g.push_drive(wobbling(&drive, k)).unwrap();
            k += 1;
        }
        g.advance_to(t);
        turns.extend(g.take_traversals().iter().map(|x| x.turnaround));
    }
    turns
}

/// With the lead of `drive_lead_s` (two periods), the results do not depend on how far ahead
/// the drive is pushed or how the gyro is advanced: bit for bit. With no lead at all (pieces
/// cut at the horizon, one more far-field boundary each time) the beat phase at every
/// turnaround stays within 1e-7 rad (the far series' boundary error is ~1e-8; measured 1e-11).
#[test]
fn results_do_not_depend_on_how_the_drive_is_fed() {
    let seconds = 0.2;
    let lead = 2.0 / 389.0;
    let a = run(lead, 0.5 / 389.0, seconds);
    let b = run(0.05, 0.0137, seconds);
    assert_eq!(a.len(), b.len());
    assert!(a.len() > 150, "{}", a.len());
    for (x, y) in a.iter().zip(&b) {
        assert_eq!(x.time_s.to_bits(), y.time_s.to_bits());
        assert_eq!(x.psi_rad.to_bits(), y.psi_rad.to_bits(), "{x:?} vs {y:?}");
    }
    let c = run(0.0, 0.4 / 389.0, seconds);
    assert_eq!(a.len(), c.len());
    let worst = a
        .iter()
        .zip(&c)
        .fold(0.0f64, |m, (x, y)| m.max((x.psi_rad - y.psi_rad).abs()));
    eprintln!("no lead vs two periods: {worst:.2e} rad at the turnarounds");
    assert!(worst < 1e-7, "{worst}");
    // Regression (measured 1e-11).
    assert!(worst < 1e-10, "{worst}");
}

/// A driven gyro with angle random walk (0.05 deg/sqrt(h)).
fn noisy_params() -> GyroParams {
    GyroParams {
        arw_deg_per_rt_h: 0.05,
        ..GyroParams::default()
    }
    .with_steady_driven_dither(ResonatorParams::default())
}

/// How [`run_noisy`] feeds the drive.
#[derive(Clone, Copy)]
enum Feed {
    /// Pushed this far ahead of every time advanced to, s.
    Lead(f64),
    /// Only until the gyro's horizon ([`Gyro::known_until_s`]: the noise horizon, less than 3/4
    /// of a period before the drive's) reaches the time advanced to, with the last segment
    /// extended half-way to the next start before each push.
    Minimal,
}

/// Runs `seconds` of the driven gyro with noise and the wobbling `drive`, fed as `feed` says,
/// advancing in steps of `step_s`; returns every turnaround (of the traversals completed).
fn run_noisy(drive: &OpenLoopDrive, feed: Feed, step_s: f64, seconds: f64) -> Vec<Turnaround> {
    let mut g = Gyro::new(noisy_params(), InputProfile::constant(5.0)).unwrap();
    let mut k = 0;
    let mut t = 0.0;
    let mut turns: Vec<Turnaround> = Vec::new();
    while t < seconds {
        t = (t + step_s).min(seconds);
        match feed {
            Feed::Lead(lead_s) => {
                while g.drive_known_until_s() < t + lead_s {
                    g.push_drive(wobbling(drive, k)).unwrap();
                    k += 1;
                }
            }
            Feed::Minimal => {
                while g.known_until_s() < t {
                    let next = wobbling(drive, k);
                    let half_way = 0.5 * (g.drive_known_until_s() + next.start_s);
                    g.extend_drive_until(half_way).unwrap();
                    g.push_drive(next).unwrap();
                    k += 1;
                }
                assert!(g.known_until_s() <= g.drive_known_until_s());
            }
        }
        g.advance_to(t);
        turns.extend(g.take_traversals().iter().map(|x| x.turnaround));
    }
    turns
}

/// With the noise on, the noise steps snap to the drive's segment starts (`hal_sim::noise`)
/// and a noise segment is used only once the drive decides its end: the results do not depend
/// on the lead or on how the gyro is advanced, bit for bit, even with the drive fed only as far
/// as the gyro's horizon (no piece is ever cut at a horizon: every piece ends at or before its
/// noise segment's decided end). Both with the open-loop drive (segment starts ~3 ticks after
/// the nominal noise grid: every boundary snaps) and with a drive at 392 Hz (its starts slide
/// through the snap windows: about half of the boundaries snap).
#[test]
fn results_with_noise_do_not_depend_on_how_the_drive_is_fed() {
    let p = noisy_params();
    let r = *p.resonator().unwrap();
    let seconds = 0.2;
    let lead = 2.0 / 389.0;
    for drive in [
        p.open_loop_drive().unwrap(),
        OpenLoopDrive::tuned(&r, 392.0, 450.0),
    ] {
        let a = run_noisy(&drive, Feed::Lead(lead), 0.5 / 389.0, seconds);
        assert!(a.len() > 150, "{}", a.len());
        for (feed, step) in [
            (Feed::Lead(0.05), 0.0137),
            (Feed::Minimal, 0.4 / 389.0),
            (Feed::Minimal, 0.0137),
        ] {
            let b = run_noisy(&drive, feed, step, seconds);
            assert_eq!(a.len(), b.len());
            for (x, y) in a.iter().zip(&b) {
                assert_eq!(x.time_s.to_bits(), y.time_s.to_bits());
                assert_eq!(x.psi_rad.to_bits(), y.psi_rad.to_bits(), "{x:?} vs {y:?}");
            }
        }
    }
}

/// With the noise on the gyro goes no further than its horizon: the drive's, or the noise
/// horizon when a noise segment's end is not decided yet (less than 3/4 of a period before);
/// it goes on when more drive decides it. Without noise the horizon is the drive's.
#[test]
fn the_noise_horizon_is_respected() {
    let p = noisy_params();
    let drive = p.open_loop_drive().unwrap();
    let mut g = Gyro::new(p, InputProfile::constant(5.0)).unwrap();
    assert_eq!(g.known_until_s(), 0.0);
    g.push_drive(drive.segment(0)).unwrap();
    g.extend_drive_until(0.0015).unwrap();
    // The first noise boundary (nominal T/4 = 0.643 ms) waits for a drive start in
    // [T/8, 3T/8) or for the drive to pass 3T/8 = 0.964 ms: decided at its nominal time.
    let t4 = 0.25 / 389.0;
    assert_eq!(g.known_until_s(), t4);
    assert!(g.try_advance_to(0.001).is_err());
    assert!(g.try_advance_to(t4).is_ok());
    // Each start of the open-loop drive decides the noise boundary it lies near (3 ticks
    // after the nominal one): the horizons coincide. A drive known past that start, but not
    // up to the next one, leaves the next noise segment open.
    let mut g = Gyro::new(p, InputProfile::constant(5.0)).unwrap();
    let mut k = 0;
    while g.drive_known_until_s() < 0.02 {
        g.push_drive(drive.segment(k)).unwrap();
        k += 1;
    }
    assert_eq!(g.known_until_s(), g.drive_known_until_s());
    g.extend_drive_until(g.drive_known_until_s() + 1e-3)
        .unwrap();
    let (known, drive_known) = (g.known_until_s(), g.drive_known_until_s());
    assert!(known < drive_known && known > drive_known - 0.75 / 389.0);
    let err = g.try_advance_to(drive_known).unwrap_err();
    assert_eq!(err.known_until_s, known);
    g.advance_to(known);
    // More drive decides the open segment.
    g.push_drive(drive.segment(k)).unwrap();
    g.push_drive(drive.segment(k + 1)).unwrap();
    assert!(g.known_until_s() > known);
    g.advance_to(g.known_until_s());
    let quiet = Gyro::new(driven_params(), InputProfile::constant(5.0)).unwrap();
    assert_eq!(quiet.known_until_s(), 0.0);
}

/// The fast integrator against the brute-force reference (RK4 on Eq. 6 with the exact
/// driven dither at every stage, 0.01 rad of beat phase per step, itself converged: 0.02
/// agrees to < 1e-10 rad), with drive segments starting at the turnarounds (inside the near
/// regions) and the amplitude changing by 1 % at each: the per-traversal error at the default
/// settings must stay within the prescribed sine's bound, 2.4e-7 rad
/// (`tests/theory_convergence.rs`; measured 1.3e-8 there and here).
#[test]
fn the_integrator_is_exact_with_the_driven_dither() {
    let p = driven_params();
    let r = p.resonator().copied().unwrap();
    // Segment starts at the drive phase where the angle has its extremes (turnarounds).
    let h = r.dac_to_angle(389.0, 0.0);
    let drive = p
        .open_loop_drive()
        .unwrap()
        .with_boundaries_at_drive_phase(core::f64::consts::FRAC_PI_2 - h.arg());
    let input = InputProfile::constant(5.0);
    let horizon = 12.0 / (2.0 * 389.0);
    let mut g = Gyro::new(p, input.clone()).unwrap();
    let mut k = 0;
    while g.drive_known_until_s() < horizon + 0.01 {
        g.push_drive(wobbling(&drive, k)).unwrap();
        k += 1;
    }
    // Compare in the far region: half-way between turnarounds.
    let mut turns = Vec::new();
    while turns.len() < 12 {
        turns.push(g.next_turnaround().time_s);
    }
    let starts: Vec<f64> = (0..k).map(|j| drive.segment(j).start_s).collect();
    let near_turn = turns
        .iter()
        .filter(|&&t| starts.iter().any(|&s| s > t && s - t < 52e-6))
        .count();
    // A segment starts at the first tick (50 us) after each turnaround: in its near region.
    assert!(
        near_turn >= 11,
        "segment starts near {near_turn} turnarounds"
    );
    let times: Vec<f64> = turns.windows(2).map(|w| 0.5 * (w[0] + w[1])).collect();
    let reference = |dtheta: f64| {
        let d = p.derive().unwrap();
        let mut fp = FreePhase::new(&p, &d, input.clone());
        for j in 0..k {
            let driven = fp.dither_mut().driven_mut().unwrap();
            driven.push(wobbling(&drive, j)).unwrap();
        }
        let mut r = Reference::new(&fp, d.omega_l_rad_per_s, 0.0, 0.0, dtheta, 1e-6);
        times.iter().map(|&t| r.advance_to(t)).collect::<Vec<f64>>()
    };
    let fine = reference(0.01);
    let coarse = reference(0.02);
    let mut fast = Gyro::new(p, input.clone()).unwrap();
    for j in 0..k {
        fast.push_drive(wobbling(&drive, j)).unwrap();
    }
    let got: Vec<f64> = times.iter().map(|&t| fast.advance_to(t)).collect();
    let diff = |a: &[f64], b: &[f64]| -> Vec<f64> { a.iter().zip(b).map(|(x, y)| x - y).collect() };
    let ref_err = diff(&coarse, &fine)
        .iter()
        .fold(0.0f64, |m, x| m.max(x.abs()));
    let d = diff(&got, &fine);
    let per_traversal = d
        .windows(2)
        .fold(d[0].abs(), |m, w| m.max((w[1] - w[0]).abs()));
    eprintln!(
        "reference converged to {ref_err:.1e} rad; fast vs reference: {per_traversal:.2e} rad \
         per traversal"
    );
    assert!(ref_err < 1e-10, "{ref_err}");
    assert!(per_traversal <= 2.4e-7, "{per_traversal}");
    // Regression (measured 5.8e-9).
    assert!(per_traversal <= 2e-8, "{per_traversal}");
}

/// The gyro is a drive sink like any other: `keep_ahead` feeds it.
#[test]
fn open_loop_drive_keeps_a_gyro_fed() {
    let p = driven_params();
    let mut drive = p.open_loop_drive().unwrap();
    let mut g = Gyro::new(p, InputProfile::constant(-3.0)).unwrap();
    let lead = g.drive_lead_s();
    for _ in 0..400 {
        let until = g.t_s() + lead;
        drive.keep_ahead(&mut g, until).unwrap();
        assert!(DriveSink::drive_known_until_s(&g) >= until);
        let t = g.next_turnaround();
        // The steady 450 arcsec dither: psi_ddot = A w^2 (to the input's share, 1e-9).
        let d = p.derive().unwrap();
        let expect = d.dither_amp_rad * d.dither_w_rad_per_s.powi(2);
        assert!(
            (t.psi_ddot_rad_per_s2.abs() / expect - 1.0).abs() < 1e-8,
            "{t:?}"
        );
    }
}

/// A drifting resonance (a 10 K ramp in 0.2 s: f0 -0.4 Hz, Q -5 %, refreshed every 10 ms)
/// under an open-loop drive: the gyro runs through every split (a breakpoint each), its
/// turnarounds alternate, one per half cycle, and the dither heads down the Lorentzian (to
/// 194.5 arcsec at the new resonance, `tests/dither_resonator.rs`; slowly: tau = 0.8 s).
#[test]
fn a_drifting_resonance_keeps_the_gyro_running() {
    use hal_sim::dither::resonator::{TemperatureDrift, TemperatureProfile};
    let r = ResonatorParams {
        temperature: TemperatureDrift {
            profile: TemperatureProfile::ramp(0.0, 25.0, 0.2, 35.0).unwrap(),
            f0_hz_per_c: -0.04,
            q_relative_per_c: -0.005,
            ..TemperatureDrift::NONE
        },
        ..Default::default()
    };
    let p = GyroParams::default().with_steady_driven_dither(r);
    let mut drive = p.open_loop_drive().unwrap();
    let mut g = Gyro::new(p, InputProfile::constant(5.0)).unwrap();
    let lead = g.drive_lead_s();
    let mut last: Option<Turnaround> = None;
    let mut n = 0;
    while g.t_s() < 0.3 {
        let until = g.t_s() + lead;
        drive.keep_ahead(&mut g, until).unwrap();
        let t = g.next_turnaround();
        if let Some(l) = last {
            assert_ne!(l.kind, t.kind);
            let half = t.time_s - l.time_s;
            assert!((half * 2.0 * 389.0 - 1.0).abs() < 1e-3, "{half}");
        }
        last = Some(t);
        n += 1;
    }
    assert!(n >= 233, "{n}");
    let state = g.dither_state(g.t_s()).unwrap();
    let rate_amp = state.rate_arcsec_per_s.abs() / (core::f64::consts::TAU * 389.0);
    let amp = state.angle_arcsec.hypot(rate_amp);
    eprintln!("{n} turnarounds; dither {amp:.2} arcsec at 0.3 s");
    assert!(amp < 445.0 && amp > 194.5, "{amp}");
}

/// The driven model's own checks: the nominal dither frequency within a factor 4 of f0, and
/// the resonator's ranges.
#[test]
fn driven_parameters_are_validated() {
    let ok = GyroParams::default().with_steady_driven_dither(ResonatorParams::default());
    assert!(ok.derive().is_ok());
    for bad in [
        GyroParams {
            dither_hz: 60.0,
            ..ok
        },
        GyroParams {
            dither_hz: 0.0,
            ..ok
        },
        GyroParams::default().with_steady_driven_dither(ResonatorParams {
            q: 1.0,
            ..Default::default()
        }),
    ] {
        assert!(bad.derive().is_err(), "{:?}", bad.dither_model);
        assert!(Gyro::new(bad, InputProfile::constant(0.0)).is_err());
    }
}
