//! Instruction counts of the board's interrupt handlers (QEMU `-icount shift=0`, where a timer at
//! PSC = 0 counts one per executed instruction): `cargo fw-icount --example board_cost`.
//! Complements `cost.rs` (the signal chain: turnaround 1106 / 1786, Lissajous sample 129).
//!
//! Measured here, each the handler body as bound by `bind_board_interrupts!` (exception entry
//! and exit, 12 + 12 cycles, come on top):
//! - `ADC` (turnaround latch): four register reads, flag clears, enqueue, pend the readout task;
//! - `TIM2` (pick-off): the register part of the handler, and the prediction (`Scheduler`);
//! - `USART1`: an entry with nothing to do, and the cost per transmitted byte (QEMU's TXE is
//!   always set; a received byte takes the same path in reverse);
//! - the input-rate shift computed once per cycle in the readout task;
//! - the `PriorityLock` round trip the main loop pays per readout access;
//! - the main loop's work per dither cycle with a calibration run collecting and the binary
//!   stream on: rate averaging, `CalibrationSession::on_cycle`, frame encoding (the record comes
//!   from the firmware's readout fed with a synthetic steady dither, as in `cost.rs`).
//!
//! Then, with the interrupts unmasked, each handler taken through its exception, the locks and
//! the main loop's sections under them, as `rtic_cost.rs` measures the RTIC binding of the same
//! handlers (the shared module `binding_cost`; docs/firmware.md#concurrency).
//!
//! The counter is TIM5 (32-bit), whose only use by the measured code is reading `CCR3`/`SR`.
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
mod binding_cost;

#[cfg(target_os = "none")]
mod app {
    use firmware::board::isr;
    use firmware::board::resources::{
        self, init_core, init_readout, start_dither, unmask_readout, READOUT, SCHEDULER,
    };
    use firmware::board::turnaround::{self, Edge, PlanLock, Scheduler};
    use firmware::board::{pac, usart};
    use firmware::calibration::session::CalibrationSession;
    use firmware::calibration::validation::AcceptanceLimits;
    use firmware::dither::DitherConfig;
    use firmware::icount::{InstructionCounter, Timer};
    use firmware::protocol::stream::{encode_frame, StreamRecord, MAX_FRAME};
    use firmware::readout::{Readout, ReadoutConfig};
    use firmware::sample::{AdcCode, TurnaroundKind, TurnaroundSample};
    use firmware::signal::compensation::{Coefficients, CompensationSettings};
    use firmware::signal::lockin::CycleRecord;
    use firmware::signal::output::{AveragerConfig, AveragingMode, RateAverager};
    use firmware::storage::DitherSetpoints;
    use micromath::F32Ext;

    firmware::bind_board_interrupts!();

    /// The binding's own code: an empty handler.
    #[cortex_m_rt::interrupt]
    fn EXTI2() {}
    use firmware::rt::pac::interrupt;

    /// Cycle records of a steady 389 Hz dither at a small rate (the synthetic gyro of `cost.rs`).
    fn records(config: &ReadoutConfig, out: &mut [Option<CycleRecord>; 8]) {
        let settings = CompensationSettings {
            coefficients: Coefficients::from_rad_per_s(344.0, 579.0).unwrap(),
            enabled: true,
        };
        let mut readout = Readout::new(config, settings);
        let half_ticks = 84_000_000 / 389 / 2;
        let mut base = 100_000u32;
        let mut n = 0;
        for i in 0..400u32 {
            let plus = i % 2 == 0;
            let count = if plus { base } else { base + 1930 };
            if !plus {
                base += 3;
            }
            let (s, c) = (count as f32 * core::f32::consts::FRAC_PI_2 + 0.3).sin_cos();
            let sample = TurnaroundSample {
                kind: if plus {
                    TurnaroundKind::Plus
                } else {
                    TurnaroundKind::Minus
                },
                encoder_count: count,
                adc_a_code: AdcCode::saturating((2048.0 + 1300.0 * c) as u16),
                adc_b_code: AdcCode::saturating((2048.0 + 1300.0 * s) as u16),
                timestamp_ticks: i * half_ticks,
                drive_locked: true,
            };
            if let Some(record) = readout.on_turnaround(config, sample) {
                out[n % 8] = Some(record);
                n += 1;
            }
        }
    }

