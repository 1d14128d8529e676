//! I2C1, master, 400 kHz (fast mode), for the gyro block's TMP117 (`crate::thermal`): the F405's
//! I2C peripheral behind `embedded_hal::i2c::I2c`, so the driver (`thermal::tmp117`) is the
//! one hal-sim's simulated sensor runs in `cargo test`.
//!
//! **Pins.** PB6 = I2C1_SCL, PB7 = I2C1_SDA (AF4, LQFP64 pins 58 and 59), open drain, 4.7 kOhm
//! pull-ups to 3.3 V on the board (the internal ~40 kOhm ones are too weak for 400 kHz).
//!
//! **Speed** (RM0090 27.6.8, 27.6.9): APB1 = 42 MHz, so `CR2.FREQ` = 42; fast mode with
//! `DUTY` = 0 has `T_high = CCR T_pclk1` and `T_low = 2 CCR T_pclk1`, so `CCR = 42 MHz /
//! (3 x 400 kHz)` = 35 (400 kHz exactly); `TRISE = 300 ns / 23.8 ns + 1` = 13.
//!
//! **Transfers** (RM0090 27.3.3, master transmitter and receiver): START, wait `SB`, the
//! address, wait `ADDR` (or `AF`: not acknowledged), clear `ADDR` by reading SR1 then SR2;
//! bytes out on `TXE`, the last one waited for with `BTF`; a read of two bytes uses the
//! `POS`/`ACK` procedure (`ACK` and `POS` set before `ADDR` is cleared, `ACK` cleared after,
//! `STOP` once `BTF` holds both bytes); one byte: `ACK` cleared and `STOP` set right after
//! `ADDR`. Every wait is bounded ([`WAIT_LOOPS`], about 1 ms at 168 MHz): a bus that never
//! answers (SDA or SCL held low, no I2C at all as under QEMU, whose netduinoplus2 does not
//! model the I2C peripheral) ends in `ErrorKind::Bus` instead of a hang; `AF` is
//! `NoAcknowledge`, `BERR` `Bus`, `ARLO` `ArbitrationLoss`. After any error the peripheral is
//! reset (`CR1.SWRST`) and set up again, so the next transfer starts clean.
//!
//! **Bus clear.** A slave that was sending when the MCU reset (or a transfer broke off) holds
//! SDA low and waits for clocks. Before the peripheral is first enabled, and after a `Bus` or
//! `ArbitrationLoss` error (on this one-master bus either means a line was low when the
//! controller released it), the controller is switched off (`PE` = 0), PB6/PB7 become GPIO
//! open-drain outputs (MODER = 01, OTYPER = 1, released through BSRR before the mode changes so
//! no line glitches low; levels read from IDR, RM0090 8.4) and `thermal::bus_recovery` runs at
//! 100 kHz: up to nine SCL pulses while SDA is low, then a START and a STOP; then the pins go
//! back to AF4 and the peripheral is reset and set up. The START/STOP toggles both lines also on
//! a free bus, which is the workaround of the erratum "I2C analog filter may provide wrong
//! value, locking BUSY flag and preventing master mode entry" (ES0182): the filter output
//! follows its line only after a transition, and `SWRST` alone does not clear `BUSY` then. The
//! sequence is bounded (`thermal::bus_recovery`: 25 us on a free bus, 115 us after nine
//! pulses, 105 us with SCL held low, as under QEMU, whose GPIO inputs read 0; about 1 ms more
//! with a slave stretching every clock to the bound) and runs only where the transfers do, in
//! the main loop. The outcome is logged at start-up (`I2C1 bus clear: ...` when the bus was
//! not free); after an error the transfer's own error is what the driver reports. The TMP117
//! also frees SDA by itself after its 30 ms bus time-out.
//!
//! **Where it runs.** Only in the main loop (`board::app`), never in the readout's interrupts:
//! a poll is ~95 us (one register) or ~190 us (two), preempted by every interrupt; the
//! controller stretches SCL while it waits, which the part accepts, so the interrupts see no
//! added latency (the main loop's own work per pass grows by at most 190 us every 50 ms).

