//! Firmware entry point.
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
mod app {
    use firmware::rt::pac as _;

    #[cortex_m_rt::entry]
    fn main() -> ! {
        defmt::info!("rlg-readout firmware {} booting", env!("CARGO_PKG_VERSION"));
        semihosting::process::exit(0)
    }
}

#[cfg(not(target_os = "none"))]
fn main() {
    println!("firmware: build for thumbv7em-none-eabihf (`cargo fw`) to get the MCU image");
}
