//! Proves the stack-overflow guard (flip-link, `.cargo/config.toml`): the stack sits at the
//! bottom of RAM, below `.data`/`.bss`, so a recursion without end runs off the start of RAM
//! and faults instead of overwriting statics. The run checks that a static placed right above
//! the stack (4 KiB) is intact up to the fault: with feature `qemu` the fault ends QEMU (the HardFault
//! handler exits with status 2, or the core locks up and `timeout` ends the run: either way
//! not status 0), and the canary word was never overwritten (checked at every level of the
//! recursion, so an overwrite would exit with status 3 first).
//! `cargo fw-run --example stack_overflow; echo $?` (QEMU 7.2 reports `Lockup: can't escalate
//! 3 to HardFault` and aborts: the fault's own exception entry cannot stack below RAM; on a
//! board the locked-up core is reset by the watchdog). `.ci/run` requires a fault, not 0 or 3.
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
mod app {
    use core::sync::atomic::{AtomicU32, Ordering};
    use firmware::rt::MemoryMap;

    const CANARY: u32 = 0xC0DE_CAFE;
    /// 4 KiB of statics in `.data`: without flip-link the stack grows down into them before it
    /// leaves RAM; with flip-link they lie above the stack, out of its way.
    static GUARD: [AtomicU32; 1024] = [const { AtomicU32::new(CANARY) }; 1024];

    #[inline(never)]
    fn recurse(depth: u32) -> u32 {
        let frame = [depth; 32];
        if GUARD.iter().any(|g| g.load(Ordering::Relaxed) != CANARY) {
            defmt::error!("static overwritten by the stack at depth {=u32}", depth);
            semihosting::process::exit(3);
        }
        if depth.is_multiple_of(256) {
            defmt::info!(
                "depth {=u32}, sp {=u32:#010x}",
                depth,
                cortex_m::register::msp::read()
            );
        }
        core::hint::black_box(&frame);
        recurse(depth + 1).wrapping_add(core::hint::black_box(frame[3]))
    }

    #[cortex_m_rt::entry]
    fn main() -> ! {
        let map = MemoryMap::linked();
        map.log();
        defmt::info!("recursing until the stack overflows: expect a fault, not status 0 or 3");
        let n = recurse(1);
        defmt::error!("recursion returned {=u32}", n);
        semihosting::process::exit(0)
    }
}

#[cfg(not(target_os = "none"))]
fn main() {
    println!("stack_overflow: an MCU example (`cargo fw-run --example stack_overflow`)");
}
