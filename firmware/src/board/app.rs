//! The interrupt design and start-up: who runs when, what they share, and [`run`].
//!
//! # Contexts, highest priority first (NVIC priority in the upper 4 bits)
//! Instruction counts measured in QEMU with `-icount` (`examples/board_cost.rs`, `cost.rs`);
//! cycles = instructions x 1.6 + 24 (exception entry and exit; docs/board.md justifies 1.6).
//!
//! | context | vector | prio | work | worst case |
//! |---|---|---|---|---|
//! | turnaround latch | `ADC` (JEOC) | 0x00 | copy ADC1/ADC2 JDR1, TIM5 CCR3, TIM2 CCR1 into a `TurnaroundSample`, enqueue, pend the readout task | 61 instr, 0.7 us |
//! | pick-off | `TIM2` (CC3/CC4) | 0x10 | edge time -> predicted turnaround -> `CCR1` | 55 instr, 0.7 us (both edges pending: 1.1 us) |
//! | serial | `USART1` | 0x20 | RX byte -> RX queue; TX queue -> DR | 35 + 20 per byte, 0.9 us |
//! | Lissajous block | `DMA2_STREAM0` (HT/TC) | 0x30 | mark a half buffer ready, pend the readout task | 44 instr (static count), 0.6 us |
//! | ms tick | `SysTick` | 0x30 | millisecond counter for the protocol's timeouts | 10 instr |
//! | readout task | `EXTI1` (software-pended, no EXTI line routed) | 0x40 | `on_turnaround` per queued sample (1106 / 1786 instr) + rate shift (71), `on_lissajous_sample` per pair (129; 51 573 at a window solve), `CycleRecord` out | 18 us per turnaround; 0.33 ms per block, 0.82 ms with a solve |
//! | main loop | thread | - | protocol (line -> parse -> `Executor`), rate averaging (716 instr per cycle), calibration run (3 910), stream frame (921), flash store, watchdog | preemptible |
//!
//! Rate-monotonic reasoning: the turnaround latch has no deadline of its own (the hardware holds
//! the result until the next trigger, a half dither period later) but is the shortest, so it
//! goes first and never delays anything measurably. The pick-off handler must arm the compare
//! within a quarter period minus 2 us (248 us at 1 kHz). The USART must read each byte within one
//! character time (21.7 us at 460 800 Bd): it is preempted only by the two handlers above
//! (< 1.8 us together). The readout task has half a dither period per turnaround and 20.7 ms
//! per Lissajous block; the main loop takes whatever is left.
//!
//! # Shared state
//! - ISR -> readout task: `TurnaroundSample`s through a heapless SPSC queue (16 entries = 8
//!   dither cycles of slack); Lissajous halves through an atomic bit mask (`adc`).
//! - readout task -> main loop: `CycleRecord`s through an SPSC queue (32 entries); the input-rate
//!   shift for the scheduler through an `AtomicI32` (`turnaround::RATE_SHIFT_TICKS`).
//! - USART1 <-> main loop: byte queues (`usart`).
//! - The `Readout` itself (status, staging settings, re-synchronising) is shared by the readout
//!   task and the main loop through a [`PriorityLock`]: the main loop raises BASEPRI to the
//!   readout task's priority for the few instructions it needs; the latch, pick-off and serial
//!   handlers are never masked. Staged settings take effect whole at the next cycle boundary
//!   (`Readout::stage_compensation`): the STYLE.md atomic swap.
//! - Only the USART's `CR1` read-modify-write in the main loop uses a (3-instruction) critical
//!   section.
//!
//! # CPU load (docs/board.md has the derivation)
//! At 389 Hz dither: 3.3 % of 168 MHz (turnaround chain 1.6 %, Lissajous stream 1.7 %); with a
//! calibration run and the binary stream on every cycle: 6.3 %. At 1 kHz: 5.7 %; with a
//! calibration run and the stream on every second cycle: 11.4 %.

