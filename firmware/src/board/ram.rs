//! What runs from RAM, so that a flash store does not stop the dither drive.
//!
//! # The stall
//! The F405's flash has a single bank, and "any attempt to read the Flash memory while it is
//! being written or erased causes the bus to stall" (RM0090 3.5): while a word is programmed
//! (16 us typical, 100 us at most) or a sector erased (1 s typical, 2 s at most), every
//! instruction fetch, constant and vector read from flash waits. Code in SRAM does not (it is
//! fetched over the system bus), nor does DMA, nor does any peripheral: the timers count, the
//! ADCs convert, the DAC takes its holding register at every trigger.
//!
//! # What runs from RAM
//! | what | why |
//! |---|---|
//! | the vector table ([`install_vectors`], VTOR) | every exception entry reads its vector |
//! | `TIM4`: the drive tick's register part, the pick-off stream, the coasting tick (`crate::dither::Coast`) | the dither stays driven with the drive its loops had set |
//! | `cossin` with its table (`crate::math::cossin`) | the coasting tick's DAC code |
//! | `SysTick` | the millisecond clock keeps time |
//! | `USART1` | received bytes are queued (512 bytes), not lost in an overrun |
//! | the flash operation itself ([`start_and_wait`], [`program_and_wait`]) | the main loop waits for `BSY` in RAM, where the handlers above can preempt it |
//!
//! Everything else (the turnaround latch, the pick-off and sync handler, the Lissajous DMA
//! handler, the readout task, the dither controller, the main loop) stays in flash and is
//! masked in the NVIC for each operation ([`with_flash_handlers_masked`]): a handler entered
//! during the operation would stall the core on its first fetch, and every handler with it.
//! For a word (16 us) they are only delayed: the latch's hardware holds its conversions and
//! count until the next compare (a half dither period away), an edge stays captured, the
//! Lissajous DMA runs on; an output latch whose compare a delayed handler arms fires that much
//! later, and its record's time says so. For an erase the readout pauses
//! (`resources::pause_readout`) and is re-synchronised after it.
//!
//! While an operation is under way ([`FLASH_BUSY`]) the drive tick coasts: it writes the next
//! code of the drive in force without calling the controller (whose code is in flash) and
//! queues the pick-off as usual; the controller is handed the ticks it missed at its next tick
//! ([`crate::dither::DitherController::coast`]).
//!
//! # Placement
//! Functions go to `.data.ramfunc.*`: cortex-m-rt's linker script puts `.data.*` in RAM with
//! its initial image in flash and its start-up copies it (SRAM is executable: no MPU region
//! forbids it). Calls between flash and RAM are out of a `BL`'s range; the linker inserts
//! long-branch thunks. Every call the RAM-resident code makes must itself be in RAM, or be
//! reached only while the flash is idle: `.ci/ram_code.py` disassembles the image and fails
//! on any other branch or address constant into flash (it names the exceptions: the
//! controller's tick, `board::dither::controller_tick`, and the panic path, which never
//! returns). It also prints the bytes; docs/board.md gives them.

use core::sync::atomic::{compiler_fence, AtomicBool, Ordering};

use cortex_m::peripheral::{NVIC, SCB};

use super::pac::Interrupt;

/// A flash operation is under way: the drive tick coasts.
pub static FLASH_BUSY: AtomicBool = AtomicBool::new(false);

/// Exceptions and interrupts of the F405: 16 system entries and 82 IRQs.
const VECTORS: usize = 16 + 82;
/// SysTick's entry.
const SYSTICK_VECTOR: usize = 15;

/// The vector table in RAM: VTOR needs it aligned to its size rounded up to a power of two
/// (128 entries, 512 bytes; Cortex-M4 generic user guide, 4.3.4).
#[repr(C, align(512))]
struct Vectors([usize; VECTORS]);

/// Written once by [`install_vectors`], before any interrupt is enabled; read by the core.
#[link_section = ".uninit.ram_vectors"]
static mut RAM_VECTORS: core::mem::MaybeUninit<Vectors> = core::mem::MaybeUninit::uninit();

/// The IRQs whose handlers are in RAM: left enabled during a flash operation.
const RAM_IRQS: [Interrupt; 2] = [Interrupt::TIM4, Interrupt::USART1];

/// Copies the vector table to RAM with the RAM-resident handlers in it and points VTOR at it.
/// Call once at start-up, before any interrupt (SysTick included) is enabled.
pub fn install_vectors(scb: &mut SCB) {
    relocate_vectors(
        scb,
        &[
            (SYSTICK_VECTOR, systick as extern "C" fn() as usize),
            (
                16 + Interrupt::TIM4 as usize,
                tim4 as extern "C" fn() as usize,
            ),
            (
                16 + Interrupt::USART1 as usize,
                usart1 as extern "C" fn() as usize,
            ),
        ],
    );
}

