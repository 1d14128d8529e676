//! Proves the fatal-error path: executes a permanently undefined instruction (`UDF`), which
//! escalates to HardFault on every Cortex-M4. With feature `qemu` the handler logs the PC and
//! exits with status 2: `cargo fw-run --example hardfault; echo $?` prints 2. With `hw` the board
//! resets instead (see `firmware::rt`).
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
mod app {
    use firmware::rt::MemoryMap;

    #[cortex_m_rt::entry]
    fn main() -> ! {
        let _ = MemoryMap::linked(); // links the firmware's runtime (vector table, handlers)
        defmt::info!("about to execute UDF: expect a HardFault");
        cortex_m::asm::udf()
    }
}

#[cfg(not(target_os = "none"))]
fn main() {
    println!("hardfault: an MCU example (`cargo fw-run --example hardfault`)");
}
