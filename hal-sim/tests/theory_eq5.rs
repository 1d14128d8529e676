//! Without dither the mean beat rate follows Eq. 5: locked (0) for |Omega_i| <= Omega_L,
//! `sqrt(Omega_i^2 - Omega_L^2)` beyond, to 1e-4 relative, measured over whole slip periods.
//!
//! Tolerance: the RK4 error at the default step is ~1e-7 relative here and the crossing
//! instants are bisected to 1e-12 s, so 1e-4 leaves a wide margin while still failing on any
//! wrong formula (a 1 % error in Omega_L shifts the rate by 5e-2 relative at 1.02 Omega_L).

use core::f64::consts::TAU;
use hal_sim::gyro::Gyro;
use hal_sim::input::InputProfile;
use hal_sim::params::GyroParams;
use hal_sim::phase::theory::eq5_mean_rate;

fn no_dither() -> GyroParams {
    GyroParams {
        dither_amplitude_arcsec: 0.0,
        ..Default::default()
    }
}

/// Time at which `sign * psi` first reaches `sign * target`, by a coarse forward scan and a
/// bisection on clones (time is forward-only).
fn crossing_time(g: &mut Gyro, target: f64, sign: f64, dt: f64) -> f64 {
    loop {
        let before = g.clone();
        let t0 = g.t_s();
        if sign * g.advance_to(t0 + dt) >= sign * target {
            let (mut lo, mut hi) = (t0, t0 + dt);
            while hi - lo > 1e-12 {
                let mid = 0.5 * (lo + hi);
                if sign * before.clone().advance_to(mid) >= sign * target {
                    hi = mid;
                } else {
                    lo = mid;
                }
            }
            *g = before;
            g.advance_to(hi);
            return hi;
        }
    }
}

#[test]
fn unlocked_mean_rate_follows_eq5() {
    let p = no_dither();
    let omega_l = p.derive().unwrap().omega_l_rad_per_s;
    for ratio in [1.02, 1.2, 2.0, -1.5] {
        let rate_deg_h = ratio * p.lock_in_deg_per_h;
        let mut g = Gyro::new(p, InputProfile::constant(rate_deg_h)).unwrap();
        let omega_i = ratio * omega_l;
        let expect = eq5_mean_rate(omega_i, omega_l);
        let sign = expect.signum();
        let period = TAU / expect.abs();
        let dt = period / 40.0;
        let n = 5.0;
        let psi0 = g.advance_to(0.01);
        let t_a = crossing_time(&mut g, psi0 + sign * 1.0, sign, dt);
        let t_b = crossing_time(&mut g, psi0 + sign * (1.0 + TAU * n), sign, dt);
        let measured = sign * TAU * n / (t_b - t_a);
        let rel = (measured / expect - 1.0).abs();
        eprintln!("ratio {ratio}: measured {measured:.9} rad/s, Eq. 5 {expect:.9}, rel {rel:.2e}");
        assert!(
            rel < 1e-4,
            "ratio {ratio}: measured {measured}, Eq. 5 {expect}, rel {rel:e}"
        );
    }
}

#[test]
fn locked_inside_the_threshold() {
    let p = no_dither();
    for ratio in [0.5, 0.98, -0.9] {
        let mut g = Gyro::new(p, InputProfile::constant(ratio * p.lock_in_deg_per_h)).unwrap();
        let psi0 = g.advance_to(0.05);
        let psi1 = g.advance_to(0.5);
        // Locked: psi settles at a fixed point (cos psi = -Omega_i/Omega_L); unlocked at
        // 1.02 Omega_L it would move by > 60 rad in this time.
        assert!(
            (psi1 - psi0).abs() < 0.5,
            "ratio {ratio}: psi moved {}",
            psi1 - psi0
        );
    }
}
