//! Firmware entry point: start-up banner, then (for now) the end of the program.
//!
//! Under QEMU (feature `qemu`) the image logs its start-up and exits with status 0 through
//! semihosting, so `cargo fw-run` ends. On a board (feature `hw`) it logs over RTT and idles;
//! the readout loop will live here.
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
mod app {
    use firmware::rt::MemoryMap;

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
        defmt::info!("start-up done: idle");
        loop {
            cortex_m::asm::wfi();
        }
    }
}

#[cfg(not(target_os = "none"))]
fn main() {
    println!("firmware: build for thumbv7em-none-eabihf (`cargo fw`) to get the MCU image");
}
