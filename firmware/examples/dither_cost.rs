//! Instruction counts of the dither drive on the emulated Cortex-M4F (issue 12, item 11):
//! `cargo fw-icount --example dither_cost` (QEMU `-icount shift=0`: TIM2 at PSC = 0 counts one
//! per executed instruction; see `firmware::icount`).
//!
//! The controller runs through its start-up into lock against a small envelope model computed
//! on the target (the pick-off exactly 90 degrees behind the drive at any frequency, so it
//! locks where it first listens, 280 Hz; its amplitude follows `dA/dt = -A / tau + g u` with
//! tau = 0.82 s and the ring-up rate of the closed-loop tests), for 4.5 s of ticks: the noise
//! dither off for the first second locked, on (30 %) after. A tick's cost does not depend on
//! the frequency; the load below is for 389 Hz. Measured per tick, as the `TIM4` handler runs
//! it:
//! - the register part (`board::dither::take_pickoff`: compare flag, JEOC check, JDR1) and the
//!   DAC write;
//! - `on_tick` inside the `DITHER` lock: the common tick, and the tick that closes a half cycle
//!   (fit, supervisor, loops, new DDS parameters), mean and largest, locked; the largest of
//!   any tick of the start-up;
//! - the parts of a common tick: `idsp::cossin`, the half-cycle window's accumulation, the DAC
//!   code, the lock round trip; of a half cycle: the fit, the two PI loops.
//!
//! The CPU load is printed for 40 000 ticks per second and 778 half cycles per second (389 Hz):
//! cycles = instructions x 1.6 + 24 (exception entry and exit; docs/board.md).
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
mod app {
    use firmware::board::dither::take_pickoff;
    use firmware::board::pac;
    use firmware::board::resources::{DitherTask, DITHER};
    use firmware::dither::{DitherConfig, DitherController, DitherState};
    use firmware::icount::{InstructionCounter, Timer};
    use firmware::profile::BoardProfile;
    use firmware::sample::AdcCode;
    use firmware::signal::output::dither_model::PickoffSample;

    firmware::bind_board_interrupts!();

    /// The envelope model: amplitude (codes) driven at resonance.
    struct Envelope {
        amplitude: f32,
        decay: f32,
        gain_per_tick: f32,
    }

    impl Envelope {
        /// The pick-off code for a drive whose DAC sample has phase `turns` and amplitude
        /// `drive` codes: `mid - A cos(2 pi turns)` (90 degrees behind `sin`).
        fn pickoff(&mut self, turns: u32, drive: f32) -> AdcCode {
            self.amplitude = self.amplitude * self.decay + self.gain_per_tick * drive;
            let (c, _) = firmware::dither::cos_sin_q31(firmware::units::Phase::from_bits(turns));
            let v = 2048.0 - self.amplitude * (c as f32 / 2_147_483_648.0);
            AdcCode::saturating((v + 0.5) as u16)
        }
    }

    #[derive(Default, Clone, Copy)]
    struct Stats {
        count: u32,
        total: u64,
        max: u32,
    }

    impl Stats {
        fn push(&mut self, n: u32) {
            self.count += 1;
            self.total += n as u64;
            self.max = self.max.max(n);
        }
        fn mean(&self) -> u32 {
            (self.total / self.count.max(1) as u64) as u32
        }
    }

