//! Chow's dead band measured on the simulated gyro, shared by `theory_chow.rs` (the prescribed
//! sine) and `theory_chow_driven.rs` (the driven resonator): the mean output over whole slip
//! periods (docs/physics.md pitfall 6), and the band fitted from it.

use core::f64::consts::TAU;
use firmware::sample::TurnaroundKind;
use hal_sim::gyro::Turnaround;
use hal_sim::units::{beat_rad_per_s_to_deg_per_h, deg_per_h_to_beat_rad_per_s};

/// Mean output (rad/s of beat phase) over `slips` whole slip periods, from the beat phase at
/// the "+" turnarounds `next` yields (once per dither cycle, the same dither phase each time),
/// after 20 ms of warm-up.
pub fn mean_output(mut next: impl FnMut() -> Turnaround, slips: f64) -> f64 {
    let mut plus = Vec::new();
    while plus.len() < 200_000 {
        let t = next();
        if t.time_s < 0.02 || t.kind != TurnaroundKind::Plus {
            continue;
        }
        plus.push((t.time_s, t.psi_rad));
        let (t0, psi0) = plus[0];
        let target = TAU * slips;
        let moved = (t.psi_rad - psi0).abs();
        if moved >= target {
            let (ta, pa) = plus[plus.len() - 2];
            let frac = (target - (pa - psi0).abs()) / (moved - (pa - psi0).abs());
            let t_star = ta + frac * (t.time_s - ta);
            return (t.psi_rad - psi0).signum() * target / (t_star - t0);
        }
    }
    panic!("no slip within 200 000 cycles");
}

/// The band fitted at 1.5, 2, 3 and -2 times Chow's band `chow_rad_per_s` (Eq. 10:
/// `Omega_L0^2 = mean(Omega_i^2 - out^2)`), relative to it; `output(input_deg_h)` is the mean
/// output there (rad/s of beat phase). Prints each point.
pub fn fitted_band_relative(
    chow_rad_per_s: f64,
    scale_factor_arcsec: f64,
    mut output: impl FnMut(f64) -> f64,
) -> f64 {
    let sf = scale_factor_arcsec;
    let chow_deg_h = beat_rad_per_s_to_deg_per_h(chow_rad_per_s, sf);
    let ratios = [1.5, 2.0, 3.0, -2.0];
    let mut sum = 0.0;
    for r in ratios {
        let input = r * chow_deg_h;
        let wi = deg_per_h_to_beat_rad_per_s(input, sf);
        let out = output(input);
        let band2 = wi * wi - out * out;
        eprintln!(
            "  input {input:+.4} deg/h: output {:+.5} deg/h, implied band {:.5} deg/h",
            beat_rad_per_s_to_deg_per_h(out, sf),
            beat_rad_per_s_to_deg_per_h(band2.max(0.0).sqrt(), sf)
        );
        sum += band2;
    }
    let fit = (sum / ratios.len() as f64).sqrt();
    let rel = fit / chow_rad_per_s - 1.0;
    eprintln!(
        "Chow band {chow_deg_h:.5} deg/h, fitted {:.5} deg/h, rel {rel:+.2e}",
        beat_rad_per_s_to_deg_per_h(fit, sf)
    );
    rel
}

/// Asserts that the beat phase at the "+" turnaround after `a` (`psi_a`, rad) and the one after
/// `b` one second later (`psi_b`) are the same to 0.5 rad (modulo a fringe) and have not slipped:
/// locked. Unlocked, even a tenth of the band of output would move it by more than 1 rad.
pub fn assert_locked(psi_a: f64, psi_b: f64) {
    let moved = psi_b - psi_a;
    assert!(
        (moved / TAU - (moved / TAU).round()).abs() * TAU < 0.5 && moved.abs() < 1.0,
        "moved {moved}"
    );
}
