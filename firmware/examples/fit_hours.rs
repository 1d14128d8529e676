//! The calibration fit's precision over hours of cycles, on the Cortex-M4F itself:
//! `cargo fw-run --example fit_hours` (QEMU; exit status 0 when it holds).
//!
//! One hour of dither cycles at 389 Hz (1 400 400 cycles) of exact synthetic data with a large
//! mean output (a 500 deg/h input: y ~ 0.87 rad per cycle against a lock-in signal of
//! ~0.02 rad), accumulated in the firmware's f64 Welford accumulator (software floating point
//! on the M4F). a and b must come back to 1e-6 relative: raw sums of squares would have lost
//! them to cancellation. Also reports the instructions per accumulated cycle when run under
//! `cargo fw-icount --example fit_hours` (TIM2 counts instructions there).
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
mod app {
    use firmware::calibration::fit::FitAccumulator;
    use firmware::icount::{InstructionCounter, Timer};

    const CYCLES: u32 = 389 * 3600;
    const A: f64 = 344.25;
    const B: f64 = 579.5;
    const K: f64 = 26.3e-6;
    /// Mean output per cycle: 500 deg/h at SF 1.8655 -> 1684 rad/s -> 4.33 rad per cycle.
    const MEAN_RAD: f64 = 4.33;

    #[cortex_m_rt::entry]
    fn main() -> ! {
        let counter = InstructionCounter::start(Timer::Tim2);

        let mut acc = FitAccumulator::new();
        // A deterministic sequence of turnaround phases (golden-angle steps): P1, P2 spread.
        let (mut u, mut v) = (0.0f64, 1.0f64);
        let start = counter.now();
        for _ in 0..CYCLES {
            u += 2.399_963_229_728_653;
            v += 1.618_033_988_749_895;
            if u > core::f64::consts::TAU {
                u -= core::f64::consts::TAU;
            }
            if v > core::f64::consts::TAU {
                v -= core::f64::consts::TAU;
            }
            // Cheap smooth stand-ins for cos/sin (any spread of P1, P2 will do).
            let (cu, sv) = (1.0 - u * u / 8.0, v / 6.3 - 0.5);
            let (p1, p2) = (K * (cu + sv), K * (sv - cu));
            acc.push(MEAN_RAD + A * p1 + B * p2, p1, p2, 1.0 / 389.0);
        }
        let instructions = counter.now().wrapping_sub(start);
        let fit = acc.solve();
        let (ok, ea, eb) = match fit {
            Ok(f) => {
                let (ea, eb) = (
                    (f.a_rad_per_s / A - 1.0).abs(),
                    (f.b_rad_per_s / B - 1.0).abs(),
                );
                (ea < 1e-6 && eb < 1e-6, ea, eb)
            }
            Err(_) => (false, 1.0, 1.0),
        };
        defmt::info!(
            "fit over {=u32} cycles (one hour at 389 Hz): relative error a {=f64}, b {=f64} (limit 1e-6)",
            CYCLES,
            ea,
            eb
        );
        defmt::info!(
            "{=u32} instructions per cycle (meaningful under fw-icount)",
            instructions / CYCLES
        );
        semihosting::process::exit(if ok { 0 } else { 1 })
    }
}

#[cfg(not(target_os = "none"))]
fn main() {
    println!("fit_hours: an MCU example (`cargo fw-run --example fit_hours`)");
}
