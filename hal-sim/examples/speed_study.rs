//! Speed against accuracy of the phase integrator for one solver setting, at the
//! docs/physics.md set and 5 deg/h: gyro-seconds per wall-second over 2 gyro-seconds, and the
//! worst per-traversal error against the converged reference (RK4 at 0.01 rad per step)
//! over 10 half cycles, measured as in `tests/theory_convergence.rs`.
//!
//! ```text
//! cargo run --release -p hal-sim --example speed_study -- [dtheta_rad] [far_threshold_rad_per_s]
//! ```
//!
//! Defaults: the solver's defaults. The tradeoffs in `src/phase/near.rs` were measured with it.

use hal_sim::gyro::{Gyro, Speed};
use hal_sim::input::InputProfile;
use hal_sim::params::GyroParams;
use hal_sim::phase::free_phase::FreePhase;
use hal_sim::phase::reference::Reference;
use std::process::ExitCode;

fn main() -> ExitCode {
    let mut p = GyroParams::default();
    let args: Vec<String> = std::env::args().skip(1).collect();
    let parsed: Result<Vec<f64>, _> = args.iter().map(|a| a.parse::<f64>()).collect();
    let Ok(values) = parsed else {
        eprintln!("usage: speed_study [dtheta_rad] [far_threshold_rad_per_s]");
        return ExitCode::from(2);
    };
    if let Some(&d) = values.first() {
        p.solver.step_phase_rad = d;
    }
    if let Some(&f) = values.get(1) {
        p.solver.far_threshold_rad_per_s = f;
    }
    let input = InputProfile::constant(5.0);
    let mut g = match Gyro::new(p, input.clone()) {
        Ok(g) => g,
        Err(e) => {
            eprintln!("speed_study: invalid solver setting: {e:?}");
            return ExitCode::from(2);
        }
    };
    let speed = Speed::of(2.0, || {
        g.advance_to(2.0);
    })
    .gyro_s_per_wall_s;

    let d = p.derive().expect("checked by Gyro::new");
    let fp = FreePhase::new(&p, &d, input.clone());
    let mut r = Reference::new(&fp, d.omega_l_rad_per_s, 0.0, p.initial_psi_rad, 0.01, 1e-6);
    let mut g = Gyro::new(p, input).expect("checked above");
    let (mut prev, mut worst) = (0.0f64, 0.0f64);
    for k in 0..10 {
        // At the dither rate's peaks, deep in the far region.
        let t = (k as f64 + 0.5) / (2.0 * p.dither_hz);
        let e = g.advance_to(t) - r.advance_to(t);
        worst = worst.max((e - prev).abs());
        prev = e;
    }
    println!(
        "dtheta {} rad, far threshold {:.2e} rad/s: {speed:.1} gyro-s per wall-s, \
         per-traversal error {worst:.2e} rad",
        p.solver.step_phase_rad, p.solver.far_threshold_rad_per_s
    );
    ExitCode::SUCCESS
}
