//! Peripheral ownership and priorities: who runs when, what the contexts share, and the
//! readout's start, stop and restart. The handlers' bodies are in [`super::isr`], the start-up
//! and the main loop in [`super::app`]; both import this file, which imports neither.
//!
//! # Contexts, highest priority first (NVIC priority in the upper 4 bits)
//! Instruction counts measured in QEMU with `-icount` (`examples/board_cost.rs`, `cost.rs`);
//! cycles = instructions x 1.6 + 24 (exception entry and exit; docs/board.md justifies 1.6).
//!
//! | context | vector | prio | work | worst case |
//! |---|---|---|---|---|
//! | latch | `ADC` (JEOC, OVR) | 0x00 | an overrun restarts the photodiode stream; copy ADC1/ADC2 JDR1, ADC3 DR (after its EOC), TIM5 CCR3, TIM2 CCR1 into a `TurnaroundSample` or an `OutputSample`, arm the next compare (`LatchPlan`, re-anchored from TIM2/TIM4), enqueue, pend the readout task | ~150 instr, 1.6 us; 480 instr, 4.7 us with ADC3's full EOC poll |
//! | dither drive tick | `TIM4` (CC1, 40 kHz) | 0x10 | ADC3 JDR1 (pick-off) -> `DitherController::on_tick` -> DAC DHR12R1; the code, stamped with TIM2's time of the tick, into the pick-off stream | 18 + 232 instr, 2.5 us; at the end of a half dither cycle 18 + 1243, 12.0 us (see docs/board.md for the stream's share) |
//! | pick-off and sync | `TIM2` (CC3/CC4, CC2) | 0x20 | edge time -> predicted turnaround -> `CCR1`; a sync edge (or the internal output period) -> the output latch's compare (`super::sync`) | 55 instr, 0.7 us (both edges pending: 1.1 us) |
//! | serial | `USART1` | 0x30 | RX byte -> RX queue; TX queue -> DR | 35 + 20 per byte, 0.9 us |
//! | Lissajous block | `DMA2_STREAM0` (HT/TC) | 0x40 | mark a half buffer ready, pend the readout task | 44 instr (static count), 0.6 us |
//! | ms tick | `SysTick` | 0x40 | millisecond counter for the protocol's timeouts | 10 instr |
//! | readout task | `EXTI1` (software-pended, no EXTI line routed) | 0x50 | the pick-off stream up to each queued output latch (`on_pickoff_sample`), `on_output_latch` per queued output latch, `on_turnaround` per queued sample + rate shift, `on_lissajous_sample` per pair (51 573 at a window solve), `CycleRecord` out; costs in docs/board.md | 18 us per turnaround; 0.33 ms per block, 0.82 ms with a solve |
//! | main loop | thread | - | protocol (line -> parse -> `Executor`), rate averaging (716 instr per cycle), calibration run (3 910), stream frame (921), flash store, watchdog | preemptible |
//!
//! Rate-monotonic reasoning: the turnaround latch has no deadline of its own (the hardware holds
//! the result until the next trigger, a half dither period later) but is the shortest, so it
//! goes first and never delays anything measurably. The dither drive tick has the shortest
//! period (25 us) and the tightest deadline (the DAC takes its holding register at the next
//! update, 23 us after the handler is raised; the sampling and the DAC update are timed by
//! TIM4 in hardware, so the handler's latency moves nothing), so it comes next: only the
//! 0.7 us latch can delay it. The pick-off handler must arm the compare within a quarter
//! period minus 2 us (248 us at 1 kHz): the tick takes at most a few us of that. The USART
//! must read each byte within one character time (21.7 us at 460 800 Bd): it is preempted
//! only by the three handlers above (one tick at most per character; with the tick that
//! closes a half cycle and a latch polling ADC3 to the end 4.7 + 12.2 + 1.1 = 18 us together).
//! The NMI (the clock security system) records a flag and returns. The
//! readout task has half a dither period per turnaround and 20.7 ms per Lissajous block; the
//! main loop takes whatever is left.
//!
//! # Shared state
//! - ISR -> readout task: `TurnaroundSample`s through a heapless SPSC queue (16 entries = 8
//!   dither cycles of slack), `OutputSample`s through another (8 entries: 8 ms at 1 kHz; a loss
//!   makes the next record a restart), the drive tick's pick-off codes through a third (128
//!   entries, 3.2 ms; a loss is a gap the dither model sees by the timestamps); Lissajous
//!   halves through an atomic bit mask (`adc`).
//! - readout task -> pick-off handler: the pick-off's measured lag through an `AtomicI32`
//!   (`turnaround::PICKOFF_LAG_TICKS`).
//! - readout task -> main loop: `OutputRecord`s through an SPSC queue (64 entries; a loss is a
//!   gap in the records' sequence numbers, which the host counts).
//! - The latch's compare plan (`turnaround::PLAN`, a `LatchPlan`) is shared by the pick-off
//!   and sync handler and the latch: short critical sections that also write CCR1.
//! - readout task -> main loop: `CycleRecord`s through an SPSC queue (32 entries); the input-rate
//!   shift for the scheduler through an `AtomicI32` (`turnaround::RATE_SHIFT_TICKS`).
//! - USART1 <-> main loop: byte queues (`usart`).
//! - The `Readout` itself (status, staging settings, re-synchronising) is shared by the readout
//!   task and the main loop (through the command service's `ReadoutAccess`, `super::ports`) via a
//!   [`PriorityLock`]: the main loop raises BASEPRI to the
//!   readout task's priority for the few instructions it needs; the latch, pick-off and serial
//!   handlers are never masked. Staged settings take effect whole at the next cycle boundary
//!   (`Readout::stage_compensation`): the STYLE.md atomic swap.
//! - Only the USART's `CR1` read-modify-write in the main loop uses a (3-instruction) critical
//!   section.
//!
//! # CPU load (docs/board.md has the derivation)
//! At a 389 Hz dither and a 1 kHz output: 21.6 % of 168 MHz (dither drive 10.0 %, the pick-off
//! stream's model 5.2 %, output latches 2.8 %, turnarounds 2.0 %, Lissajous stream 1.7 %);
//! with a calibration run and the binary stream on every cycle: 23.8 %.