    #[cortex_m_rt::entry]
    fn main() -> ! {
        let counter = InstructionCounter::start(Timer::Tim2);
        let profile = BoardProfile::F405;
        let config = DitherConfig::for_profile(&profile);
        let mut controller = DitherController::new(&config);
        controller.enable();
        DITHER.init(DitherTask { config, controller });

        // The handler's register part (TIM4, ADC3 as the board sets them up; QEMU models both).
        let (tim4, adc3, dac) =
            unsafe { (&*pac::TIM4::ptr(), &*pac::ADC3::ptr(), &*pac::DAC::ptr()) };
        let registers = counter.count(|| {
            core::hint::black_box(take_pickoff(tim4, adc3));
        });
        let dac_write = counter.count(|| {
            dac.dhr12r1().write(|w| unsafe { w.bits(2048) });
        });
        // The pick-off stream's part (`board::dither::on_tick` and `isr::tim4`): both counters
        // read together for the sample's stamp, the sample into its queue.
        let tim2 = unsafe { &*pac::TIM2::ptr() };
        let queue = cortex_m::singleton!(: heapless::spsc::Queue<PickoffSample, 129> =
            heapless::spsc::Queue::new())
        .unwrap();
        let (mut producer, _consumer) = queue.split();
        let stream = counter.count(|| {
            let (t2, t4) =
                cortex_m::interrupt::free(|_| (tim2.cnt().read().bits(), tim4.cnt().read().bits()));
            let sample = PickoffSample {
                timestamp_ticks: t2.wrapping_sub(t4),
                code: AdcCode::MID,
            };
            core::hint::black_box(producer.enqueue(sample).is_ok());
        });

        // 389 Hz, tau = 2Q / w0 = 0.818 s, ring-up rate 1650 arcsec/s = 4125 codes/s at the limit.
        let tick_hz = profile.drive_tick_hz as f32;
        let limit = DITHER
            .lock(|t| t.config.amplitude.drive_limit_codes())
            .unwrap();
        let mut model = Envelope {
            amplitude: 0.0,
            decay: 1.0 - 1.0 / (0.818 * tick_hz),
            gain_per_tick: 4125.0 / limit / tick_hz,
        };
        let (mut startup_max, mut common, mut update, mut noisy_common, mut noisy_update) = (
            0u32,
            Stats::default(),
            Stats::default(),
            Stats::default(),
            Stats::default(),
        );
        let mut dac_code = 2048u16;
        let mut locked_ticks = 0u32;
        let mut stack_bytes = 0u32;
        for i in 0..(4 * profile.drive_tick_hz + profile.drive_tick_hz / 2) {
            // The drive's phase at this sample's instant: the DAC sample in force, less the
            // zero-order hold's half step, plus the ADC's aperture (what the controller assumes).
            let (turns, drive) = DITHER
                .lock(|t| {
                    let d = t.controller.drive();
                    let phase = d.phase_of(t.controller.tick().wrapping_sub(d.start_tick));
                    let lag = d.step.to_bits() as f32 * (0.5 - t.config.sample_delay_ticks());
                    (
                        phase.to_bits().wrapping_sub(lag as u32),
                        d.amplitude_codes() as f32,
                    )
                })
                .unwrap();
            let code = model.pickoff(turns, drive);
            let mut tick = None;
            let mut n = 0;
            let mut run = || {
                n = counter.count(|| {
                    tick = DITHER.lock(|t| t.controller.on_tick(&t.config, code));
                });
            };
            if i.is_multiple_of(97) {
                // Painting the stack costs ~100 k instructions: every 97th tick (co-prime with
                // the 103-tick half cycle, so the half-cycle updates are sampled too).
                stack_bytes = stack_bytes.max(firmware::stack::depth_of(run));
            } else {
                run();
            }
            let tick = tick.unwrap();
            dac_code = tick.dac_code;
            let locked = DITHER.lock(|t| t.controller.state()) == Some(DitherState::Locked);
            if !locked {
                startup_max = startup_max.max(n);
                continue;
            }
            locked_ticks += 1;
            if locked_ticks == profile.drive_tick_hz {
                DITHER.lock(|t| t.controller.set_noise_depth_percent(30.0).unwrap());
            }
            let noisy = locked_ticks > profile.drive_tick_hz;
            match (tick.half_cycle, noisy) {
                (false, false) => common.push(n),
                (true, false) => update.push(n),
                (false, true) => noisy_common.push(n),
                (true, true) => noisy_update.push(n),
            }
        }
        {
            use firmware::dither::Window;
            use firmware::units::Phase;
            let mut w = Window::new();
            let mut p = Phase::from_bits(12345);
            let c1 = counter.count(|| {
                core::hint::black_box(firmware::dither::cos_sin_q31(core::hint::black_box(p)));
            });
            let c2 = counter.count(|| {
                w.push(core::hint::black_box(2100), 52, 1000, 2000, 4095);
            });
            let d = DITHER.lock(|t| t.controller.drive()).unwrap();
            let c3 = counter.count(|| {
                core::hint::black_box(d.code_from_sin(core::hint::black_box(123456789)));
            });
            let c4 = counter.count(|| {
                core::hint::black_box(DITHER.lock(|_| ()));
            });
            for i in 0..51u32 {
                let (c, s) = firmware::dither::cos_sin_q31(p + Phase::from_bits(i * 41_764_787));
                w.push(
                    2048 + (i * 37 % 1000) as u16,
                    (i * 37 % 1000) as i32,
                    c >> 16,
                    s >> 16,
                    4095,
                );
            }
            let c5 = counter.count(|| {
                core::hint::black_box(w.close());
            });
            let (c6, c7) = DITHER
                .lock(|t| {
                    let mut f = firmware::dither::FrequencyLoop::default();
                    f.start(Phase::from_bits(41_764_787));
                    let mut a = firmware::dither::AmplitudeLoop::default();
                    a.start(600 << 16, 2.1);
                    f.update(&t.config.frequency, Phase::from_bits(1000));
                    a.update(&t.config.amplitude, 1125.0, 1120.0);
                    let c6 = counter.count(|| {
                        core::hint::black_box(f.update(
                            &t.config.frequency,
                            core::hint::black_box(Phase::from_bits(1234)),
                        ));
                    });
                    let c7 = counter.count(|| {
                        core::hint::black_box(a.update(
                            &t.config.amplitude,
                            1125.0,
                            core::hint::black_box(1121.0),
                        ));
                    });
                    (c6, c7)
                })
                .unwrap();
            defmt::info!(
                "parts of a half cycle: fit (close, incl. sqrtf and idsp::atan2) {=u32}, frequency PI (idsp BiquadClamp) {=u32}, amplitude PI (idsp BiquadClamp, input scaling) {=u32} instructions",
                c5,
                c6,
                c7
            );
            p = p + Phase::QUARTER_TURN;
            core::hint::black_box(p);
            defmt::info!(
                "parts of a tick: idsp::cossin {=u32}, window push {=u32}, DAC code {=u32}, DITHER lock {=u32} instructions",
                c1,
                c2,
                c3,
                c4
            );
        }
        defmt::info!(
            "stack: TIM4 dither tick (on_tick in the DITHER lock) {=u32} bytes deepest of every 97th tick",
            stack_bytes
        );
        let state = DITHER.lock(|t| t.controller.status(&t.config)).unwrap();
        defmt::info!(
            "dither state after 4.5 s: {} (last DAC code {=u16})",
            state.state,
            dac_code
        );
        defmt::info!(
            "TIM4 handler register part: {=u32} (pick-off) + {=u32} (DAC write) instructions; the pick-off stream's stamp and queue: {=u32}",
            registers,
            dac_write,
            stream
        );
        defmt::info!(
            "on_tick in the DITHER lock, locked: common {=u32} mean / {=u32} max ({=u32} ticks), half cycle {=u32} mean / {=u32} max ({=u32})",
            common.mean(), common.max, common.count, update.mean(), update.max, update.count
        );
        defmt::info!(
            "with the 30 % noise dither: common {=u32} / {=u32}, half cycle {=u32} / {=u32} ({=u32})",
            noisy_common.mean(), noisy_common.max, noisy_update.mean(), noisy_update.max, noisy_update.count
        );
        defmt::info!(
            "largest tick of the start-up: {=u32} instructions",
            startup_max
        );
        // Load at 389 Hz: 40 000 ticks/s, 778 of them close a half cycle.
        let handler = |on_tick: u32| (registers + dac_write + on_tick) as f32 * 1.6 + 24.0;
        let per_second = (tick_hz - 778.0) * handler(noisy_common.mean().max(common.mean()))
            + 778.0 * handler(noisy_update.mean().max(update.mean()));
        let worst = tick_hz * handler(noisy_common.max.max(common.max))
            + 778.0
                * (handler(noisy_update.max.max(update.max))
                    - handler(noisy_common.max.max(common.max)));
        defmt::info!(
            "drive CPU load at 168 MHz: {=f32} % (means), {=f32} % (every tick at its max)",
            per_second / 168e6 * 100.0,
            worst / 168e6 * 100.0
        );
        semihosting::process::exit(if state.state == DitherState::Locked {
            0
        } else {
            1
        })
    }
}

#[cfg(not(target_os = "none"))]
fn main() {
    println!("dither_cost: an MCU example (cargo fw-icount --example dither_cost)");
}
