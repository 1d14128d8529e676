//! The board's handlers bound by RTIC 2, measured on the emulated M4F as `board_cost.rs`
//! measures the board's own binding (the shared module `binding_cost`; docs/firmware.md
//! #concurrency compares the two):
//!
//! ```text
//! cargo fw-icount --features rtic-study --example rtic_cost
//! ```
//!
//! The app is `rtic_board.rs`'s (`rtic_binding`'s `board_app!`: the same tasks, priorities,
//! vectors, RAM placement and resources), with a start-up that sets only what the measurement
//! needs (no timer, ADC or DMA is started, the dither controller is off, the counter is TIM5)
//! and an empty task on `EXTI2`.
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
mod binding_cost;
#[cfg(target_os = "none")]
#[macro_use]
mod rtic_binding;

#[cfg(target_os = "none")]
use firmware::board::{ram, resources};
#[cfg(target_os = "none")]
use firmware::icount::{InstructionCounter, Timer};

#[cfg(target_os = "none")]
board_app! {
    parts: InstructionCounter,
    init: |core, device| {
        ram::relocate_vectors(&mut core.SCB, &[]);
        let counter = InstructionCounter::start(Timer::Tim5);
        let profile = firmware::profile::BoardProfile::F405;
        let config = profile.readout_config(389.0);
        let readout = resources::readout_parts(
            config,
            firmware::readout::Readout::new(
                &config,
                firmware::signal::compensation::CompensationSettings::default(),
            ),
        );
        let dither_config = firmware::dither::DitherConfig::for_profile(&profile);
        let off = firmware::storage::DitherSetpoints {
            enabled: false,
            amplitude_arcsec: dither_config.default_setpoint_arcsec,
            noise_percent: 0.0,
        };
        let (dither, coast) = resources::dither_task(dither_config, Some(off), None);
        let (_serial, serial_isr) = usart::configure(device.USART1);
        (
            rtic_binding::Resources {
                readout: readout.task,
                dither,
                latch: readout.latch,
                output_latch: readout.output_latch,
                pickoff: readout.pickoff,
                coast,
                scheduler: firmware::board::turnaround::Scheduler::new(),
                serial_isr,
            },
            counter,
        )
    },
    idle: |counter, locks| {
        binding_cost::measure("rtic", &counter, &mut locks);
        semihosting::process::exit(0)
    },

    /// The binding's own code: an empty handler.
    #[task(binds = EXTI2, priority = 11)]
    fn empty(_: empty::Context) {}
}

#[cfg(not(target_os = "none"))]
fn main() {
    println!(
        "rtic_cost: an MCU example (cargo fw-icount --features rtic-study --example rtic_cost)"
    );
}