use crate::millis::Millis;
use core::cell::UnsafeCell;
use core::sync::atomic::AtomicU32;

use cortex_m::peripheral::{scb::SystemHandler, NVIC, SCB, SYST};
use heapless::spsc::{Consumer, Producer, Queue};

use super::{adc, pac, turnaround, Owned, Shared};
use crate::board_timing::selftest::SelfTestReport;
use crate::dither::Coast;
use crate::dither::{DitherConfig, DitherController};
use crate::readout::{Readout, ReadoutConfig};
use crate::sample::{OutputSample, TurnaroundSample};
use crate::service::record_queue::{LossyProducer, Tagged};
use crate::signal::lockin::CycleRecord;
use crate::signal::output::dither_model::PickoffSample;
use crate::signal::output::latch_plan::LatchPlan;
use crate::signal::output::record::OutputRecord;
use crate::storage::DitherSetpoints;
use pac::Interrupt;

/// NVIC priorities (the F405 implements the upper 4 bits).
pub mod priority {
    /// `ADC` (JEOC): the turnaround latch, the highest.
    pub const TURNAROUND_LATCH: u8 = 0x00;
    /// `TIM4` (CC1): the dither drive tick, 40 kHz.
    pub const DITHER_TICK: u8 = 0x10;
    /// `TIM2` (CC3/CC4): the pick-off handler.
    pub const PICKOFF: u8 = 0x20;
    /// `USART1`: the serial link.
    pub const SERIAL: u8 = 0x30;
    /// `DMA2_STREAM0` (HT/TC): a Lissajous block ready.
    pub const LISSAJOUS_DMA: u8 = 0x40;
    /// `SysTick`: the millisecond tick.
    pub const TICK: u8 = 0x40;
    /// `EXTI1` (software-pended): the readout task, the lowest interrupt.
    pub const READOUT_TASK: u8 = 0x50;
}

/// The software-pended vector of the readout task (EXTI line 1 is not routed to any pin).
pub const READOUT_TASK_IRQ: Interrupt = Interrupt::EXTI1;

const TURNAROUND_QUEUE: usize = 17; // 16 usable
const RECORD_QUEUE: usize = 33; // 32 usable
const OUTPUT_LATCH_QUEUE: usize = 9; // 8 usable: 8 ms at a 1 kHz sync
const OUTPUT_RECORD_QUEUE: usize = 65; // 64 usable: 64 ms at a 1 kHz sync
/// The pick-off stream: 128 samples, 3.2 ms at 40 kHz, against the readout task's period (a
/// half dither cycle or an output period, 1.7 ms at most from 300 Hz and a 1 kHz output).
const PICKOFF_QUEUE: usize = 129;