use core::convert::Infallible;

use embedded_hal::delay::DelayNs;
use embedded_hal::digital::{self, InputPin, OutputPin};
use embedded_hal::i2c::{ErrorKind, ErrorType, NoAcknowledgeSource, Operation, SevenBitAddress};

use super::{pac, Port};
use crate::thermal::bus_recovery::{self, Recovery, RecoveryTiming};

/// RCC APB1ENR bit of I2C1 (RM0090 7.3.13).
const APB1_I2C1: u32 = 1 << 21;
/// APB1 clock, MHz (`CR2.FREQ`).
const PCLK1_MHZ: u16 = 42;
/// Fast mode, DUTY = 0: 42 MHz / (3 x 35) = 400 kHz.
const CCR_400KHZ: u16 = 35;
/// Fast-mode rise time: 300 ns at 42 MHz, + 1.
const TRISE_FAST: u16 = 13;
/// I2C1's lines on port B and their alternate function.
const SCL_PIN: u32 = 6;
const SDA_PIN: u32 = 7;
const AF_I2C1: u32 = 4;
// GPIO register offsets (RM0090 8.4).
const MODER: usize = 0x00;
const OTYPER: usize = 0x04;
const IDR: usize = 0x10;
const BSRR: usize = 0x18;
/// Upper bound of one wait's polls (about 1 ms at 168 MHz; a byte at 400 kHz is 22.5 us).
pub const WAIT_LOOPS: u32 = 20_000;

// SR1 bits (RM0090 27.6.6).
const SB: u16 = 1 << 0;
const ADDR: u16 = 1 << 1;
const BTF: u16 = 1 << 2;
const RXNE: u16 = 1 << 6;
const TXE: u16 = 1 << 7;
const BERR: u16 = 1 << 8;
const ARLO: u16 = 1 << 9;
const AF: u16 = 1 << 10;
// CR1 bits (RM0090 27.6.1).
const PE: u16 = 1 << 0;
const START: u16 = 1 << 8;
const STOP: u16 = 1 << 9;
const ACK: u16 = 1 << 10;
const POS: u16 = 1 << 11;
const SWRST: u16 = 1 << 15;

