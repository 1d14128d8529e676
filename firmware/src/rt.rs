//! MCU glue, compiled only for `target_os = "none"`: logger, memory map, panic and fault handlers.
//!
//! Two ways out of a fatal error, chosen by feature:
//!
//! * `qemu` (emulator, or a board under a debugger): log, then a semihosting exit with a status
//!   (panic 1, HardFault 2), so QEMU ends and `cargo fw-run`/`fw-test` report the failure.
//! * `hw` (a board on its own): log over RTT, wait a moment so an attached probe can drain the
//!   buffer, then reset the MCU. Semihosting is a `BKPT`, which on a board without a debugger
//!   escalates to a lockup: the instrument would stay dead until power-cycled. After the reset
//!   the pins return to their reset state (dither drive off) and the firmware starts again.
//!   A fault that repeats at every boot therefore reset-loops; its message is in the RTT log.

use core::cell::Cell;
use cortex_m::interrupt::{self, Mutex}; // also the critical-section implementation
#[cfg(feature = "hw")]
use defmt_rtt as _;
#[cfg(feature = "qemu")]
use defmt_semihosting as _;
pub use stm32f4::stm32f405 as pac; // vector table

#[cfg(all(feature = "qemu", feature = "hw"))]
compile_error!("features `qemu` and `hw` choose the logger and the fatal-error path: enable one");
#[cfg(not(any(feature = "qemu", feature = "hw")))]
compile_error!(
    "the MCU build needs feature `qemu` (emulator) or `hw` (board): see the cargo aliases"
);

/// Where the linker put things, read from the symbols of `memory.x` and cortex-m-rt's `link.x`.
#[derive(Clone, Copy, Debug, defmt::Format)]
pub struct MemoryMap {
    /// Start of flash and of the code, 0x0800_0000.
    pub flash_start: u32,
    /// First byte after code, read-only data and the initial values of `.data`.
    pub flash_end: u32,
    /// Calibration store: the last two 128 KiB sectors (10 and 11), never used for code.
    pub calibration_start: u32,
    /// First byte after the calibration store.
    pub calibration_end: u32,
    /// Start of the statics (`.data`, then `.bss` and `.uninit`).
    pub static_start: u32,
    /// First byte after the statics.
    pub static_end: u32,
    /// Lowest address of the stack: with flip-link the start of SRAM, below the statics, so
    /// an overflow faults instead of overwriting them (docs/firmware.md "Stack").
    pub stack_bottom: u32,
    /// Initial stack pointer: the stack grows down from here to `stack_bottom`.
    pub stack_top: u32,
}

extern "C" {
    static __calibration_start: u8;
    static __calibration_end: u8;
    static __sidata: u8;
    static __sdata: u8;
    static __edata: u8;
    static _stack_start: u8;
    static _stack_end: u8;
    static __euninit: u8;
}

/// The address of a linker symbol (its value; the symbol is never read, so no `unsafe`).
macro_rules! addr {
    ($sym:ident) => {
        core::ptr::addr_of!($sym) as u32
    };
}

impl MemoryMap {
    /// Flash sector size of sectors 5 to 11.
    pub const SECTOR_BYTES: u32 = 128 * 1024;

    /// The map of this image, from the linker symbols.
    pub fn linked() -> Self {
        Self {
            flash_start: 0x0800_0000,
            flash_end: addr!(__sidata) + (addr!(__edata) - addr!(__sdata)),
            calibration_start: addr!(__calibration_start),
            calibration_end: addr!(__calibration_end),
            static_start: addr!(__sdata),
            static_end: addr!(__euninit),
            stack_bottom: addr!(_stack_end),
            stack_top: addr!(_stack_start),
        }
    }

    /// Logs the map at info level (start-up banner).
    pub fn log(&self) {
        defmt::info!(
            "flash  {=u32:#010x}..{=u32:#010x}: {=u32} bytes of code and constants",
            self.flash_start,
            self.flash_end,
            self.flash_end - self.flash_start
        );
        defmt::info!(
            "calib  {=u32:#010x} (sector 10), {=u32:#010x} (sector 11), end {=u32:#010x}",
            self.calibration_start,
            self.calibration_start + Self::SECTOR_BYTES,
            self.calibration_end
        );
        defmt::info!(
            "ram    {=u32:#010x}..{=u32:#010x}: {=u32} bytes static; stack {=u32:#010x}..{=u32:#010x} ({=u32} bytes) below it",
            self.static_start,
            self.static_end,
            self.static_end.wrapping_sub(self.static_start),
            self.stack_bottom,
            self.stack_top,
            self.stack_top.wrapping_sub(self.stack_bottom)
        );
    }
}

/// Called once by the panic and HardFault handlers before they end the program, e.g. for a
/// test harness to close its report. Runs in the fault context: keep it to logging.
static FATAL_HOOK: Mutex<Cell<Option<FatalHook>>> = Mutex::new(Cell::new(None));
type FatalHook = fn();

/// Installs the hook the fatal-error handlers call before ending the program.
pub fn set_fatal_hook(hook: FatalHook) {
    interrupt::free(|cs| FATAL_HOOK.borrow(cs).set(Some(hook)));
}

/// Ends the program after a fatal error (see the module docs for what each feature does).
fn fatal(code: i32) -> ! {
    // Taken, not read: a panic inside the hook ends here without calling it again.
    if let Some(hook) = interrupt::free(|cs| FATAL_HOOK.borrow(cs).take()) {
        hook();
    }
    #[cfg(feature = "qemu")]
    {
        semihosting::process::exit(code)
    }
    #[cfg(not(feature = "qemu"))]
    {
        let _ = code;
        // ~12 ms at 168 MHz, ~125 ms at the 16 MHz reset clock: time for a probe to read RTT.
        cortex_m::asm::delay(2_000_000);
        cortex_m::peripheral::SCB::sys_reset()
    }
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    defmt::error!("{}", defmt::Display2Format(info));
    fatal(1)
}

#[defmt::panic_handler]
fn defmt_panic() -> ! {
    fatal(1) // defmt::panic!/assert!: the message is already logged
}

#[cortex_m_rt::exception]
unsafe fn HardFault(ef: &cortex_m_rt::ExceptionFrame) -> ! {
    defmt::error!("HardFault at pc={=u32:#x} lr={=u32:#x}", ef.pc(), ef.lr());
    fatal(2)
}