use core::cell::UnsafeCell;
use core::sync::atomic::{AtomicU32, Ordering};

use cortex_m::peripheral::{scb::SystemHandler, NVIC, SCB, SYST};
use heapless::spsc::{Consumer, Producer, Queue};

use super::service::{Service, ServiceConfig};
use super::{adc, clocks, encoder, flash, pac, turnaround, usart, watchdog, Owned};
use crate::protocol::execute::Identity;
use crate::readout::{Readout, ReadoutConfig};
use crate::sample::TurnaroundSample;
use crate::signal::lockin::CycleRecord;
use crate::storage::Geometry;
use pac::Interrupt;

/// NVIC priorities (the F405 implements the upper 4 bits).
pub mod priority {
    pub const TURNAROUND_LATCH: u8 = 0x00;
    pub const PICKOFF: u8 = 0x10;
    pub const SERIAL: u8 = 0x20;
    pub const LISSAJOUS_DMA: u8 = 0x30;
    pub const TICK: u8 = 0x30;
    pub const READOUT_TASK: u8 = 0x40;
}

/// The software-pended vector of the readout task (EXTI line 1 is not routed to any pin).
pub const READOUT_TASK_IRQ: Interrupt = Interrupt::EXTI1;

/// Board profile: the gyro this board reads (docs/physics.md parameter set).
pub const DITHER_HZ_NOMINAL: f64 = 389.0;
pub const SCALE_FACTOR_ARCSEC: f64 = 1.8655;
/// The scheduler accepts dither frequencies in this range.
const DITHER_HZ_RANGE: (u32, u32) = (200, 1500);

const TURNAROUND_QUEUE: usize = 17; // 16 usable
const RECORD_QUEUE: usize = 33; // 32 usable

/// Turnarounds lost because the readout task fell 16 behind; cycle records the main loop did not
/// take in time.
pub static TURNAROUNDS_DROPPED: AtomicU32 = AtomicU32::new(0);
pub static RECORDS_DROPPED: AtomicU32 = AtomicU32::new(0);
/// Milliseconds since start (SysTick), wrapping.
static MILLIS: AtomicU32 = AtomicU32::new(0);

/// A value shared by contexts up to a priority ceiling: whoever locks raises BASEPRI to the
/// ceiling, so no other user can run meanwhile (the stack resource policy, as RTIC does it).
/// Users: only contexts at the ceiling's priority or below (numerically >=), and never nested.
pub struct PriorityLock<T> {
    ceiling: u8,
    value: UnsafeCell<Option<T>>,
}

// SAFETY: access is serialised by BASEPRI (see the type's docs).
unsafe impl<T: Send> Sync for PriorityLock<T> {}

impl<T> PriorityLock<T> {
    pub const fn new(ceiling: u8) -> Self {
        Self {
            ceiling,
            value: UnsafeCell::new(None),
        }
    }

    /// Sets the value; before any user's interrupt is enabled.
    pub fn init(&self, value: T) {
        cortex_m::interrupt::free(|_| {
            // SAFETY: interrupts are off and users are not yet enabled.
            unsafe { *self.value.get() = Some(value) };
        });
    }

    /// Runs `f` with the value (None before `init`). Must not be nested.
    pub fn lock<R>(&self, f: impl FnOnce(&mut T) -> R) -> Option<R> {
        let old = cortex_m::register::basepri::read();
        // Raising BASEPRI only masks more; restored below.
        cortex_m::register::basepri_max::write(self.ceiling);
        // SAFETY: at the ceiling no other user runs; not nested by contract.
        let result = unsafe { (*self.value.get()).as_mut().map(f) };
        // SAFETY: back to the caller's level.
        unsafe { cortex_m::register::basepri::write(old) };
        result
    }
}

/// What the readout task owns.
pub struct ReadoutTask {
    pub config: ReadoutConfig,
    pub readout: Readout,
    samples: Consumer<'static, TurnaroundSample>,
    records: Producer<'static, CycleRecord>,
}