/// An I2C error with its embedded-hal kind.
#[derive(Clone, Copy, Debug, PartialEq, Eq, defmt::Format)]
pub struct I2cError(#[defmt(Debug2Format)] pub ErrorKind);

impl embedded_hal::i2c::Error for I2cError {
    fn kind(&self) -> ErrorKind {
        self.0
    }
}

/// I2C1 as the TMP117's bus.
pub struct I2c1 {
    i2c: pac::I2C1,
}

impl I2c1 {
    /// Clocks I2C1, sets up PB6/PB7 (AF4, open drain) and the peripheral (400 kHz).
    pub fn init(i2c: pac::I2C1, rcc: &pac::RCC) -> Self {
        // SAFETY: read-modify-write of enable bits during start-up, one context.
        rcc.apb1enr()
            .modify(|r, w| unsafe { w.bits(r.bits() | APB1_I2C1) });
        match clear_bus() {
            Recovery::Free => defmt::debug!("I2C1 bus free"),
            outcome => defmt::warn!("I2C1 bus clear: {}", outcome),
        }
        let me = Self { i2c };
        me.configure();
        me
    }

    fn configure(&self) {
        let i2c = &self.i2c;
        // SAFETY: raw field values of RM0090 27.6 (see the module docs).
        unsafe {
            i2c.cr1().write(|w| w.bits(SWRST));
            i2c.cr1().write(|w| w.bits(0));
            i2c.cr2().write(|w| w.bits(PCLK1_MHZ));
            i2c.ccr().write(|w| w.bits((1 << 15) | CCR_400KHZ));
            i2c.trise().write(|w| w.bits(TRISE_FAST));
            i2c.cr1().write(|w| w.bits(PE));
        }
    }

    fn sr1(&self) -> u16 {
        self.i2c.sr1().read().bits()
    }

    fn cr1_set(&self, bits: u16) {
        // SAFETY: sets control bits of RM0090 27.6.1.
        self.i2c
            .cr1()
            .modify(|r, w| unsafe { w.bits(r.bits() | bits) });
    }

    fn cr1_clear(&self, bits: u16) {
        // SAFETY: clears control bits of RM0090 27.6.1.
        self.i2c
            .cr1()
            .modify(|r, w| unsafe { w.bits(r.bits() & !bits) });
    }

    /// Waits for any of `flags` in SR1; an error flag or the bound ends it with the error.
    fn wait(&self, flags: u16, nack: NoAcknowledgeSource) -> Result<u16, I2cError> {
        for _ in 0..WAIT_LOOPS {
            let sr1 = self.sr1();
            if sr1 & AF != 0 {
                return Err(I2cError(ErrorKind::NoAcknowledge(nack)));
            }
            if sr1 & ARLO != 0 {
                return Err(I2cError(ErrorKind::ArbitrationLoss));
            }
            if sr1 & BERR != 0 {
                return Err(I2cError(ErrorKind::Bus));
            }
            if sr1 & flags != 0 {
                return Ok(sr1);
            }
        }
        Err(I2cError(ErrorKind::Bus))
    }

    /// START and the address byte (`read`: R/W = 1); `ADDR` is left set for the caller.
    fn address(&self, address: SevenBitAddress, read: bool) -> Result<(), I2cError> {
        self.cr1_set(START);
        self.wait(SB, NoAcknowledgeSource::Unknown)?;
        let byte = (u16::from(address) << 1) | u16::from(read);
        // SAFETY: the address byte (RM0090 27.3.3).
        self.i2c.dr().write(|w| unsafe { w.bits(byte) });
        self.wait(ADDR, NoAcknowledgeSource::Address)?;
        Ok(())
    }

    fn clear_addr(&self) {
        let _ = self.sr1();
        let _ = self.i2c.sr2().read().bits();
    }

    fn write_bytes(&self, bytes: &[u8]) -> Result<(), I2cError> {
        for &b in bytes {
            self.wait(TXE, NoAcknowledgeSource::Data)?;
            // SAFETY: a data byte.
            self.i2c.dr().write(|w| unsafe { w.bits(u16::from(b)) });
        }
        self.wait(BTF, NoAcknowledgeSource::Data)?;
        Ok(())
    }

    fn read_byte(&self) -> u8 {
        (self.i2c.dr().read().bits() & 0xFF) as u8
    }

    /// Reads into `buf` (1 or 2 bytes: what the TMP117 needs; longer reads take one byte at a
    /// time with ACK, the last two by the two-byte procedure), then STOP.
    fn read_bytes(&self, address: SevenBitAddress, buf: &mut [u8]) -> Result<(), I2cError> {
        match buf.len() {
            0 => {
                self.cr1_set(STOP);
                Ok(())
            }
            1 => {
                self.cr1_clear(ACK | POS);
                self.address(address, true)?;
                self.clear_addr();
                self.cr1_set(STOP);
                self.wait(RXNE, NoAcknowledgeSource::Data)?;
                if let Some(b) = buf.first_mut() {
                    *b = self.read_byte();
                }
                Ok(())
            }
            n => {
                self.cr1_set(ACK);
                self.address(address, true)?;
                self.clear_addr();
                let (head, tail) = buf.split_at_mut(n - 2);
                for b in head {
                    self.wait(RXNE, NoAcknowledgeSource::Data)?;
                    *b = self.read_byte();
                }
                // The last two: NACK the last, STOP once both are in (DR and the shift register).
                self.wait(BTF, NoAcknowledgeSource::Data)?;
                self.cr1_clear(ACK);
                self.cr1_set(STOP);
                for b in tail {
                    *b = self.read_byte();
                    let _ = self.wait(RXNE, NoAcknowledgeSource::Data);
                }
                Ok(())
            }
        }
    }

    fn run(
        &mut self,
        address: SevenBitAddress,
        operations: &mut [Operation<'_>],
    ) -> Result<(), I2cError> {
        let last = operations.len().saturating_sub(1);
        for (i, op) in operations.iter_mut().enumerate() {
            match op {
                Operation::Write(bytes) => {
                    self.address(address, false)?;
                    self.clear_addr();
                    self.write_bytes(bytes)?;
                    if i == last {
                        self.cr1_set(STOP);
                    }
                }
                Operation::Read(buf) => self.read_bytes(address, buf)?,
            }
        }
        Ok(())
    }
}

impl ErrorType for I2c1 {
    type Error = I2cError;
}

impl embedded_hal::i2c::I2c<SevenBitAddress> for I2c1 {
    /// One transaction: each operation starts with a (repeated) START, the last ends with
    /// STOP. After an error: STOP, and the peripheral reset and set up again.
    fn transaction(
        &mut self,
        address: SevenBitAddress,
        operations: &mut [Operation<'_>],
    ) -> Result<(), Self::Error> {
        let result = self.run(address, operations);
        if let Err(I2cError(kind)) = result {
            self.cr1_set(STOP);
            if matches!(kind, ErrorKind::Bus | ErrorKind::ArbitrationLoss) {
                // SAFETY: PE off before the pins leave the peripheral (the erratum's sequence).
                self.i2c.cr1().write(|w| unsafe { w.bits(0) });
                let _ = clear_bus();
            }
            self.configure();
        }
        result
    }
}

/// PB6 or PB7 as an open-drain GPIO line for the bus clear: set high = released (BSRR),
/// level from IDR.
struct BusLine(u32);

impl digital::ErrorType for BusLine {
    type Error = Infallible;
}

impl OutputPin for BusLine {
    fn set_low(&mut self) -> Result<(), Infallible> {
        Port::B.write(BSRR, 1 << (self.0 + 16));
        Ok(())
    }

    fn set_high(&mut self) -> Result<(), Infallible> {
        Port::B.write(BSRR, 1 << self.0);
        Ok(())
    }
}

impl InputPin for BusLine {
    fn is_high(&mut self) -> Result<bool, Infallible> {
        Ok(Port::B.read(IDR) & (1 << self.0) != 0)
    }

    fn is_low(&mut self) -> Result<bool, Infallible> {
        self.is_high().map(|high| !high)
    }
}

/// A busy wait of at least `ns`, rounded up to whole microseconds of SYSCLK cycles
/// (`asm::delay` waits at least its count; flash wait states only lengthen it).
struct CycleDelay;

impl DelayNs for CycleDelay {
    fn delay_ns(&mut self, ns: u32) {
        cortex_m::asm::delay(
            ns.div_ceil(1000)
                .saturating_mul(super::SYSCLK_HZ / 1_000_000),
        );
    }
}

/// The bus clear through GPIO (see the module docs); I2C1 must be off (`PE` = 0). Leaves
/// PB6/PB7 in AF4, open drain.
fn clear_bus() -> Recovery {
    for pin in [SCL_PIN, SDA_PIN] {
        Port::B.write(BSRR, 1 << pin);
        Port::B.modify(OTYPER, 0, 1 << pin);
        Port::B.modify(MODER, 0b11 << (2 * pin), 0b01 << (2 * pin));
    }
    let Ok(outcome) = bus_recovery::recover(
        &mut BusLine(SCL_PIN),
        &mut BusLine(SDA_PIN),
        &mut CycleDelay,
        &RecoveryTiming::STANDARD,
    );
    for pin in [SCL_PIN, SDA_PIN] {
        Port::B.alternate(pin, AF_I2C1);
    }
    outcome
}
