//! The figures both bindings of the board's handlers are measured by, on the emulated M4F
//! (QEMU `-icount shift=0`: one counter tick per instruction): the board's own binding
//! (`board_cost.rs`: the statics of `board::resources`, handlers bound by
//! `bind_board_interrupts!` and `board::ram`) and RTIC's (`rtic_cost.rs`, feature
//! `rtic-study`). One module, so both print the same lines measured the same way
//! (docs/firmware.md#concurrency compares them):
//!
//! - each handler taken through its exception: pended from thread mode, counted to its
//!   return, less the same pend with interrupts off. That is the handler whole, the binding's
//!   entry and exit code included; the core's own stacking (12 cycles in, 10-12 out) is no
//!   instruction and comes on top on silicon. The least of five runs (a SysTick falling into one
//!   would add its own);
//! - an empty handler (`EXTI2`, bound by each binary with an empty body at the readout task's
//!   priority): the binding's own code per interrupt;
//! - each lock's round trip from the main loop (an empty section), and the main loop's
//!   sections under the dither controller's lock (they hold the drive tick off) and under
//!   the latch plan's (they hold every interrupt off);
//! - the main loop's two recurring log messages: defmt's logger holds every interrupt off
//!   while it encodes and writes a message (a critical section in `acquire`..`release`, both
//!   the RTT logger of `hw` and the semihosting logger measured here, whose write is one
//!   trap; RTT's copy into its RAM buffer comes on top on a board).
//!
//! The latch handler runs its full path (the plan armed first; QEMU never sets ADC3's EOC, so
//! its poll runs to the end) with the readout task held off by its lock meanwhile (the
//! turnaround it queues would otherwise be processed inside the count); the drive tick with
//! the controller switched off; the rest on their idle paths.

use core::hint::black_box;

use cortex_m::peripheral::{NVIC, SCB};
use firmware::board::app::Health;
use firmware::board::pac::{self, Interrupt};
use firmware::board::resources::{DitherTask, Locks, ReadoutTask};
use firmware::board::turnaround::{self, Schedule};
use firmware::board::Shared;
use firmware::dither::DitherState;
use firmware::icount::InstructionCounter;
use firmware::sample::TurnaroundKind;
use firmware::signal::output::latch_plan::LatchPlan;
use firmware::storage::DitherSetpoints;

/// A vector to pend.
#[derive(Clone, Copy)]
enum Vector {
    Irq(Interrupt),
    SysTick,
}

fn pend(vector: Vector) {
    match vector {
        Vector::Irq(irq) => NVIC::pend(irq),
        Vector::SysTick => SCB::set_pendst(),
    }
    // Taken before the next instruction (as `resources::pause_readout` relies on).
    cortex_m::asm::dsb();
    cortex_m::asm::isb();
}

fn unpend(vector: Vector) {
    match vector {
        Vector::Irq(irq) => NVIC::unpend(irq),
        Vector::SysTick => SCB::clear_pendst(),
    }
}

/// Instructions of the handler of `vector` taken through its exception (module docs);
/// `before` runs ahead of each pend (the latch's plan is armed there).
fn through_exception(
    counter: &InstructionCounter,
    vector: Vector,
    mut before: impl FnMut(),
) -> u32 {
    let mut least = u32::MAX;
    for _ in 0..5 {
        before();
        let pend_only = cortex_m::interrupt::free(|_| {
            let n = counter.count(|| pend(vector));
            unpend(vector);
            n
        });
        let whole = counter.count(|| pend(vector));
        least = least.min(whole.saturating_sub(pend_only));
    }
    least
}

/// Arms the compare for a turnaround a quarter of TIM2's range ahead, as the pick-off handler
/// would (the latch discards a match nobody armed).
fn arm(plan: &mut impl Shared<Value = LatchPlan>) {
    // SAFETY: TIM2's counter is only read; its compare is written through the plan.
    let tim2 = unsafe { &*pac::TIM2::ptr() };
    let now = tim2.cnt().read().bits();
    let schedule = Schedule {
        compare_ticks: now.wrapping_add(1 << 30),
        kind: TurnaroundKind::Minus,
    };
    turnaround::arm(tim2, schedule, now, plan);
}

/// Instructions of `f`, the least of five.
fn least_of_five(counter: &InstructionCounter, mut f: impl FnMut()) -> u32 {
    (0..5).map(|_| counter.count(&mut f)).min().unwrap_or(0)
}

