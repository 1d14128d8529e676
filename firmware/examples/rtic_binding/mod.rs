//! What the RTIC examples (`rtic_board.rs`, `rtic_cost.rs`; feature `rtic-study`) share: the
//! adapter from RTIC's resource proxies to the board's `Shared`, and the check that the app's
//! priorities (literals in `#[task(priority = N)]`, which RTIC turns into NVIC and SysTick
//! priorities before `init`) are the board's table, `board::resources::priority`.

use cortex_m::peripheral::scb::SystemHandler;
use cortex_m::peripheral::{NVIC, SCB};
use firmware::board::pac::Interrupt;
use firmware::board::resources::{priority, READOUT_TASK_IRQ};

/// An RTIC resource proxy as the board's [`firmware::board::Shared`]: RTIC's lock (the value
/// is always there: RTIC initialises every resource in `init`).
pub struct Rtic<M>(pub M);

impl<M: rtic::Mutex> firmware::board::Shared for Rtic<M> {
    type Value = M::T;

    #[inline(always)]
    fn lock<R>(&mut self, f: impl FnOnce(&mut M::T) -> R) -> Option<R> {
        Some(self.0.lock(f))
    }
}

/// Panics unless every bound vector has the board's priority (call in `init`, after RTIC has
/// set them). RTIC's logical priority p is the NVIC's `(16 - p) << 4` on the F405's 4 bits: 16
/// the latch, 15 the drive tick, 14 the pick-off, 13 the serial link, 12 the Lissajous DMA and
/// SysTick, 11 the readout task.
pub fn check_priorities() {
    let irqs = [
        (Interrupt::ADC, priority::TURNAROUND_LATCH),
        (Interrupt::TIM4, priority::DITHER_TICK),
        (Interrupt::TIM2, priority::PICKOFF),
        (Interrupt::USART1, priority::SERIAL),
        (Interrupt::DMA2_STREAM0, priority::LISSAJOUS_DMA),
        (READOUT_TASK_IRQ, priority::READOUT_TASK),
    ];
    for (irq, board) in irqs {
        let app = NVIC::get_priority(irq);
        defmt::assert_eq!(app, board, "priority of IRQ {=u16}", irq as u16);
    }
    let app = SCB::get_priority(SystemHandler::SysTick);
    defmt::assert_eq!(app, priority::TICK, "priority of SysTick");
}

/// What `init` hands the tasks: every value of the board's RTIC resources.
pub struct Resources {
    /// The readout task's state (shared with the main loop).
    pub readout: firmware::board::resources::ReadoutTask,
    /// The dither controller (shared with the main loop).
    pub dither: firmware::board::resources::DitherTask,
    /// The latch's end of the turnaround queue.
    pub latch: heapless::spsc::Producer<'static, firmware::sample::TurnaroundSample>,
    /// The latch's end of the output latch queue.
    pub output_latch: heapless::spsc::Producer<'static, firmware::sample::OutputSample>,
    /// The drive tick's end of the pick-off stream.
    pub pickoff:
        heapless::spsc::Producer<'static, firmware::signal::output::dither_model::PickoffSample>,
    /// The drive tick's coast state.
    pub coast: firmware::dither::Coast,
    /// The pick-off handler's prediction.
    pub scheduler: firmware::board::turnaround::Scheduler,
    /// The USART1 handler's queue ends.
    pub serial_isr: firmware::board::usart::IsrSide,
}