/// The readout, shared by the readout task and the main loop.
pub static READOUT: PriorityLock<ReadoutTask> = PriorityLock::new(priority::READOUT_TASK);
/// The turnaround latch's end of the sample queue.
static LATCH_SIDE: Owned<Producer<'static, TurnaroundSample>> = Owned::new();
/// The pick-off handler's prediction state.
static SCHEDULER: Owned<turnaround::Scheduler> = Owned::new();

/// Creates the queues and the readout; returns the main loop's end of the record queue.
pub fn init_readout(config: ReadoutConfig, readout: Readout) -> Consumer<'static, CycleRecord> {
    let samples =
        cortex_m::singleton!(: Queue<TurnaroundSample, TURNAROUND_QUEUE> = Queue::new()).unwrap();
    let records = cortex_m::singleton!(: Queue<CycleRecord, RECORD_QUEUE> = Queue::new()).unwrap();
    let (sample_in, sample_out) = samples.split();
    let (record_in, record_out) = records.split();
    LATCH_SIDE.init(sample_in);
    READOUT.init(ReadoutTask {
        config,
        readout,
        samples: sample_out,
        records: record_in,
    });
    record_out
}

/// Milliseconds since start (wrapping).
pub fn now_ms() -> u32 {
    MILLIS.load(Ordering::Relaxed)
}

/// The handlers' bodies; bound to the vectors by [`crate::bind_board_interrupts`].
pub mod isr {
    use super::*;

    /// `ADC`: the turnaround latch (JEOC of ADC1).
    pub fn adc() {
        // SAFETY: register reads/flag clears of peripherals this handler owns after start-up.
        let (adc1, adc2, tim2, tim5) = unsafe {
            (
                &*pac::ADC1::ptr(),
                &*pac::ADC2::ptr(),
                &*pac::TIM2::ptr(),
                &*pac::TIM5::ptr(),
            )
        };
        let Some(sample) = turnaround::latch(adc1, adc2, tim2, tim5) else {
            return;
        };
        // SAFETY: this handler is the only producer.
        if let Some(queue) = unsafe { LATCH_SIDE.get() } {
            if queue.enqueue(sample).is_err() {
                TURNAROUNDS_DROPPED.fetch_add(1, Ordering::Relaxed);
            }
        }
        NVIC::pend(READOUT_TASK_IRQ);
    }

    /// `TIM2`: a pick-off edge.
    pub fn tim2() {
        // SAFETY: TIM2's SR/CCR are used by this handler only after start-up (and by the main
        // loop's pause, with this interrupt masked).
        let tim = unsafe { &*pac::TIM2::ptr() };
        // SAFETY: this handler owns the scheduler.
        if let Some(scheduler) = unsafe { SCHEDULER.get() } {
            turnaround::on_pickoff_interrupt(tim, scheduler);
        }
    }

    /// `USART1`.
    pub fn usart1() {
        usart::on_interrupt();
    }

    /// `DMA2_STREAM0`: a Lissajous half buffer is complete.
    pub fn dma2_stream0() {
        // SAFETY: LISR/LIFCR of stream 0 are used by this handler only.
        if adc::on_dma_interrupt(unsafe { &*pac::DMA2::ptr() }) {
            NVIC::pend(READOUT_TASK_IRQ);
        }
    }

    /// `SysTick`: 1 ms.
    pub fn systick() {
        MILLIS.fetch_add(1, Ordering::Relaxed);
    }

    /// `EXTI1` (software): the readout task.
    pub fn readout_task() {
        READOUT.lock(|task| {
            while let Some(sample) = task.samples.dequeue() {
                if let Some(record) = task.readout.on_turnaround(&task.config, sample) {
                    turnaround::publish_rate_shift(&record);
                    if task.records.enqueue(record).is_err() {
                        RECORDS_DROPPED.fetch_add(1, Ordering::Relaxed);
                    }
                }
            }
            let (config, readout) = (&task.config, &mut task.readout);
            adc::take_ready_blocks(|a, b| readout.on_lissajous_sample(config, a, b));
        });
    }
}