/// Turnarounds lost because the readout task fell 16 behind.
pub static TURNAROUNDS_DROPPED: AtomicU32 = AtomicU32::new(0);
/// Cycle records the main loop did not take in time.
pub static RECORDS_DROPPED: AtomicU32 = AtomicU32::new(0);
/// Output latches lost because the readout task fell 8 behind: the record after them is a
/// restart (`Readout::break_output_chain`), its period spanning the loss.
pub static OUTPUT_LATCHES_DROPPED: AtomicU32 = AtomicU32::new(0);
/// Output records the main loop did not take in time: gaps in the records' sequence numbers.
pub static OUTPUT_RECORDS_DROPPED: AtomicU32 = AtomicU32::new(0);
/// Pick-off stream samples dropped on a full queue (the readout task held off for over
/// 3.2 ms): the dither model sees the gap in their timestamps and starts afresh, the output
/// meanwhile invalid (`NO_DITHER_MODEL`).
pub static PICKOFF_SAMPLES_DROPPED: AtomicU32 = AtomicU32::new(0);
/// Milliseconds since start (SysTick), 64 bits: never wraps.
static MILLIS: Millis = Millis::new();

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
    /// An empty lock at `ceiling`, the NVIC priority of its highest-priority user.
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
    /// The signal chain's settings.
    pub config: ReadoutConfig,
    /// The signal chain's state.
    pub readout: Readout,
    /// The task's end of the turnaround sample queue (16 entries), filled by the latch.
    pub samples: Consumer<'static, TurnaroundSample>,
    /// The task's end of the cycle record queue (32 entries), emptied by the main loop; a
    /// record dropped on a full queue is counted by the next one queued.
    pub records: LossyProducer<'static, CycleRecord>,
    /// The task's end of the output latch queue (8 entries), filled by the latch.
    pub output_samples: Consumer<'static, OutputSample>,
    /// The task's end of the output record queue (64 entries), emptied by the main loop.
    pub outputs: Producer<'static, OutputRecord>,
    /// The task's end of the pick-off stream (128 entries), filled by the drive tick.
    pub pickoff: Consumer<'static, PickoffSample>,
    /// [`OUTPUT_LATCHES_DROPPED`] as last seen: a change breaks the output chain.
    pub output_latches_dropped_seen: u32,
}

/// The main loop's ends of the readout task's queues.
pub struct ReadoutQueues {
    /// Closed dither cycles, each with the count dropped right before it.
    pub cycles: Consumer<'static, Tagged<CycleRecord>>,
    /// Output records.
    pub outputs: Consumer<'static, OutputRecord>,
}

/// What the drive tick owns: the dither controller and its settings.
pub struct DitherTask {
    /// The controller's settings (from the board profile).
    pub config: DitherConfig,
    /// The controller's state.
    pub controller: DitherController,
}

/// The dither controller, owned by the drive tick (`isr::tim4`), shared with the main loop.
pub static DITHER: PriorityLock<DitherTask> = PriorityLock::new(priority::DITHER_TICK);

/// The readout, shared by the readout task and the main loop.
pub static READOUT: PriorityLock<ReadoutTask> = PriorityLock::new(priority::READOUT_TASK);

/// [`DITHER`] as a [`Shared`] value (a handle without size: nothing to pass).
pub struct DitherLock;

impl Shared for DitherLock {
    type Value = DitherTask;

    #[inline(always)]
    fn lock<R>(&mut self, f: impl FnOnce(&mut DitherTask) -> R) -> Option<R> {
        DITHER.lock(f)
    }
}

/// [`READOUT`] as a [`Shared`] value.
pub struct ReadoutLock;

impl Shared for ReadoutLock {
    type Value = ReadoutTask;

    #[inline(always)]
    fn lock<R>(&mut self, f: impl FnOnce(&mut ReadoutTask) -> R) -> Option<R> {
        READOUT.lock(f)
    }
}
/// The turnaround latch's end of the sample queue (owner: `isr::adc`).
pub static LATCH_SIDE: Owned<Producer<'static, TurnaroundSample>> = Owned::new();
/// The latch's end of the output latch queue (owner: `isr::adc`).
pub static OUTPUT_LATCH_SIDE: Owned<Producer<'static, OutputSample>> = Owned::new();
/// The drive tick's end of the pick-off stream (owner: `isr::tim4`).
pub static PICKOFF_SIDE: Owned<Producer<'static, PickoffSample>> = Owned::new();
/// The pick-off handler's prediction state (owner: `isr::tim2`).
pub static SCHEDULER: Owned<turnaround::Scheduler> = Owned::new();

