//! The complete board firmware as an RTIC 2 app: the study that docs/firmware.md#concurrency
//! decides on, not the product (`board::app::run` is; this example needs the feature
//! `rtic-study`).
//!
//! ```text
//! cargo build -p firmware --target thumbv7em-none-eabihf --release --features hw,rtic-study --example rtic_board
//! python3 .ci/ram_code.py --rtic target/thumbv7em-none-eabihf/release/examples/rtic_board
//! cargo build -p firmware --target thumbv7em-none-eabihf --release --features qemu,rtic-study --example rtic_board
//! python3 .ci/qemu_serial.py --board target/thumbv7em-none-eabihf/release/examples/rtic_board
//! ```
//!
//! Faithful to the board: the same hardware tasks at the same priorities on the same vectors
//! (checked against `board::resources::priority` at start-up: `rtic_binding`), the same start-up
//! (`board::app::bring_up`), the same handler bodies (`board::isr`), drivers, main loop
//! (`board::app::serve`) and command service. What differs is only the binding:
//!
//! - the three values the contexts share are RTIC `#[shared]` resources (the readout task's
//!   state, the dither controller, the latch's compare plan), their ceilings computed by RTIC
//!   from the `shared = [...]` lists, their locks RTIC's (BASEPRI, or a critical section for
//!   the plan, whose ceiling is the top priority), handed to the bodies through
//!   `rtic_binding::Rtic`;
//! - what one context owns (queue ends, the coast state, the pick-off prediction, the USART's
//!   queue ends, the main loop's parts) is RTIC `#[local]`, not `board::Owned` statics;
//! - RTIC sets the priorities and unmasks every bound interrupt when `init` returns.
//!
//! The flash stall: the drive tick, USART1 and SysTick must run from RAM during a flash
//! operation (`board::ram`). RTIC's `#[task]` puts the task's attributes on both functions it
//! generates (the `#[no_mangle]` vector symbol and the task body), so a `#[link_section =
//! ".data.ramfunc.*"]` on the task links both into RAM; the linked vector table then points at
//! them, and `init` copies that table to RAM unchanged (`board::ram::relocate_vectors`, VTOR).
//! `.ci/ram_code.py --rtic` checks the result as it checks the board's.
//!
//! What stays outside RTIC: the NMI (RTIC binds only exceptions of configurable priority; its
//! handler touches an atomic flag and RCC_CIR, as on the board), and the NVIC masking around a
//! flash operation and a store's pause (`board::ram::with_flash_handlers_masked`,
//! `board::resources::pause_readout`), which RTIC does not model and does not forbid.
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
#[macro_use]
mod rtic_binding;

#[cfg(target_os = "none")]
use firmware::board::app::{bring_up, serve};
#[cfg(target_os = "none")]
use firmware::board::{flash, ports, ram, resources, usart, watchdog};

/// What the main loop takes over from `init`.
#[cfg(target_os = "none")]
pub struct MainLoop {
    service: firmware::service::Service<flash::InternalFlash>,
    queues: resources::ReadoutQueues,
    serial: usart::SerialPort,
    watchdog: watchdog::Watchdog,
    selftest: firmware::board_timing::selftest::SelfTestReport,
    sensor: firmware::board::app::BlockSensor,
}

#[cfg(target_os = "none")]
board_app! {
    parts: MainLoop,
    init: |core, device| {
        defmt::info!("rlg-readout board firmware {} (RTIC)", env!("CARGO_PKG_VERSION"));
        let board = bring_up(&mut core, device, |cp| {
            // RTIC has set the priorities; the RAM-resident tasks are linked into RAM, so the
            // table is copied as it is.
            ram::relocate_vectors(&mut cp.SCB, &[]);
            resources::start_tick(&mut cp.SYST);
        });
        let (dither, coast) = board.dither;
        (
            rtic_binding::Resources {
                readout: board.readout.task,
                dither,
                latch: board.readout.latch,
                output_latch: board.readout.output_latch,
                pickoff: board.readout.pickoff,
                coast,
                scheduler: board.scheduler,
                serial_isr: board.serial_isr,
            },
            MainLoop {
                service: board.service,
                queues: board.readout.queues,
                serial: board.serial,
                watchdog: board.watchdog,
                selftest: board.selftest,
                sensor: board.sensor,
            },
        )
    },
    idle: |m, locks| {
        // `board::app::serve` on RTIC's resource proxies.
        let ports = ports::BoardPorts::with_locks(m.serial, Some(m.watchdog), true, m.selftest, locks);
        serve(
            m.service,
            m.queues,
            ports,
            Some(m.sensor),
            Some("# rlg-readout ready"),
        )
    },
}

#[cfg(not(target_os = "none"))]
fn main() {
    println!("rtic_board: an MCU example (feature rtic-study; see docs/firmware.md#concurrency)");
}