/// Binds the board's handlers to the vector table. Invoke once, at the top level of the binary
/// that calls [`run`] or [`serve`] (a library cannot own vectors without forcing them on every
/// binary that links it, the on-target tests included).
#[macro_export]
macro_rules! bind_board_interrupts {
    () => {
        mod board_vectors {
            use $crate::rt::pac::interrupt;

            #[cortex_m_rt::interrupt]
            fn ADC() {
                $crate::board::app::isr::adc()
            }
            #[cortex_m_rt::interrupt]
            fn TIM2() {
                $crate::board::app::isr::tim2()
            }
            #[cortex_m_rt::interrupt]
            fn USART1() {
                $crate::board::app::isr::usart1()
            }
            #[cortex_m_rt::interrupt]
            fn DMA2_STREAM0() {
                $crate::board::app::isr::dma2_stream0()
            }
            #[cortex_m_rt::interrupt]
            fn EXTI1() {
                $crate::board::app::isr::readout_task()
            }
            #[cortex_m_rt::exception]
            fn SysTick() {
                $crate::board::app::isr::systick()
            }
        }
    };
}

/// Sets the priorities of every board context and starts the 1 ms tick. Interrupt lines stay
/// masked; the callers unmask what they use.
pub fn init_core(scb: &mut SCB, nvic: &mut NVIC, syst: &mut SYST) {
    // SAFETY: priorities are set before any of these interrupts is unmasked.
    unsafe {
        nvic.set_priority(Interrupt::ADC, priority::TURNAROUND_LATCH);
        nvic.set_priority(Interrupt::TIM2, priority::PICKOFF);
        nvic.set_priority(Interrupt::USART1, priority::SERIAL);
        nvic.set_priority(Interrupt::DMA2_STREAM0, priority::LISSAJOUS_DMA);
        nvic.set_priority(READOUT_TASK_IRQ, priority::READOUT_TASK);
        scb.set_priority(SystemHandler::SysTick, priority::TICK);
    }
    syst.set_clock_source(cortex_m::peripheral::syst::SystClkSource::Core);
    syst.set_reload(super::SYSCLK_HZ / 1000 - 1);
    syst.clear_current();
    syst.enable_interrupt();
    syst.enable_counter();
}

/// Unmasks the readout task and (with `hardware`) the turnaround and Lissajous interrupts.
pub fn unmask_readout(hardware: bool) {
    // SAFETY: every handler's state was initialised before this call.
    unsafe {
        NVIC::unmask(READOUT_TASK_IRQ);
        if hardware {
            NVIC::unmask(Interrupt::DMA2_STREAM0);
            NVIC::unmask(Interrupt::TIM2);
            NVIC::unmask(Interrupt::ADC);
        }
    }
}

/// Stops every readout interrupt for a flash store: producers first, then the readout task is
/// run once to empty the sample queue (it preempts the caller at once), then masked too.
pub fn pause_readout(hardware: bool) {
    if hardware {
        NVIC::mask(Interrupt::ADC);
        NVIC::mask(Interrupt::TIM2);
        NVIC::mask(Interrupt::DMA2_STREAM0);
        // SAFETY: TIM2's handler is masked: the main loop may park its compare.
        turnaround::pause(unsafe { &*pac::TIM2::ptr() });
    }
    NVIC::pend(READOUT_TASK_IRQ);
    // The pended task (priority 0x40 > thread) is taken before the next instruction completes.
    cortex_m::asm::dsb();
    cortex_m::asm::isb();
    NVIC::mask(READOUT_TASK_IRQ);
}

