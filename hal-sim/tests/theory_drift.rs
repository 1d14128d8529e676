//! A drifting lock-in threshold (issue 5's tracking scenario): with Omega_L(t) = Omega_L
//! (1 + r t), the per-traversal errors follow the stationary-phase formula with the *current*
//! Omega_L. Least-squares amplitude of the simulated errors against the formula with unit
//! Omega_L, in a window at the start and one at the end of a +5 % drift over 20 s: each must
//! equal Omega_L(t) at the window's centre within 0.2 % (the formula's second-order part,
//! ~(Omega_L k)^2, averages out over a window's phases to well below that).

use hal_sim::gyro::Gyro;
use hal_sim::input::InputProfile;
use hal_sim::params::GyroParams;
use hal_sim::phase::theory::traversal_error;

/// The fitted Omega_L (rad/s) of the traversals in [t0, t1].
fn fitted_lock_in(g: &mut Gyro, t0: f64, t1: f64) -> f64 {
    g.advance_to(t0);
    let _ = g.take_traversals();
    g.advance_to(t1);
    let (mut sxy, mut sxx) = (0.0, 0.0);
    for t in g.take_traversals() {
        let ta = t.turnaround;
        let unit = traversal_error(1.0, ta.psi_rad, ta.psi_ddot_rad_per_s2);
        sxy += unit * t.lockin_error_rad;
        sxx += unit * unit;
    }
    sxy / sxx
}

#[test]
fn traversal_errors_follow_a_drifting_lock_in() {
    let params = GyroParams {
        lock_in_drift_per_s: 0.05 / 20.0,
        lock_in_drift_until_s: 20.0,
        seed: 5,
        ..GyroParams::default()
    };
    let mut g = Gyro::new(params, InputProfile::constant(10.0)).unwrap();
    let early = fitted_lock_in(&mut g, 0.5, 1.5);
    let late = fitted_lock_in(&mut g, 18.5, 19.5);
    let (want_early, want_late) = (g.lock_in_rad_per_s(1.0), g.lock_in_rad_per_s(19.0));
    eprintln!(
        "fitted Omega_L: {early:.3} (true {want_early:.3}), {late:.3} (true {want_late:.3}) rad/s"
    );
    assert!((early / want_early - 1.0).abs() < 2e-3);
    assert!((late / want_late - 1.0).abs() < 2e-3);
    assert!(late / early > 1.04, "the drift shows: {}", late / early);
}