/// Copies the linked vector table to RAM, writes each `(entry, handler address)` of
/// `handlers` over it and points VTOR at it. A binary whose RAM-resident handlers are the
/// linked ones (RTIC's tasks given a `.data.ramfunc` section: `examples/rtic_board.rs`)
/// passes none. Call once at start-up, before any interrupt (SysTick included) is enabled.
pub fn relocate_vectors(scb: &mut SCB, handlers: &[(usize, usize)]) {
    let table = core::ptr::addr_of_mut!(RAM_VECTORS).cast::<usize>();
    // SAFETY: VTOR points at the linked table (flash) at reset, VECTORS entries long; the RAM
    // table is written here only, before any interrupt can read it; entries are below VECTORS.
    unsafe {
        let flash = scb.vtor.read() as *const usize;
        for i in 0..VECTORS {
            table.add(i).write(flash.add(i).read());
        }
        for &(entry, handler) in handlers {
            if entry < VECTORS {
                table.add(entry).write(handler);
            }
        }
        cortex_m::asm::dsb();
        scb.vtor.write(table as u32);
        cortex_m::asm::dsb();
        cortex_m::asm::isb();
    }
}

/// `TIM4`: the drive tick (`super::isr::tim4`).
#[link_section = ".data.ramfunc.tim4"]
#[inline(never)]
extern "C" fn tim4() {
    super::isr::tim4();
}

/// `USART1` (`super::isr::usart1`).
#[link_section = ".data.ramfunc.usart1"]
#[inline(never)]
extern "C" fn usart1() {
    super::isr::usart1();
}

/// `SysTick` (`super::isr::systick`).
#[link_section = ".data.ramfunc.systick"]
#[inline(never)]
extern "C" fn systick() {
    super::isr::systick();
}

/// Runs `op` (a flash operation through [`start_and_wait`] or [`program_and_wait`]) with every
/// enabled interrupt whose handler is in flash masked, and unmasks them after: what became
/// pending meanwhile runs then. From the main loop only.
pub fn with_flash_handlers_masked<R>(op: impl FnOnce() -> R) -> R {
    // SAFETY: the NVIC's enable registers are changed by the main loop only after start-up;
    // the set-enable write below restores exactly what was enabled before.
    let nvic = unsafe { &*NVIC::PTR };
    let mut ram = [0u32; 3];
    for irq in RAM_IRQS {
        let n = irq as usize;
        if let Some(word) = ram.get_mut(n / 32) {
            *word |= 1 << (n % 32);
        }
    }
    let mut masked = [0u32; 3];
    for (((m, ram_word), iser), icer) in masked
        .iter_mut()
        .zip(ram.iter())
        .zip(nvic.iser.iter())
        .zip(nvic.icer.iter())
    {
        *m = iser.read() & !ram_word;
        // SAFETY: clearing enables only masks.
        unsafe { icer.write(*m) };
    }
    cortex_m::asm::dsb();
    cortex_m::asm::isb();
    let result = op();
    for (m, iser) in masked.iter().zip(nvic.iser.iter()) {
        // SAFETY: the same lines that were enabled before.
        unsafe { iser.write(*m) };
    }
    result
}

/// FLASH_SR and FLASH_CR (RM0090 3.9).
const FLASH_SR: *mut u32 = 0x4002_3C0C as *mut u32;
const FLASH_CR: *mut u32 = 0x4002_3C10 as *mut u32;
const SR_BSY: u32 = 1 << 16;
const CR_STRT: u32 = 1 << 16;

/// Writes `cr`, then `cr | STRT` (a sector erase), and waits in RAM until the flash is no
/// longer busy; returns `FLASH_SR` then. The flash must be unlocked.
#[link_section = ".data.ramfunc.flash_op"]
#[inline(never)]
pub fn start_and_wait(cr: u32) -> u32 {
    FLASH_BUSY.store(true, Ordering::Relaxed);
    compiler_fence(Ordering::SeqCst);
    // SAFETY: FLASH_CR/SR are the flash interface's registers; the caller unlocked it.
    unsafe {
        FLASH_CR.write_volatile(cr);
        FLASH_CR.write_volatile(cr | CR_STRT);
    }
    wait()
}

/// Writes `cr` (with `PG`), then `value` to `address` (32 bits, or its low byte when `byte`),
/// and waits in RAM until the flash is no longer busy; returns `FLASH_SR` then. The flash
/// must be unlocked and `address` aligned and programmable.
#[link_section = ".data.ramfunc.flash_op"]
#[inline(never)]
pub fn program_and_wait(cr: u32, address: u32, value: u32, byte: bool) -> u32 {
    FLASH_BUSY.store(true, Ordering::Relaxed);
    compiler_fence(Ordering::SeqCst);
    // SAFETY: as in `start_and_wait`; the address is checked by the caller.
    unsafe {
        FLASH_CR.write_volatile(cr);
        if byte {
            (address as *mut u8).write_volatile(value as u8);
        } else {
            (address as *mut u32).write_volatile(value);
        }
    }
    wait()
}

/// Waits while `BSY` (the registers are not flash: reading them does not stall), then clears
/// [`FLASH_BUSY`].
#[inline(always)]
fn wait() -> u32 {
    cortex_m::asm::dsb();
    // SAFETY: FLASH_SR is read-only here.
    let mut sr = unsafe { FLASH_SR.read_volatile() };
    while sr & SR_BSY != 0 {
        // SAFETY: as above.
        sr = unsafe { FLASH_SR.read_volatile() };
    }
    compiler_fence(Ordering::SeqCst);
    FLASH_BUSY.store(false, Ordering::Relaxed);
    sr
}