/// Resumes after a store: the readout re-synchronises (count reference, quadrant, open cycle are
/// dropped), stale hardware results are discarded, interrupts unmasked.
pub fn resume_readout(hardware: bool) {
    READOUT.lock(|task| task.readout.resynchronise());
    if hardware {
        // SAFETY: the latch handler is masked; a result taken before the stall is stale.
        adc::discard_injected(unsafe { &*pac::ADC1::ptr() });
        NVIC::unpend(Interrupt::ADC);
        NVIC::unpend(Interrupt::TIM2);
    }
    unmask_readout(hardware);
}

/// The board's identity: serial number and unlock key from OTP block 0 (0x1FFF_7800, words 0
/// and 1, written at production). Unprogrammed OTP (0xFFFF_FFFF) gives serial 0 and the
/// development key 0xC0FF_EE42: a production board must have its key programmed. (QEMU does
/// not map the OTP area: a read there faults, so the `qemu` build uses the defaults.)
fn identity() -> Identity {
    let otp = |word: usize| {
        if cfg!(feature = "qemu") {
            return u32::MAX;
        }
        // SAFETY: the OTP area is always readable on the F405.
        unsafe { (0x1FFF_7800 as *const u32).add(word).read_volatile() }
    };
    let or = |value: u32, default: u32| if value == u32::MAX { default } else { value };
    Identity {
        firmware_version: env!("CARGO_PKG_VERSION"),
        build: env!("FW_BUILD_PROFILE"),
        board: "rlg-readout-f405",
        serial_number: or(otp(0), 0),
        key: or(otp(1), 0xC0FF_EE42),
        scale_factor_arcsec: SCALE_FACTOR_ARCSEC as f32,
        capture_timer_hz: super::TIMER_HZ,
    }
}

/// Brings the board up and runs it: clocks, watchdog, serial link, calibration from flash,
/// encoder, turnaround timer, ADCs, interrupts, then the main loop. Needs
/// [`crate::bind_board_interrupts`] in the binary.
pub fn run() -> ! {
    let mut cp = cortex_m::Peripherals::take().unwrap();
    let dp = pac::Peripherals::take().unwrap();
    let source = clocks::init(&dp.RCC, &dp.FLASH);
    let watchdog = watchdog::Watchdog::start(dp.IWDG);
    clocks::enable(
        &dp.RCC,
        clocks::AHB1_GPIOA | clocks::AHB1_GPIOB | clocks::AHB1_GPIOC | clocks::AHB1_DMA2,
        clocks::APB1_TIM2 | clocks::APB1_TIM3 | clocks::APB1_TIM5,
        clocks::APB2_USART1 | clocks::APB2_ADC1 | clocks::APB2_ADC2,
    );
    defmt::info!("clocks: 168 MHz from {}", source);
    init_core(&mut cp.SCB, &mut cp.NVIC, &mut cp.SYST);
    let serial = usart::init(dp.USART1);
    let flash = flash::InternalFlash::new(dp.FLASH);
    let config = ReadoutConfig::for_board(
        super::TIMER_HZ as f64,
        DITHER_HZ_NOMINAL,
        crate::profile::BoardProfile::F405.counter_width,
    );
    let service_config = ServiceConfig {
        identity: identity(),
        geometry: Geometry::F405_SECTORS_10_11,
        hardware: true,
        dither_hz: DITHER_HZ_NOMINAL,
        scale_factor_arcsec: SCALE_FACTOR_ARCSEC,
        banner: Some("# rlg-readout ready"),
        intercept: None,
    };
    let service = Service::new(service_config, serial, flash, Some(watchdog), config);
    let _encoder = encoder::Encoder::new(dp.TIM5);
    SCHEDULER.init(turnaround::Scheduler::new(
        super::TIMER_HZ,
        DITHER_HZ_RANGE.0,
        DITHER_HZ_RANGE.1,
    ));
    adc::init(&dp.ADC_COMMON, &dp.ADC1, &dp.ADC2, &dp.TIM3, &dp.DMA2);
    turnaround::init(&dp.TIM2);
    unmask_readout(true);
    // SAFETY: the USART's queues were set up in `usart::init`.
    unsafe { NVIC::unmask(Interrupt::USART1) };
    service.run()
}