/// The board as an RTIC app: its resources (three shared, the rest local) and its seven
/// hardware tasks on the board's handler bodies, one list for every binary that binds the
/// board this way (as `bind_board_interrupts!` is for the board's own binding). The binary
/// gives the type of what its main loop takes over (`parts`), `init`'s body (the core and
/// device peripherals in, `(Resources, parts)` out), `idle`'s body (the parts and the shared
/// values as `board::resources::Locks` in; it never returns) and any tasks of its own.
macro_rules! board_app {
    (
        parts: $parts:ty,
        init: |$core:ident, $device:ident| { $($init:tt)* },
        idle: |$taken:ident, $locks:ident| { $($idle:tt)* },
        $($extra:tt)*
    ) => {
        #[rtic::app(device = firmware::rt::pac, peripherals = true)]
        mod app {
            use super::*;
            use $crate::rtic_binding::{check_priorities, Resources, Rtic};
            use firmware::board::resources::{DitherTask, Locks, ReadoutTask};
            use firmware::board::{isr, usart};
            use firmware::signal::output::latch_plan::LatchPlan;

            #[shared]
            struct Shared {
                /// The readout task (11) and the main loop: ceiling 11.
                readout: ReadoutTask,
                /// The drive tick (15) and the main loop: ceiling 15.
                dither: DitherTask,
                /// The latch (16), the pick-off handler (14) and the main loop: ceiling 16,
                /// the top, so its lock is a critical section.
                plan: LatchPlan,
            }

            #[local]
            struct Local {
                latch: heapless::spsc::Producer<'static, firmware::sample::TurnaroundSample>,
                output_latch: heapless::spsc::Producer<'static, firmware::sample::OutputSample>,
                pickoff: heapless::spsc::Producer<
                    'static,
                    firmware::signal::output::dither_model::PickoffSample,
                >,
                coast: firmware::dither::Coast,
                scheduler: firmware::board::turnaround::Scheduler,
                serial_isr: usart::IsrSide,
                parts: Option<$parts>,
            }

            #[init]
            fn init(cx: init::Context) -> (Shared, Local) {
                check_priorities();
                #[allow(unused_mut)]
                let mut $core = cx.core;
                let $device = cx.device;
                let (r, parts): (Resources, $parts) = { $($init)* };
                (
                    Shared {
                        readout: r.readout,
                        dither: r.dither,
                        plan: LatchPlan::new(),
                    },
                    Local {
                        latch: r.latch,
                        output_latch: r.output_latch,
                        pickoff: r.pickoff,
                        coast: r.coast,
                        scheduler: r.scheduler,
                        serial_isr: r.serial_isr,
                        parts: Some(parts),
                    },
                )
            }

            #[idle(shared = [readout, dither, plan], local = [parts])]
            fn idle(cx: idle::Context) -> ! {
                let Some($taken) = cx.local.parts.take() else {
                    // `init` always hands them over; idle runs once.
                    loop {
                        cortex_m::asm::wfi();
                    }
                };
                #[allow(unused_mut)]
                let mut $locks = Locks {
                    readout: Rtic(cx.shared.readout),
                    dither: Rtic(cx.shared.dither),
                    plan: Rtic(cx.shared.plan),
                };
                $($idle)*
            }

            /// The turnaround latch.
            #[task(binds = ADC, priority = 16, shared = [plan], local = [latch, output_latch])]
            fn adc(cx: adc::Context) {
                let (latch, output_latch) = (cx.local.latch, cx.local.output_latch);
                isr::latch(
                    &mut Rtic(cx.shared.plan),
                    || Some(latch),
                    || Some(output_latch),
                );
            }

            /// The dither drive tick, from RAM.
            #[task(binds = TIM4, priority = 15, shared = [dither], local = [coast, pickoff])]
            #[link_section = ".data.ramfunc.tim4"]
            fn tim4(cx: tim4::Context) {
                isr::drive_tick(
                    Some(cx.local.coast),
                    &mut Rtic(cx.shared.dither),
                    Some(cx.local.pickoff),
                );
            }

            /// The pick-off and sync edges.
            #[task(binds = TIM2, priority = 14, shared = [plan], local = [scheduler])]
            fn tim2(cx: tim2::Context) {
                isr::pickoff(Some(cx.local.scheduler), &mut Rtic(cx.shared.plan));
            }

            /// The serial link, from RAM.
            #[task(binds = USART1, priority = 13, local = [serial_isr])]
            #[link_section = ".data.ramfunc.usart1"]
            fn usart1(cx: usart1::Context) {
                usart::transfer(cx.local.serial_isr);
            }

            /// A Lissajous half buffer.
            #[task(binds = DMA2_STREAM0, priority = 12)]
            fn dma2_stream0(_: dma2_stream0::Context) {
                isr::dma2_stream0();
            }

            /// The millisecond tick, from RAM.
            #[task(binds = SysTick, priority = 12)]
            #[link_section = ".data.ramfunc.systick"]
            fn systick(_: systick::Context) {
                isr::systick();
            }

            /// The readout task (software-pended by the latch and the Lissajous DMA handler).
            #[task(binds = EXTI1, priority = 11, shared = [readout])]
            fn readout_task(mut cx: readout_task::Context) {
                cx.shared.readout.lock(isr::readout_pass);
            }

            $($extra)*
        }

        /// The NMI (the clock security system) stays a cortex-m-rt exception: RTIC binds only
        /// exceptions of configurable priority.
        mod nmi {
            // SAFETY: the NMI preempts critical sections: its handler touches only RCC_CIR
            // and an atomic flag, nothing a critical section guards.
            #[cortex_m_rt::exception]
            unsafe fn NonMaskableInt() {
                firmware::board::isr::nmi()
            }
        }
    };
}
