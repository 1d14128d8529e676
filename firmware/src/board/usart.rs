//! The serial link: USART1 on PA9 (TX) / PA10 (RX), AF7, 460 800 Bd 8N1, interrupt-driven both
//! ways through bounded lock-free queues (heapless SPSC). Nothing blocks, in the handler or out.
//!
//! # Receive
//! `RXNEIE`: every received byte raises the USART1 interrupt (priority 2, below the turnaround
//! handlers only), which moves it from `DR` into the RX queue ([`RX_QUEUE_BYTES`]); the main loop
//! consumes it. The F405's USART has no FIFO: a byte must be read within one character time
//! (21.7 us at 460 800 Bd) or the next overwrites nothing and is lost with `ORE` set. The
//! handler's worst-case latency is the two turnaround handlers (< 2 us), and it runs from RAM
//! (`super::ram`), so a flash store does not stall it either: an overrun means a fault. `ORE` (and
//! `FE`/`NF`) are counted; `ORE` is cleared by the SR-then-DR read the handler does anyway. A
//! full RX queue drops the byte and counts it; the line assembler then reports the damaged line
//! (`ERR 7`/`ERR 8`/checksum), so the host sees an answer for every line it sent.
//!
//! # Transmit
//! The main loop writes answers and stream frames into the TX queue ([`TX_QUEUE_BYTES`], room for
//! three longest answers) and calls [`SerialPort::kick`], which enables `TXEIE` and pends the
//! interrupt. The handler moves bytes while `TXE` is set (on the board: about two per entry),
//! and clears `TXEIE` when the queue is empty. Pending it by software makes the same code work
//! in QEMU 7.2, whose USART model never raises a TXE interrupt (its TX is instantaneous and TXE
//! is always set: the handler then drains up to [`TX_BURST`] bytes per entry and pends itself
//! again). A full TX queue makes [`SerialPort::write`] return short: the caller decides (stream
//! frames are dropped whole, answers are written only when they fit).
//!
//! # Baud rate
//! `BRR = 84 MHz / 460 800 = 182` (OVER8 = 0): 461 538 Bd, +0.16 %. 460 800 Bd carries the
//! 47-byte stream frame of every dither cycle at 389 Hz (18.3 kB/s of 46 kB/s); at 1 kHz use
//! `stream on 2`. A terminal at 115 200 Bd needs [`BAUD`] changed (BRR = 729).

use core::sync::atomic::{AtomicU32, Ordering};

use heapless::spsc::{Consumer, Producer, Queue};

use super::{pac, Owned};
use pac::Interrupt;

/// Line rate: the protocol's (the host tool's default too).
pub const BAUD: u32 = crate::protocol::SERIAL_BAUD;
/// Receive queue, bytes (N - 1 usable): several command lines.
pub const RX_QUEUE_BYTES: usize = 512;
/// Transmit queue, bytes (N - 1 usable).
pub const TX_QUEUE_BYTES: usize = 1024;
/// Bytes moved per handler entry at most (bounds the handler where TXE never clears: QEMU).
const TX_BURST: usize = 32;

// USART_SR
const SR_FE: u16 = 1 << 1;
const SR_NF: u16 = 1 << 2;
const SR_ORE: u16 = 1 << 3;
const SR_RXNE: u16 = 1 << 5;
const SR_TXE: u16 = 1 << 7;
// USART_CR1
const CR1_RE: u16 = 1 << 2;
const CR1_TE: u16 = 1 << 3;
const CR1_RXNEIE: u16 = 1 << 5;
const CR1_TXEIE: u16 = 1 << 7;
const CR1_UE: u16 = 1 << 13;

/// Receive overruns (`ORE`: a byte lost in hardware).
pub static OVERRUNS: AtomicU32 = AtomicU32::new(0);
/// Framing or noise errors.
pub static LINE_ERRORS: AtomicU32 = AtomicU32::new(0);
/// Bytes dropped because the RX queue was full.
pub static RX_DROPPED: AtomicU32 = AtomicU32::new(0);

/// The handler's ends of the queues.
pub struct IsrSide {
    rx: Producer<'static, u8>,
    tx: Consumer<'static, u8>,
}

static ISR_SIDE: Owned<IsrSide> = Owned::new();

/// The main loop's side of the link.
pub struct SerialPort {
    rx: Consumer<'static, u8>,
    tx: Producer<'static, u8>,
}

fn regs() -> &'static pac::usart1::RegisterBlock {
    // SAFETY: USART1 is configured once in `init`; afterwards the handler owns SR/DR and both
    // sides change CR1 only in critical sections (`kick`) or from the handler itself.
    unsafe { &*pac::USART1::ptr() }
}

/// Configures USART1 and its pins (clocks for USART1 and GPIOA must be on) and returns the main
/// loop's side; the handler's side goes to its static. Call once; the caller unmasks `USART1`
/// in the NVIC afterwards.
pub fn init(usart: pac::USART1) -> SerialPort {
    let (port, side) = configure(usart);
    install(side);
    port
}

