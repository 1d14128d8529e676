//! Per traversal, the simulated lock-in phase error (change of the slow variable `chi`
//! across the near region) matches the stationary-phase formulas of docs/physics.md,
//! `Omega_L k cos(psi0+ + pi/4)` and `Omega_L k sin(psi0- + pi/4)` with `k` from the actual
//! |psi_ddot|, with correlation >= 0.999 for each kind.
//!
//! Tolerance: the formulas are first order in `Omega_L k` (~0.018 rad); the second-order
//! part is ~(Omega_L k)^2 ~ 3e-4 rad, i.e. ~2 % of the signal, which costs ~2e-4 of
//! correlation; 0.999 therefore tests the physics, and fails for Eq. 12's misprinted cos at
//! the "-" turnaround (correlation ~0). An input of 10 deg/h (outside the dead band) sweeps
//! psi0 over all phases.

use hal_sim::gyro::Gyro;
use hal_sim::input::InputProfile;
use hal_sim::params::{AmplitudeModulation, GyroParams};
use hal_sim::phase::theory::traversal_error;

fn correlation(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len() as f64;
    let (ma, mb) = (a.iter().sum::<f64>() / n, b.iter().sum::<f64>() / n);
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (x, y) in a.iter().zip(b) {
        sab += (x - ma) * (y - mb);
        saa += (x - ma) * (x - ma);
        sbb += (y - mb) * (y - mb);
    }
    sab / (saa * sbb).sqrt()
}

fn check(params: GyroParams, input_deg_h: f64) {
    let omega_l = params.derive().unwrap().omega_l_rad_per_s;
    let mut g = Gyro::new(params, InputProfile::constant(input_deg_h)).unwrap();
    g.advance_to(0.5);
    let tr = g.take_traversals();
    assert!(tr.len() > 350, "{} traversals", tr.len());
    for plus in [true, false] {
        let (sim, theory): (Vec<f64>, Vec<f64>) = tr
            .iter()
            .filter(|t| (t.turnaround.psi_ddot_rad_per_s2 > 0.0) == plus)
            .map(|t| {
                let ta = t.turnaround;
                (
                    t.lockin_error_rad,
                    traversal_error(omega_l, ta.psi_rad, ta.psi_ddot_rad_per_s2),
                )
            })
            .unzip();
        let r = correlation(&sim, &theory);
        let rms = (sim.iter().map(|x| x * x).sum::<f64>() / sim.len() as f64).sqrt();
        eprintln!(
            "{} turnarounds: n = {}, correlation {r:.9} (1 - r = {:.1e}), rms error {rms:.4} rad",
            if plus { "+" } else { "-" },
            sim.len(),
            1.0 - r
        );
        assert!(r >= 0.999, "correlation {r}");
    }
}

#[test]
fn traversal_error_matches_stationary_phase() {
    check(GyroParams::default(), 10.0);
}

#[test]
fn traversal_error_matches_with_amplitude_jitter_and_noise() {
    let p = GyroParams {
        amplitude_jitter: AmplitudeModulation::jitter(0.01),
        arw_deg_per_rt_h: 0.01,
        ..Default::default()
    };
    check(p, -7.0);
}