/// The main loop's ways to the values it shares with the handlers (`super::ports::BoardPorts`
/// holds them): the board's statics ([`STATIC_LOCKS`]), or an RTIC app's resource proxies.
pub struct Locks<R, D, P> {
    /// The readout task's state ([`READOUT`]).
    pub readout: R,
    /// The drive tick's controller ([`DITHER`]).
    pub dither: D,
    /// The latch's compare plan (`turnaround::PlanLock`).
    pub plan: P,
}

/// The board's statics, as the main loop reaches them.
pub type StaticLocks = Locks<ReadoutLock, DitherLock, turnaround::PlanLock>;

/// The board's statics.
pub const STATIC_LOCKS: StaticLocks = Locks {
    readout: ReadoutLock,
    dither: DitherLock,
    plan: turnaround::PlanLock,
};

/// The readout's state and every end of its queues, before they go to their contexts.
pub struct ReadoutParts {
    /// The readout task's state.
    pub task: ReadoutTask,
    /// The latch's end of the turnaround sample queue.
    pub latch: Producer<'static, TurnaroundSample>,
    /// The latch's end of the output latch queue.
    pub output_latch: Producer<'static, OutputSample>,
    /// The drive tick's end of the pick-off stream.
    pub pickoff: Producer<'static, PickoffSample>,
    /// The main loop's ends of the record queues.
    pub queues: ReadoutQueues,
}

/// Creates the queues and the readout task's state (once: the queues are static singletons).
#[allow(clippy::unwrap_used)] // at reset, once: the static queues are taken for the first time
pub fn readout_parts(config: ReadoutConfig, readout: Readout) -> ReadoutParts {
    let samples =
        cortex_m::singleton!(: Queue<TurnaroundSample, TURNAROUND_QUEUE> = Queue::new()).unwrap();
    let records =
        cortex_m::singleton!(: Queue<Tagged<CycleRecord>, RECORD_QUEUE> = Queue::new()).unwrap();
    let output_samples =
        cortex_m::singleton!(: Queue<OutputSample, OUTPUT_LATCH_QUEUE> = Queue::new()).unwrap();
    let outputs =
        cortex_m::singleton!(: Queue<OutputRecord, OUTPUT_RECORD_QUEUE> = Queue::new()).unwrap();
    let pickoff =
        cortex_m::singleton!(: Queue<PickoffSample, PICKOFF_QUEUE> = Queue::new()).unwrap();
    let (pickoff_in, pickoff_out) = pickoff.split();
    let (sample_in, sample_out) = samples.split();
    let (record_in, record_out) = records.split();
    let (output_sample_in, output_sample_out) = output_samples.split();
    let (output_in, output_out) = outputs.split();
    ReadoutParts {
        task: ReadoutTask {
            config,
            readout,
            samples: sample_out,
            records: LossyProducer::new(record_in),
            output_samples: output_sample_out,
            outputs: output_in,
            pickoff: pickoff_out,
            output_latches_dropped_seen: 0,
        },
        latch: sample_in,
        output_latch: output_sample_in,
        pickoff: pickoff_in,
        queues: ReadoutQueues {
            cycles: record_out,
            outputs: output_out,
        },
    }
}

/// Puts the readout's parts into the statics of their contexts; returns the main loop's ends
/// of the record queues.
pub fn install_readout(parts: ReadoutParts) -> ReadoutQueues {
    PICKOFF_SIDE.init(parts.pickoff);
    LATCH_SIDE.init(parts.latch);
    OUTPUT_LATCH_SIDE.init(parts.output_latch);
    READOUT.init(parts.task);
    parts.queues
}

/// Creates the queues and the readout ([`readout_parts`], [`install_readout`]); returns the
/// main loop's ends of the record queues.
pub fn init_readout(config: ReadoutConfig, readout: Readout) -> ReadoutQueues {
    install_readout(readout_parts(config, readout))
}

/// Milliseconds since start (64 bits, monotonic).
pub fn now_ms() -> u64 {
    MILLIS.now_ms()
}

/// One SysTick: a millisecond passed (`isr::systick` only, the clock's single writer).
pub fn tick_ms() {
    MILLIS.tick();
}

/// Puts the vector table in RAM (`super::ram`), sets the priorities of every board context and
/// starts the 1 ms tick. Interrupt lines stay masked; the callers unmask what they use.
pub fn init_core(scb: &mut SCB, nvic: &mut NVIC, syst: &mut SYST) {
    super::ram::install_vectors(scb);
    set_priorities(scb, nvic);
    start_tick(syst);
}