    #[cortex_m_rt::entry]
    fn main() -> ! {
        let mut cp = cortex_m::Peripherals::take().unwrap();
        let dp = pac::Peripherals::take().unwrap();
        let counter = InstructionCounter::start(Timer::Tim5);
        init_core(&mut cp.SCB, &mut cp.NVIC, &mut cp.SYST);
        let config = firmware::profile::BoardProfile::F405.readout_config(389.0);
        let _records = init_readout(
            config,
            Readout::new(&config, CompensationSettings::default()),
        );
        // Interrupts stay masked: the handler bodies are called directly.

        // Armed as the pick-off handler would (else the latch discards the match).
        let tim2 = unsafe { &*pac::TIM2::ptr() };
        let armed = turnaround::Schedule {
            compare_ticks: tim2.cnt().read().bits().wrapping_add(1 << 30),
            kind: TurnaroundKind::Minus,
        };
        turnaround::arm(tim2, armed, tim2.cnt().read().bits(), &mut PlanLock);
        let latch = counter.count(isr::adc);
        turnaround::arm(tim2, armed, tim2.cnt().read().bits(), &mut PlanLock);
        let latch_stack = firmware::stack::depth_of(isr::adc);

        let pickoff_registers = counter.count(isr::tim2);
        let pickoff_stack = firmware::stack::depth_of(isr::tim2);
        let mut scheduler = Scheduler::new();
        let half = 84_000_000 / 389 / 2;
        let mut t = 1000u32;
        for i in 0..6 {
            let edge = if i % 2 == 0 {
                Edge::Rising
            } else {
                Edge::Falling
            };
            scheduler.on_edge(edge, t, 0, 0);
            t = t.wrapping_add(half);
        }
        let mut scheduled = None;
        let mut prediction = 0;
        let prediction_stack = firmware::stack::depth_of(|| {
            prediction = counter.count(|| {
                scheduled = scheduler.on_edge(Edge::Rising, t, 123, 0);
            });
        });

        let mut serial = usart::init(dp.USART1);
        let usart_idle = counter.count(isr::usart1);
        const BYTES: u32 = 32;
        serial.write(&[b'.'; BYTES as usize]);
        let usart_tx = counter.count(isr::usart1);
        serial.write(&[b'.'; BYTES as usize]);
        let usart_stack = firmware::stack::depth_of(isr::usart1);
        let per_byte = usart_tx.saturating_sub(usart_idle) / BYTES;

        let rate_shift = counter.count(|| {
            core::hint::black_box(turnaround::rate_shift_ticks(
                core::hint::black_box(12_125.0),
                core::hint::black_box(1515.6),
                core::hint::black_box(389.0),
            ));
        });
        let lock = counter.count(|| {
            core::hint::black_box(READOUT.lock(|task| task.readout.counters()));
        });

        let mut recs = [None; 8];
        // The readout task's work: the signal chain over the turnarounds of eight cycles.
        let readout_stack = firmware::stack::depth_of(|| records(&config, &mut recs));
        let averager_config = AveragerConfig {
            window_cycles: 389,
            mode: AveragingMode::WholePeriods,
            timer_hz: 84e6,
            scale_factor_arcsec: 1.8655,
        };
        let mut averager = RateAverager::new();
        let mut session = CalibrationSession::new(AcceptanceLimits::DEFAULT);
        session.start_run(0, 1_000_000).unwrap();
        let (mut averaging, mut calibration, mut stream, mut measured) = (0, 0, 0, 0);
        let mut cycle_stack = 0;
        for (i, record) in recs.iter().flatten().enumerate() {
            cycle_stack = cycle_stack.max(firmware::stack::depth_of(|| {
                core::hint::black_box(averager.clone().push(&averager_config, record.output));
                session
                    .clone()
                    .on_cycle(record, record.duration_s(&config.cycle));
                let mut buf = [0u8; MAX_FRAME];
                let frame = StreamRecord::from_cycle(i as u32, record);
                core::hint::black_box(encode_frame(&frame, &mut buf));
            }));
            averaging = averaging.max(counter.count(|| {
                core::hint::black_box(averager.push(&averager_config, record.output));
            }));
            calibration = calibration.max(counter.count(|| {
                session.on_cycle(record, record.duration_s(&config.cycle));
            }));
            stream = stream.max(counter.count(|| {
                let mut buf = [0u8; MAX_FRAME];
                let frame = StreamRecord::from_cycle(i as u32, record);
                core::hint::black_box(encode_frame(&frame, &mut buf));
            }));
            measured += 1;
        }

        defmt::info!("ADC turnaround latch handler: {=u32} instructions", latch);
        defmt::info!(
            "TIM2 pick-off handler: {=u32} (registers, no edge) + {=u32} (prediction) instructions",
            pickoff_registers,
            prediction
        );
        defmt::info!(
            "USART1 handler: {=u32} instructions idle, {=u32} per byte moved",
            usart_idle,
            per_byte
        );
        defmt::info!(
            "rate shift (once per cycle): {=u32} instructions",
            rate_shift
        );
        defmt::info!(
            "PriorityLock round trip (copy of the counters): {=u32} instructions",
            lock
        );
        defmt::info!(
            "main loop per cycle (max of {=u32}): averaging {=u32}, calibration run {=u32}, stream frame {=u32} instructions",
            measured,
            averaging,
            calibration,
            stream
        );
        defmt::info!(
            "stack: ADC latch {=u32}, TIM2 pick-off {=u32} (registers) / {=u32} (prediction), USART1 {=u32}, readout task (signal chain, 8 cycles) {=u32}, main loop cycle work {=u32} bytes",
            latch_stack,
            pickoff_stack,
            prediction_stack,
            usart_stack,
            readout_stack,
            cycle_stack
        );

        // Through the exceptions: the handlers' state as the board sets it (the controller
        // off), every line unmasked.
        SCHEDULER.init(Scheduler::new());
        let dither = DitherConfig::for_profile(&firmware::profile::BoardProfile::F405);
        let off = DitherSetpoints {
            enabled: false,
            amplitude_arcsec: dither.default_setpoint_arcsec,
            noise_percent: 0.0,
        };
        start_dither(dither, Some(off), None);
        // SAFETY: every handler's state is set; EXTI2's handler is empty.
        unsafe {
            cp.NVIC
                .set_priority(pac::Interrupt::EXTI2, resources::priority::READOUT_TASK);
            cortex_m::peripheral::NVIC::unmask(pac::Interrupt::USART1);
            cortex_m::peripheral::NVIC::unmask(pac::Interrupt::EXTI2);
        }
        unmask_readout(true);
        let mut locks = resources::STATIC_LOCKS;
        super::binding_cost::measure("board", &counter, &mut locks);

        semihosting::process::exit(if scheduled.is_some() && measured > 0 {
            0
        } else {
            1
        })
    }
}

#[cfg(not(target_os = "none"))]
fn main() {
    println!("board_cost: an MCU example (cargo fw-icount --example board_cost)");
}