/// Measures and logs every figure (module docs) with `binding` ("board", "rtic") in front.
/// Every handler and the lines `EXTI2` (empty) must be bound and unmasked, their state set
/// (the dither controller switched off); `locks` are the main loop's.
pub fn measure<R, D, P>(binding: &str, counter: &InstructionCounter, locks: &mut Locks<R, D, P>)
where
    R: Shared<Value = ReadoutTask>,
    D: Shared<Value = DitherTask>,
    P: Shared<Value = LatchPlan>,
{
    let Locks {
        readout,
        dither,
        plan,
    } = locks;
    let empty = through_exception(counter, Vector::Irq(Interrupt::EXTI2), || {});
    let latch = readout
        .lock(|_| through_exception(counter, Vector::Irq(Interrupt::ADC), || arm(plan)))
        .unwrap_or(0);
    let tick = through_exception(counter, Vector::Irq(Interrupt::TIM4), || {});
    let pickoff = through_exception(counter, Vector::Irq(Interrupt::TIM2), || {});
    let serial = through_exception(counter, Vector::Irq(Interrupt::USART1), || {});
    let dma = through_exception(counter, Vector::Irq(Interrupt::DMA2_STREAM0), || {});
    let systick = through_exception(counter, Vector::SysTick, || {});
    let readout_task = through_exception(counter, Vector::Irq(Interrupt::EXTI1), || {});
    defmt::info!(
        "{=str} binding, through the exception: empty handler {=u32}, ADC latch {=u32}, TIM4 drive tick (controller off) {=u32}, TIM2 pick-off (no edge) {=u32}, USART1 (idle) {=u32}, DMA2_STREAM0 (no flag) {=u32}, SysTick {=u32}, EXTI1 readout task (queues empty) {=u32} instructions",
        binding, empty, latch, tick, pickoff, serial, dma, systick, readout_task
    );

    let readout_lock = least_of_five(counter, || {
        readout.lock(|v| {
            black_box(v);
        });
    });
    let dither_lock = least_of_five(counter, || {
        dither.lock(|v| {
            black_box(v);
        });
    });
    let plan_lock = least_of_five(counter, || {
        plan.lock(|v| {
            black_box(v);
        });
    });
    defmt::info!(
        "{=str} binding, lock round trip from the main loop (empty section): readout {=u32}, dither {=u32}, latch plan {=u32} instructions",
        binding, readout_lock, dither_lock, plan_lock
    );

    // The main loop's sections under the dither controller's lock, lock included.
    let status = least_of_five(counter, || {
        black_box(dither.lock(|t| t.controller.status(&t.config)));
    });
    let state = least_of_five(counter, || {
        black_box(dither.lock(|t| t.controller.state()));
    });
    let amplitude_check = least_of_five(counter, || {
        dither.lock(|t| {
            t.controller
                .check_count_amplitude(&t.config, black_box(1500.0))
        });
    });
    let watch = least_of_five(counter, || {
        black_box(dither.lock(|t| {
            (t.controller.state() == DitherState::Locked)
                .then(|| t.controller.estimate().frequency_hz)
        }));
    });
    let setpoints = least_of_five(counter, || {
        black_box(dither.lock(|t| t.controller.setpoints()));
    });
    // `dither set`: a new amplitude and noise depth, the drive left off (each run alternates
    // between two amplitudes, so every one changes it).
    let mut amplitude = 400.0;
    let apply = least_of_five(counter, || {
        amplitude = if amplitude == 400.0 { 420.0 } else { 400.0 };
        let new = DitherSetpoints {
            enabled: false,
            amplitude_arcsec: black_box(amplitude),
            noise_percent: 25.0,
        };
        black_box(dither.lock(|t| t.controller.apply_setpoints(&t.config, new)));
    });
    defmt::info!(
        "{=str} binding, main loop under the dither lock (lock included): status {=u32}, state {=u32}, count amplitude check {=u32}, watch's estimate {=u32}, setpoints {=u32}, apply setpoints {=u32} instructions",
        binding, status, state, amplitude_check, watch, setpoints, apply
    );

    // The latch plan's sections (interrupts off): arming a turnaround (the pick-off handler's,
    // with the few instructions of `turnaround::arm` around it), a store's pause, the overrun
    // count for the health log.
    let arm_section = least_of_five(counter, || arm(plan));
    // SAFETY: the pick-off handler does not run (no edge is captured): the main loop may park
    // the compare, as a store's pause does with that handler masked.
    let tim2 = unsafe { &*pac::TIM2::ptr() };
    let pause = least_of_five(counter, || turnaround::pause(tim2, plan));
    let overruns = least_of_five(counter, || {
        black_box(turnaround::sync_overruns(plan));
    });
    defmt::info!(
        "{=str} binding, latch plan sections (interrupts off, lock included): arm a turnaround {=u32} (whole call), pause {=u32}, overrun count {=u32} instructions",
        binding, arm_section, pause, overruns
    );

    let health = Health::now(0, 0);
    let log_status = dither
        .lock(|t| t.controller.status(&t.config))
        .map_or(0, |status| {
            counter.count(|| defmt::info!("dither: {}", status))
        });
    let log_health = counter.count(|| defmt::warn!("board health: {}", health));
    defmt::info!(
        "{=str} binding, the main loop's log messages (interrupts off): dither status {=u32}, board health {=u32} instructions",
        binding, log_status, log_health
    );
}