/// Puts the handler's side into the static [`on_interrupt`] serves (once, before `USART1` is
/// unmasked).
pub fn install(side: IsrSide) {
    ISR_SIDE.init(side);
}

/// [`init`], handing both sides back (the handler's to the caller's binding: an RTIC local).
#[allow(clippy::unwrap_used)] // at reset, once: the peripherals and the static queues are taken for the first time
pub fn configure(usart: pac::USART1) -> (SerialPort, IsrSide) {
    super::Port::A.alternate(9, 7);
    super::Port::A.alternate_pull_up(10, 7);
    let rx = cortex_m::singleton!(: Queue<u8, RX_QUEUE_BYTES> = Queue::new()).unwrap();
    let tx = cortex_m::singleton!(: Queue<u8, TX_QUEUE_BYTES> = Queue::new()).unwrap();
    let (rx_producer, rx_consumer) = rx.split();
    let (tx_producer, tx_consumer) = tx.split();
    let side = IsrSide {
        rx: rx_producer,
        tx: tx_consumer,
    };
    usart.cr1().write(|w| unsafe { w.bits(0) });
    usart
        .brr()
        .write(|w| unsafe { w.bits(((super::PCLK2_HZ + BAUD / 2) / BAUD) as u16) });
    usart.cr2().write(|w| unsafe { w.bits(0) });
    usart.cr3().write(|w| unsafe { w.bits(0) });
    usart
        .cr1()
        .write(|w| unsafe { w.bits(CR1_UE | CR1_TE | CR1_RE | CR1_RXNEIE) });
    (
        SerialPort {
            rx: rx_consumer,
            tx: tx_producer,
        },
        side,
    )
}

/// The USART1 handler on the board's static ([`transfer`] with it). Runs from RAM
/// (`super::ram`): inlined there whole.
#[inline(always)]
pub fn on_interrupt() {
    // SAFETY: only this handler uses the ISR side (set in `init` before the IRQ was unmasked).
    if let Some(side) = unsafe { ISR_SIDE.get() } {
        transfer(side);
    }
}

/// The USART1 handler's work: received bytes into the RX queue, queued bytes out.
#[inline(always)]
pub fn transfer(side: &mut IsrSide) {
    let usart = regs();
    loop {
        let sr = usart.sr().read().bits();
        if sr & (SR_RXNE | SR_ORE) == 0 {
            break;
        }
        // Reading DR after SR clears RXNE, ORE, FE and NF.
        let byte = usart.dr().read().bits() as u8;
        if sr & SR_ORE != 0 {
            OVERRUNS.fetch_add(1, Ordering::Relaxed);
        }
        if sr & (SR_FE | SR_NF) != 0 {
            LINE_ERRORS.fetch_add(1, Ordering::Relaxed);
        }
        if sr & SR_RXNE != 0 && side.rx.enqueue(byte).is_err() {
            RX_DROPPED.fetch_add(1, Ordering::Relaxed);
        }
    }
    let mut sent = 0;
    while sent < TX_BURST && usart.sr().read().bits() & SR_TXE != 0 {
        let Some(byte) = side.tx.dequeue() else {
            break;
        };
        usart.dr().write(|w| unsafe { w.bits(byte as u16) });
        sent += 1;
    }
    if !side.tx.ready() {
        usart
            .cr1()
            .modify(|r, w| unsafe { w.bits(r.bits() & !CR1_TXEIE) });
    } else if sent == TX_BURST {
        // TXE stayed set for a whole burst (QEMU): come back for the rest.
        cortex_m::peripheral::NVIC::pend(Interrupt::USART1);
    }
}

impl SerialPort {
    /// The next received byte, if any.
    pub fn read_byte(&mut self) -> Option<u8> {
        self.rx.dequeue()
    }

    /// Free room in the TX queue, bytes.
    pub fn tx_room(&self) -> usize {
        self.tx.capacity() - self.tx.len()
    }

    /// Queues as many of `bytes` as fit and returns how many; call [`SerialPort::kick`] after.
    pub fn write(&mut self, bytes: &[u8]) -> usize {
        bytes
            .iter()
            .take_while(|&&b| self.tx.enqueue(b).is_ok())
            .count()
    }

    /// Starts the transmitter on what is queued.
    pub fn kick(&mut self) {
        // CR1 is also changed by the handler: read-modify-write with interrupts off (3 instr.).
        cortex_m::interrupt::free(|_| {
            regs()
                .cr1()
                .modify(|r, w| unsafe { w.bits(r.bits() | CR1_TXEIE) })
        });
        cortex_m::peripheral::NVIC::pend(Interrupt::USART1);
    }

    /// Whether everything queued has been handed to the USART.
    pub fn tx_idle(&self) -> bool {
        self.tx.is_empty()
    }
}
