//! MCU glue (only for `target_os = "none"`): logger, panic and fault handlers.
use cortex_m as _; // critical-section implementation
#[cfg(feature = "qemu")]
use defmt_semihosting as _;
#[cfg(feature = "hw")]
use defmt_rtt as _;
pub use stm32f4::stm32f405 as pac; // vector table

#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    defmt::error!("{}", defmt::Display2Format(info));
    semihosting::process::exit(1)
}

#[defmt::panic_handler]
fn defmt_panic() -> ! {
    semihosting::process::exit(1)
}

#[cortex_m_rt::exception]
unsafe fn HardFault(ef: &cortex_m_rt::ExceptionFrame) -> ! {
    defmt::error!("HardFault at pc={=u32:#x}", ef.pc());
    semihosting::process::exit(2)
}
