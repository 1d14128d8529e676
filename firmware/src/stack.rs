//! Painted-stack measurement (MCU only): how deep the stack went.
//!
//! [`paint`] fills the free stack, from its lowest address (`_stack_end`: with flip-link the
//! start of RAM) up to a margin below the current stack pointer, with a pattern;
//! [`deepest`] later finds the lowest word that no longer holds it. The difference to the
//! stack pointer at painting time is the depth everything since then used, interrupts included
//! (they run on the same main stack). [`depth_of`] measures one call from thread mode.
//!
//! Used by `examples/board_cost.rs`, `examples/dither_cost.rs` and `examples/serial_protocol.rs`
//! (the serial protocol run in QEMU); docs/firmware.md "Stack" quotes the figures. A
//! measurement, not a proof: it covers the paths the run took (the static bound would need
//! cargo-call-stack, which needs nightly).

const PAINT: u32 = 0x5AC3_A53C;
/// Words left untouched just below the stack pointer (the painting function's own frame).
const MARGIN_WORDS: usize = 16;

extern "C" {
    static _stack_end: u32;
}

fn bottom() -> *mut u32 {
    // Only the address of the linker symbol is taken.
    core::ptr::addr_of!(_stack_end) as *mut u32
}

/// Paints the free stack below the current stack pointer; returns that stack pointer.
#[inline(never)]
pub fn paint() -> u32 {
    let sp = cortex_m::register::msp::read();
    let top = (sp as usize / 4 - MARGIN_WORDS) * 4;
    let mut p = bottom();
    while (p as usize) < top {
        // SAFETY: between the stack's lowest address and below the live frames: free stack.
        unsafe {
            p.write_volatile(PAINT);
            p = p.add(1);
        }
    }
    sp
}

/// The lowest address written since [`paint`] (the deepest point of the stack).
pub fn deepest() -> u32 {
    let mut p = bottom();
    // SAFETY: reads of the stack region painted before.
    while unsafe { p.read_volatile() } == PAINT {
        p = unsafe { p.add(1) };
    }
    p as u32
}

/// Bytes of stack `f` used below the caller's stack pointer (its frames and any interrupt
/// taken meanwhile).
pub fn depth_of(f: impl FnOnce()) -> u32 {
    let sp = paint();
    f();
    sp.saturating_sub(deepest())
}