/// Sets the NVIC and SysTick priorities of [`priority`].
fn set_priorities(scb: &mut SCB, nvic: &mut NVIC) {
    // SAFETY: priorities are set before any of these interrupts is unmasked.
    unsafe {
        nvic.set_priority(Interrupt::ADC, priority::TURNAROUND_LATCH);
        nvic.set_priority(Interrupt::TIM4, priority::DITHER_TICK);
        nvic.set_priority(Interrupt::TIM2, priority::PICKOFF);
        nvic.set_priority(Interrupt::USART1, priority::SERIAL);
        nvic.set_priority(Interrupt::DMA2_STREAM0, priority::LISSAJOUS_DMA);
        nvic.set_priority(READOUT_TASK_IRQ, priority::READOUT_TASK);
        scb.set_priority(SystemHandler::SysTick, priority::TICK);
    }
}

/// Starts SysTick's 1 ms interrupt.
pub fn start_tick(syst: &mut SYST) {
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

/// Starts the dither controller with the stored setpoints (`DitherController::apply_stored`:
/// none stored, the defaults, enabled; a refused record keeps its `enabled`) and unmasks the
/// drive tick. With the board's power-up checks (`selftest`) passed the pick-off check runs
/// first (the half-drive sweep, `crate::dither`'s `self_test`), then the start-up if the drive
/// is wanted on; with a check failed the drive is inhibited. `None`: no board (the QEMU serial
/// example: the controller exists for the protocol, its tick never runs). TIM4, the DAC and
/// ADC3 must be set up (`dither::init`).
pub fn start_dither(
    config: DitherConfig,
    stored: Option<DitherSetpoints>,
    selftest: Option<&SelfTestReport>,
) {
    install_dither(dither_task(config, stored, selftest));
}

/// The drive tick's state as [`start_dither`] starts it: the controller with the stored
/// setpoints (and the pick-off check, or inhibited) and the coast state that follows it.
pub fn dither_task(
    config: DitherConfig,
    stored: Option<DitherSetpoints>,
    selftest: Option<&SelfTestReport>,
) -> (DitherTask, Coast) {
    let mut controller = DitherController::new(&config);
    controller.apply_stored(&config, stored);
    match selftest {
        Some(report) if report.hardware_passed() => controller.start_self_test(),
        Some(_) => controller.inhibit(),
        None => {}
    }
    let coast = Coast::new(&controller);
    (DitherTask { config, controller }, coast)
}

/// Puts the drive tick's state into its statics and unmasks the tick.
pub fn install_dither((task, coast): (DitherTask, Coast)) {
    super::dither::COAST.init(coast);
    DITHER.init(task);
    // SAFETY: the tick's state was initialised just above.
    unsafe { NVIC::unmask(Interrupt::TIM4) };
}

/// Stops every readout interrupt for a flash erase (`ports::BoardPorts::stop_readout`):
/// producers first, then the readout task is run once to empty the sample queue (it preempts
/// the caller at once), then masked too. The dither drive goes on: its tick runs from RAM and
/// coasts through the erase (`super::ram`).
pub fn pause_readout(hardware: bool, plan: &mut impl Shared<Value = LatchPlan>) {
    if hardware {
        NVIC::mask(Interrupt::ADC);
        NVIC::mask(Interrupt::TIM2);
        NVIC::mask(Interrupt::DMA2_STREAM0);
        // SAFETY: TIM2's handler is masked: the main loop may park its compare.
        turnaround::pause(unsafe { &*pac::TIM2::ptr() }, plan);
    }
    NVIC::pend(READOUT_TASK_IRQ);
    // The pended task (priority 0x50, above thread mode) is taken before the next instruction
    // completes.
    cortex_m::asm::dsb();
    cortex_m::asm::isb();
    NVIC::mask(READOUT_TASK_IRQ);
}

/// Resumes after a store (`ports::BoardPorts::restart_readout`): the readout re-synchronises (count reference, quadrant, open cycle are
/// dropped), stale hardware results are discarded, interrupts unmasked.
pub fn resume_readout(hardware: bool, readout: &mut impl Shared<Value = ReadoutTask>) {
    readout.lock(|task| task.readout.resynchronise());
    if hardware {
        // SAFETY: the latch handler is masked; a result taken before the stall is stale.
        adc::discard_injected(unsafe { &*pac::ADC1::ptr() });
        NVIC::unpend(Interrupt::ADC);
        NVIC::unpend(Interrupt::TIM2);
    }
    unmask_readout(hardware);
}
