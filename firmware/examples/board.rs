//! The complete board firmware (`board::app::run`): what `main.rs` will call once it hands over
//! to the board code. Flash it with `cargo hw-run --example board`.
//!
//! Under QEMU it starts but cannot do its job (TIM2/TIM5/ADC/DMA are not faithful there, see
//! TOOLCHAIN.md): `.ci/qemu_serial.py` exercises the serial and protocol half through the
//! `serial_protocol` example instead.
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
mod app {
    firmware::bind_board_interrupts!();

    #[cortex_m_rt::entry]
    fn main() -> ! {
        defmt::info!("rlg-readout board firmware {}", env!("CARGO_PKG_VERSION"));
        firmware::board::app::run()
    }
}

#[cfg(not(target_os = "none"))]
fn main() {
    println!("board: an MCU example (cargo hw-run --example board)");
}
