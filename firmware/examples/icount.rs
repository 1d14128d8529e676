//! Instructions per call of the per-cycle core functions, counted in QEMU with
//! `-icount shift=0` (1 ns of virtual time per instruction) by TIM2 at QEMU's 1 GHz timer clock:
//! `cargo fw-icount --example icount`. Deterministic: the same numbers on every run.
//!
//! These are instruction counts, not Cortex-M4 cycles (no wait states, multi-cycle loads,
//! divides or the soft-float f64 routines' real timing); on a board TIM2 counts timer ticks and
//! `DWT.CYCCNT` gives cycles. Budget for scale: at 168 MHz and a 389 Hz dither a cycle has
//! 432 k core cycles, two turnarounds.
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
mod app {
    use core::hint::black_box;
    use firmware::calibration::{fit::FitAccumulator, tracking::Tracker, tracking::TrackingConfig};
    use firmware::icount::{InstructionCounter, Timer};
    use firmware::sample::TurnaroundKind;
    use firmware::signal::compensation::{Coefficients, CompensationSettings, Compensator};
    use firmware::signal::lockin::CycleOutput;
    use firmware::signal::lockin::{traversal_terms, traversal_time_s, LevelPair, LockinTerms};
    use firmware::signal::output::{AveragerConfig, AveragingMode, RateAverager};

    const CALLS: u32 = 64;

    /// xorshift32: varied inputs, so a call's count is an average over its paths.
    struct Rng(u32);
    impl Rng {
        fn next(&mut self) -> u32 {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 17;
            self.0 ^= self.0 << 5;
            self.0
        }
        fn unit(&mut self) -> f32 {
            (self.next() >> 8) as f32 / 8_388_608.0 - 1.0
        }
    }

    struct Counter(InstructionCounter);
    impl Counter {
        fn now(&self) -> u32 {
            self.0.now()
        }
        /// Mean instructions per call of `f` over `CALLS` calls, less the loop's own cost.
        fn per_call(&self, rng: &mut Rng, mut f: impl FnMut(&mut Rng)) -> u32 {
            let empty = self.total(rng, |r| {
                black_box(r.next());
            });
            self.total(rng, |r| f(r)).saturating_sub(empty) / CALLS
        }
        fn total(&self, rng: &mut Rng, mut f: impl FnMut(&mut Rng)) -> u32 {
            let start = self.now();
            for _ in 0..CALLS {
                f(black_box(&mut *rng));
            }
            self.now().wrapping_sub(start)
        }
    }

    #[cortex_m_rt::entry]
    fn main() -> ! {
        let counter = Counter(InstructionCounter::start(Timer::Tim2));
        let mut rng = Rng(0x1234_5678);

        let n = counter.per_call(&mut rng, |r| {
            let k = traversal_time_s(black_box(9.1e9 * (1.5 + r.unit())));
            let levels = LevelPair {
                cos_psi_h: r.unit(),
                sin_psi_h: r.unit(),
            };
            black_box(traversal_terms(
                TurnaroundKind::Plus,
                levels,
                k.unwrap_or(0.0),
            ));
        });
        defmt::info!("insns/call  lockin: k + traversal_terms        {=u32}", n);

        let coefficients = Coefficients::from_rad_per_s(387.0, 383.0).unwrap();
        let mut comp = Compensator::new(CompensationSettings {
            coefficients,
            enabled: true,
        });
        let n = counter.per_call(&mut rng, |r| {
            let terms = LockinTerms {
                p1_s: 5e-5 * r.unit(),
                p2_s: 5e-5 * r.unit(),
            };
            black_box(comp.cycle_correction(terms));
        });
        defmt::info!("insns/call  compensation: cycle_correction   {=u32}", n);

        let config = AveragerConfig {
            window_cycles: 389,
            mode: AveragingMode::WholePeriods,
            timer_hz: 84e6,
            scale_factor_arcsec: 1.8655,
        };
        let mut averager = RateAverager::new();
        let n = counter.per_call(&mut rng, |r| {
            let cycle = CycleOutput {
                increment: firmware::units::PhaseDelta::from_q32((r.next() as i32 as i64) << 2),
                duration_ticks: 215_938,
                ..CycleOutput::default()
            };
            black_box(averager.push(&config, cycle));
        });
        defmt::info!("insns/call  output: RateAverager::push (f64) {=u32}", n);

        let mut fit = FitAccumulator::new();
        let n = counter.per_call(&mut rng, |r| {
            let (p1, p2) = (26e-6 * r.unit() as f64, 26e-6 * r.unit() as f64);
            black_box(fit.push(0.05 + 387.0 * p1 + 383.0 * p2, p1, p2, 1.0 / 389.0));
        });
        defmt::info!("insns/call  calibration: fit push (f64)      {=u32}", n);

        let tracking = TrackingConfig::with_memory(500.0, 26.3e-6);
        let mut tracker = Tracker::new(&tracking, 387.0, 383.0);
        let n = counter.per_call(&mut rng, |r| {
            let (p1, p2) = (26e-6 * r.unit() as f64, 26e-6 * r.unit() as f64);
            tracker.update(&tracking, 0.05 + 387.0 * p1 + 383.0 * p2, p1, p2, true);
        });
        black_box(&tracker);
        defmt::info!("insns/call  calibration: tracker update (f64) {=u32}", n);

        semihosting::process::exit(0)
    }
}

#[cfg(not(target_os = "none"))]
fn main() {
    println!("icount: an MCU example (`cargo fw-icount --example icount`)");
}
