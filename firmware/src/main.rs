//! Firmware entry point: start-up banner and memory map, then the board.
//!
//! - On a board (feature `hw`, `cargo hw-run`): the readout runs for good,
//!   [`firmware::board::app::run`] brings up clocks, watchdog, serial link, the calibration from
//!   flash, the encoder and turnaround timers, the ADCs and the interrupts.
//! - Under QEMU (feature `qemu`, `cargo fw-run`): the image logs its start-up and exits with
//!   status 0 through semihosting, so the boot is checked in CI. QEMU does not model the
//!   timers, ADCs and DMA faithfully; the board's serial and protocol half runs in QEMU as
//!   `examples/serial_protocol.rs` and `examples/board.rs` (see `.ci/qemu_serial.py`).
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
mod app {
    use firmware::rt::MemoryMap;

    #[cfg(feature = "hw")]
    firmware::bind_board_interrupts!();

    #[cortex_m_rt::entry]
    fn main() -> ! {
        defmt::info!(
            "rlg-readout firmware {} ({} build, opt-level {}) on STM32F405",
            env!("CARGO_PKG_VERSION"),
            env!("FW_BUILD_PROFILE"),
            env!("FW_OPT_LEVEL"),
        );
        MemoryMap::linked().log();
        finish()
    }

    #[cfg(feature = "qemu")]
    fn finish() -> ! {
        defmt::info!("start-up done: exiting (qemu)");
        semihosting::process::exit(0)
    }

    #[cfg(not(feature = "qemu"))]
    fn finish() -> ! {
        firmware::board::app::run()
    }
}

#[cfg(not(target_os = "none"))]
fn main() {
    println!("firmware: build for thumbv7em-none-eabihf (`cargo fw`) to get the MCU image");
}
