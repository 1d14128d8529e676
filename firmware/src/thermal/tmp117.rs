//! A small driver for the TI TMP117 digital temperature sensor, written against
//! `embedded_hal::i2c::I2c` (embedded-hal 1.0), so that one driver runs on the board's I2C1
//! (`board::i2c`) and against hal-sim's simulated sensor in `cargo test`.
//!
//! # The part (TI TMP117 data sheet, SNOSD82D)
//!
//! - Temperature result register 0x00: 16-bit two's complement, LSB 7.8125 m°C (1/128 °C);
//!   it reads 0x8000 (-256 °C) after a reset until the first conversion is complete.
//! - Configuration register 0x01: bit 13 `Data_Ready` (set at the end of a conversion, cleared
//!   when the configuration or the result register is read), bits 11:10 `MOD` (00 continuous
//!   conversion), bits 9:7 `CONV`, bits 6:5 `AVG` (01: 8 conversions averaged), bit 1
//!   `Soft_Reset`. [`CONFIGURATION`] selects continuous conversion, 8 averages and `CONV` = 000,
//!   i.e. one result every 125 ms ([`CONVERSION_MS`]).
//! - Device ID register 0x0F: 0x0117 ([`DEVICE_ID`]; bits 15:12 are the revision).
//! - Accuracy ±0.1 °C from -20 to +50 °C, ±0.15 °C from -40 to +70 °C without calibration;
//!   I2C address 0x48 with ADD0 at GND ([`ADDRESS`]); the interface resets itself when SCL or
//!   SDA are held low for about 30 ms (the SMBus time-out), which frees a bus a reset left in
//!   the middle of a byte.
//!
//! # Why not the `tmp117` crate
//!
//! The `tmp117` crate (2.x/3.x, embedded-hal 1.0) is a complete driver, but its high-level API
//! waits: `wait_temp` polls with a `DelayNs` until a conversion is ready, and the driver keeps
//! the part in shutdown between its closures (a battery design). Here the read runs in the
//! board's main loop, which must not block for a conversion (125 ms) nor own a delay; it needs
//! one non-blocking step (is a result ready? then read it) and every bus error passed up
//! unchanged, so the monitor (`super::sensor`) can tell a NACK from a stuck bus. Its
//! dependencies (`bilge`, `device-register`, `embedded-hal-async`) would also add to the image.
//! Two register reads and one write are all this board needs.
//!
//! # Cost
//!
//! A poll is one `write_read` of the configuration register (address + pointer, repeated start,
//! address + 2 bytes: 38 bit times with the ACKs) and, when a result is ready (every 125 ms),
//! one more of the result register: 95 us and 190 us at 400 kHz, in the main loop; the
//! readout's interrupts preempt it (the F405's I2C master stretches SCL while it waits for
//! software, which the part accepts), so they see no added latency.

use embedded_hal::i2c::{I2c, SevenBitAddress};

/// The sensor's 7-bit address with ADD0 tied to GND.
pub const ADDRESS: SevenBitAddress = 0x48;
/// Temperature result register.
pub const REG_TEMPERATURE: u8 = 0x00;
/// Configuration register.
pub const REG_CONFIGURATION: u8 = 0x01;
/// Device ID register.
pub const REG_DEVICE_ID: u8 = 0x0F;
/// The device ID's part number bits (11:0) read 0x117.
pub const DEVICE_ID: u16 = 0x0117;
/// Configuration `Data_Ready` bit.
pub const DATA_READY: u16 = 1 << 13;
/// Continuous conversion (MOD = 00), CONV = 000, AVG = 01 (8 averages): a result every 125 ms.
pub const CONFIGURATION: u16 = 0b01 << 5;
/// Time between two results with [`CONFIGURATION`], ms (data sheet: 8 averages, 125 ms).
pub const CONVERSION_MS: u32 = 125;
/// The result register's value before the first conversion (-256 °C).
pub const NO_RESULT: i16 = i16::MIN;
/// Degrees Celsius per LSB of the result register: 1/128.
pub const C_PER_LSB: f32 = 1.0 / 128.0;

/// What went wrong talking to the sensor.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Tmp117Error<E> {
    /// The bus transaction failed (the I2C implementation's error: NACK, bus error, time-out).
    Bus(E),
    /// The device ID register holds another part (the value read).
    WrongDevice(u16),
}

/// The driver: the bus and the sensor's address.
#[derive(Debug)]
pub struct Tmp117<I> {
    i2c: I,
    address: SevenBitAddress,
}

impl<I: I2c> Tmp117<I> {
    /// A sensor at `address` on `i2c`.
    pub fn new(i2c: I, address: SevenBitAddress) -> Self {
        Self { i2c, address }
    }

    /// The bus, for fault injection in tests and to release it.
    pub fn i2c_mut(&mut self) -> &mut I {
        &mut self.i2c
    }

    fn read(&mut self, register: u8) -> Result<u16, Tmp117Error<I::Error>> {
        let mut bytes = [0u8; 2];
        self.i2c
            .write_read(self.address, &[register], &mut bytes)
            .map_err(Tmp117Error::Bus)?;
        Ok(u16::from_be_bytes(bytes))
    }

    /// Checks the device ID and starts continuous conversion ([`CONFIGURATION`]).
    pub fn start(&mut self) -> Result<(), Tmp117Error<I::Error>> {
        let id = self.read(REG_DEVICE_ID)?;
        if id & 0x0FFF != DEVICE_ID {
            return Err(Tmp117Error::WrongDevice(id));
        }
        let [hi, lo] = CONFIGURATION.to_be_bytes();
        self.i2c
            .write(self.address, &[REG_CONFIGURATION, hi, lo])
            .map_err(Tmp117Error::Bus)
    }

    /// One non-blocking step: the new result (raw, 1/128 °C) if a conversion ended since the last
    /// call, `Ok(None)` if none did. Reading the configuration clears `Data_Ready`.
    pub fn poll(&mut self) -> Result<Option<i16>, Tmp117Error<I::Error>> {
        if self.read(REG_CONFIGURATION)? & DATA_READY == 0 {
            return Ok(None);
        }
        Ok(Some(self.read(REG_TEMPERATURE)? as i16))
    }
}
