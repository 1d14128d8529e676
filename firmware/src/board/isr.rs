//! The interrupt handlers: thin. Each copies its registers into plain structs (a
//! `TurnaroundSample`, an edge time, a byte, a ready flag) and calls plain logic or hands the
//! data on through a queue; the priorities, queues and locks they use are in
//! [`super::resources`]. The bodies are bound to the vectors by [`crate::bind_board_interrupts`]
//! in the binary, not here: a library that owned vectors would force them on every binary that
//! links it, the on-target tests included.
//!
//! Each handler with state is two functions: the body ([`latch`], [`drive_tick`], [`pickoff`],
//! [`readout_pass`]), which takes its own state and the values it shares as parameters, and
//! the board's handler ([`adc`], [`tim4`], [`tim2`], [`readout_task`]), which hands the body
//! the statics of [`super::resources`]. `examples/rtic_board.rs` hands the same bodies RTIC's
//! resources instead.

use core::sync::atomic::Ordering;

use cortex_m::peripheral::NVIC;
use heapless::spsc::Producer;

use super::resources::{
    self, DitherLock, DitherTask, ReadoutTask, LATCH_SIDE, OUTPUT_LATCHES_DROPPED,
    OUTPUT_LATCH_SIDE, OUTPUT_RECORDS_DROPPED, PICKOFF_SAMPLES_DROPPED, PICKOFF_SIDE, READOUT,
    READOUT_TASK_IRQ, RECORDS_DROPPED, SCHEDULER, TURNAROUNDS_DROPPED,
};
use super::turnaround::{Latched, PlanLock, Scheduler};
use super::{adc, dither, pac, turnaround, usart, Shared};
use crate::dither::Coast;
use crate::sample::{OutputSample, TurnaroundSample};
use crate::signal::output::dither_model::PickoffSample;
use crate::signal::output::latch_plan::LatchPlan;
use crate::signal::output::record::OutputStatus;

/// `ADC`: [`latch`] with the board's statics.
pub fn adc() {
    latch(
        &mut PlanLock,
        // SAFETY: this handler is the only producer of both queues.
        || unsafe { LATCH_SIDE.get() },
        || unsafe { OUTPUT_LATCH_SIDE.get() },
    );
}

/// The latch (JEOC of ADC1): a turnaround, or an output latch (`super::sync`), into its queue
/// (each reached only when a sample is for it); first a regular-group overrun, which restarts
/// the photodiode stream (`super::adc`).
#[inline(always)]
pub fn latch<'q>(
    plan: &mut impl Shared<Value = LatchPlan>,
    turnarounds: impl FnOnce() -> Option<&'q mut Producer<'static, TurnaroundSample>>,
    outputs: impl FnOnce() -> Option<&'q mut Producer<'static, OutputSample>>,
) {
    // SAFETY: the ADC common CCR, the ADCs' OVR flags and DMA2 stream 0 are touched here only
    // by the stream's restart (see `adc::restart_stream`).
    let (common, dma) = unsafe { (&*pac::ADC_COMMON::ptr(), &*pac::DMA2::ptr()) };
    // SAFETY: register reads/flag clears of peripherals this handler owns after start-up; the
    // CCR1 write is inside the plan's critical section (`turnaround::latch`). ADC3's regular
    // data register is read by this handler only (the drive tick reads its injected one).
    let (adc1, adc2, adc3, tim2, tim5) = unsafe {
        (
            &*pac::ADC1::ptr(),
            &*pac::ADC2::ptr(),
            &*pac::ADC3::ptr(),
            &*pac::TIM2::ptr(),
            &*pac::TIM5::ptr(),
        )
    };
    if !adc::on_adc_interrupt(common, adc1, adc2, dma) {
        return;
    }
    match turnaround::latch(adc1, adc2, adc3, tim2, tim5, plan) {
        Some(Latched::Turnaround(sample)) => {
            if let Some(queue) = turnarounds() {
                if queue.enqueue(sample).is_err() {
                    TURNAROUNDS_DROPPED.fetch_add(1, Ordering::Relaxed);
                }
            }
        }
        Some(Latched::Output(sample)) => {
            if let Some(queue) = outputs() {
                if queue.enqueue(sample).is_err() {
                    OUTPUT_LATCHES_DROPPED.fetch_add(1, Ordering::Relaxed);
                }
            }
        }
        None => return,
    }
    NVIC::pend(READOUT_TASK_IRQ);
}

/// `TIM4`: [`drive_tick`] with the board's statics. Runs from RAM (`super::ram`): inlined
/// there whole.
#[inline(always)]
pub fn tim4() {
    // SAFETY: this handler owns the coast state and is the only producer of the stream.
    let (coast, stream) = unsafe { (dither::COAST.get(), PICKOFF_SIDE.get()) };
    drive_tick(coast, &mut DitherLock, stream);
}

/// The dither drive tick (TIM4 CC1), and the pick-off stream's sample. Inlined whole into the
/// RAM-resident handler (`super::ram`).
#[inline(always)]
pub fn drive_tick(
    coast: Option<&mut Coast>,
    dither: &mut impl Shared<Value = DitherTask>,
    stream: Option<&mut Producer<'static, PickoffSample>>,
) {
    // SAFETY: TIM4's SR, ADC3's SR/JDR1 and the DAC's DHR12R1 are used by this handler only
    // after start-up (and by the main loop's store pause, with this interrupt masked); TIM2's
    // and TIM4's counters are only read.
    let (tim, adc3, dac, tim2) = unsafe {
        (
            &*pac::TIM4::ptr(),
            &*pac::ADC3::ptr(),
            &*pac::DAC::ptr(),
            &*pac::TIM2::ptr(),
        )
    };
    let sample = dither::on_tick(tim, adc3, dac, tim2, coast, dither);
    if let Some(queue) = stream {
        if queue.enqueue(sample).is_err() {
            PICKOFF_SAMPLES_DROPPED.fetch_add(1, Ordering::Relaxed);
        }
    }
}

/// `TIM2`: [`pickoff`] with the board's statics.
pub fn tim2() {
    // SAFETY: this handler owns the scheduler.
    pickoff(unsafe { SCHEDULER.get() }, &mut PlanLock);
}

/// A pick-off edge or a sync edge (TIM2).
#[inline(always)]
pub fn pickoff(scheduler: Option<&mut Scheduler>, plan: &mut impl Shared<Value = LatchPlan>) {
    // SAFETY: TIM2's SR/CCR are used by this handler only after start-up (and by the main
    // loop's pause, with this interrupt masked).
    let tim = unsafe { &*pac::TIM2::ptr() };
    if let Some(scheduler) = scheduler {
        turnaround::on_pickoff_interrupt(tim, scheduler, plan);
    }
}

/// `USART1`. Runs from RAM (`super::ram`): inlined there whole.
#[inline(always)]
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

/// `NonMaskableInt`: the clock security system (the crystal stopped). Touches only RCC_CIR
/// and an atomic flag: the NMI preempts every critical section.
pub fn nmi() {
    super::clocks::on_nmi();
}

/// `SysTick`: 1 ms. Runs from RAM (`super::ram`): inlined there whole.
#[inline(always)]
pub fn systick() {
    resources::tick_ms();
}

/// `EXTI1` (software): the readout task, [`readout_pass`] in the readout's lock.
pub fn readout_task() {
    READOUT.lock(readout_pass);
}

/// The readout task's pass: the queued output latches, pick-off samples, turnarounds and
/// Lissajous blocks through the readout, its records out.
#[inline(always)]
pub fn readout_pass(task: &mut ReadoutTask) {
    // Output latches first (they are older than the turnaround that pended the task at
    // most by a few microseconds, and each record carries its own time).
    let dropped = OUTPUT_LATCHES_DROPPED.load(Ordering::Relaxed);
    if dropped != task.output_latches_dropped_seen {
        task.output_latches_dropped_seen = dropped;
        task.readout.break_output_chain();
    }
    let timing_fault = super::watch::TIMING_FAULT.load(Ordering::Relaxed);
    // Each output latch first, with the dither model as the stream so far made it (the
    // model evaluates its sine at the latch's own instant: a fit a millisecond older is the
    // same sine), then the stream up to it: the record's latency is the latch's own work,
    // not a backlog of pick-off samples.
    while let Some(sample) = task.output_samples.dequeue() {
        if timing_fault {
            task.readout.mark_output(OutputStatus::TIMING_FAULT);
        }
        let record = task.readout.on_output_latch(&task.config, sample);
        if task.outputs.enqueue(record).is_err() {
            OUTPUT_RECORDS_DROPPED.fetch_add(1, Ordering::Relaxed);
        }
        if let Some(lag) = task.readout.pickoff_lag_ticks(&task.config) {
            turnaround::publish_pickoff_lag(lag);
        }
        let at = sample.timestamp_ticks;
        while task
            .pickoff
            .peek()
            .is_some_and(|p| at.wrapping_sub(p.timestamp_ticks) < u32::MAX / 2)
        {
            if let Some(p) = task.pickoff.dequeue() {
                task.readout.on_pickoff_sample(&task.config, p);
            }
        }
    }
    while let Some(p) = task.pickoff.dequeue() {
        task.readout.on_pickoff_sample(&task.config, p);
    }
    while let Some(sample) = task.samples.dequeue() {
        if let Some(record) = task.readout.on_turnaround(&task.config, sample) {
            turnaround::publish_rate_shift(&record);
            if !task.records.push(record) {
                RECORDS_DROPPED.fetch_add(1, Ordering::Relaxed);
            }
        }
    }
    let (config, readout) = (&task.config, &mut task.readout);
    adc::take_ready_blocks(|a, b| readout.on_lissajous_sample(config, a, b));
}

/// Binds the board's flash-resident handlers to the vector table. Invoke once, at the top level
/// of the binary that runs the board (`board::app::run`, or `board::app::serve` in the QEMU
/// serial example). `TIM4`, `USART1` and `SysTick` are not here: their handlers are in RAM,
/// put into the RAM copy of the table by `super::ram::install_vectors` (`resources::init_core`).
#[macro_export]
macro_rules! bind_board_interrupts {
    () => {
        mod board_vectors {
            use $crate::rt::pac::interrupt;

            #[cortex_m_rt::interrupt]
            fn ADC() {
                $crate::board::isr::adc()
            }
            #[cortex_m_rt::interrupt]
            fn TIM2() {
                $crate::board::isr::tim2()
            }
            #[cortex_m_rt::interrupt]
            fn DMA2_STREAM0() {
                $crate::board::isr::dma2_stream0()
            }
            #[cortex_m_rt::interrupt]
            fn EXTI1() {
                $crate::board::isr::readout_task()
            }
            // SAFETY: the NMI preempts critical sections: its handler touches only RCC_CIR
            // and an atomic flag, nothing a critical section guards.
            #[cortex_m_rt::exception]
            unsafe fn NonMaskableInt() {
                $crate::board::isr::nmi()
            }
        }
    };
}
