//! A simulated TI TMP117 on the gyro block, behind `embedded_hal::i2c::I2c` (embedded-hal 1.0):
//! the firmware's own driver (`firmware::thermal::tmp117`) and monitor run against it in
//! `cargo test` as they run against the board's I2C1.
//!
//! The model: the registers the driver uses (result 0x00, configuration 0x01 with
//! `Data_Ready`, device ID 0x0F = 0x0117), continuous conversion with a result every 125 ms
//! (the configuration the driver writes; the result register reads -256 °C until the first
//! one, as after the part's reset), the block's temperature from the gyro's profile plus a
//! fixed offset (the part's accuracy, ±0.1 °C) and white noise of about one LSB
//! (`noise_rms_c`), rounded to 1/128 °C. A write to an unknown register or a malformed transfer
//! is a NACK of the data, as on the part. Faults ([`SensorFault`]):
//!
//! - `Nack`: nothing acknowledges the address (the part unpowered or gone);
//! - `StuckBus`: SDA held low: every transfer ends in a bus error (the board's controller
//!   reports its time-out as `ErrorKind::Bus`);
//! - `Frozen`: the conversion stops: `Data_Ready` never sets again, the result holds;
//! - `StuckCode`: conversions go on, always with the same code.
//!
//! Time is the caller's: [`SimTmp117::set_time_s`] before each poll (the simulated board's
//! clock).

use crate::dither::resonator::TemperatureProfile;
use embedded_hal::i2c::{
    ErrorKind, ErrorType, I2c, NoAcknowledgeSource, Operation, SevenBitAddress,
};
use firmware::thermal::tmp117::{
    ADDRESS, CONVERSION_MS, DATA_READY, DEVICE_ID, REG_CONFIGURATION, REG_DEVICE_ID,
    REG_TEMPERATURE,
};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

/// A fault of the sensor or its bus.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SensorFault {
    /// The address is not acknowledged.
    Nack,
    /// SDA held low: every transfer fails with a bus error.
    StuckBus,
    /// The conversion stops: no new result.
    Frozen,
    /// Results go on with one code.
    StuckCode,
}

/// The bus error the simulated controller reports.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BusError(pub ErrorKind);

impl embedded_hal::i2c::Error for BusError {
    fn kind(&self) -> ErrorKind {
        self.0
    }
}

/// The simulated sensor and its bus.
#[derive(Clone, Debug)]
pub struct SimTmp117 {
    profile: TemperatureProfile,
    offset_c: f64,
    noise_rms_c: f64,
    rng: ChaCha8Rng,
    now_s: f64,
    configuration: u16,
    pointer: u8,
    /// The result register.
    result: i16,
    /// Conversions counted so far (continuous mode started at `started_s`).
    converted: u64,
    started_s: Option<f64>,
    fault: Option<SensorFault>,
    /// Transfers made (for the cost figures).
    pub transfers: u64,
}

impl SimTmp117 {
    /// A sensor on a block at `profile`, reading `offset_c` high with `noise_rms_c` of noise,
    /// seeded by `seed`; at power-up (shutdown: no conversion until configured).
    pub fn new(profile: TemperatureProfile, offset_c: f64, noise_rms_c: f64, seed: u64) -> Self {
        Self {
            profile,
            offset_c,
            noise_rms_c,
            rng: ChaCha8Rng::seed_from_u64(seed),
            now_s: 0.0,
            configuration: 0x0220,
            pointer: 0,
            result: i16::MIN,
            converted: 0,
            started_s: None,
            fault: None,
            transfers: 0,
        }
    }

    /// The simulated time now, s (forward only).
    pub fn set_time_s(&mut self, t_s: f64) {
        self.now_s = self.now_s.max(t_s);
        self.convert_until_now();
    }

    /// Injects a fault (`None`: the fault ends).
    pub fn set_fault(&mut self, fault: Option<SensorFault>) {
        self.fault = fault;
    }

    /// The fault in force.
    pub fn fault(&self) -> Option<SensorFault> {
        self.fault
    }

    fn convert_until_now(&mut self) {
        let Some(start) = self.started_s else {
            return;
        };
        if self.fault == Some(SensorFault::Frozen) {
            return;
        }
        let period = f64::from(CONVERSION_MS) * 1e-3;
        let due = ((self.now_s - start) / period).floor().max(0.0) as u64;
        if due > self.converted {
            // Only the latest result matters (the register holds one).
            let end_s = start + due as f64 * period;
            self.converted = due;
            if self.fault != Some(SensorFault::StuckCode) {
                let z: f64 = StandardNormal.sample(&mut self.rng);
                let temp = self.profile.at(end_s) + self.offset_c + self.noise_rms_c * z;
                self.result = (temp * 128.0).round().clamp(-32768.0, 32767.0) as i16;
            }
            self.configuration |= DATA_READY;
        }
    }

    fn read_register(&mut self) -> u16 {
        match self.pointer {
            REG_TEMPERATURE => {
                self.configuration &= !DATA_READY;
                self.result as u16
            }
            REG_CONFIGURATION => {
                let c = self.configuration;
                self.configuration &= !DATA_READY;
                c
            }
            REG_DEVICE_ID => DEVICE_ID,
            _ => 0,
        }
    }

    fn write_bytes(&mut self, bytes: &[u8]) -> Result<(), BusError> {
        let Some((&pointer, data)) = bytes.split_first() else {
            return Ok(());
        };
        if ![REG_TEMPERATURE, REG_CONFIGURATION, REG_DEVICE_ID].contains(&pointer) {
            return Err(BusError(ErrorKind::NoAcknowledge(
                NoAcknowledgeSource::Data,
            )));
        }
        self.pointer = pointer;
        match data {
            [] => Ok(()),
            [hi, lo] if pointer == REG_CONFIGURATION => {
                let value = u16::from_be_bytes([*hi, *lo]);
                // MOD = 00: continuous conversion from now on.
                if (value >> 10) & 0b11 == 0 && self.started_s.is_none() {
                    self.started_s = Some(self.now_s);
                    self.converted = 0;
                }
                self.configuration = (value & !DATA_READY) | (self.configuration & DATA_READY);
                Ok(())
            }
            _ => Err(BusError(ErrorKind::NoAcknowledge(
                NoAcknowledgeSource::Data,
            ))),
        }
    }
}

impl ErrorType for SimTmp117 {
    type Error = BusError;
}

impl I2c<SevenBitAddress> for SimTmp117 {
    fn transaction(
        &mut self,
        address: SevenBitAddress,
        operations: &mut [Operation<'_>],
    ) -> Result<(), Self::Error> {
        self.transfers += 1;
        self.convert_until_now();
        match self.fault {
            Some(SensorFault::Nack) => {
                return Err(BusError(ErrorKind::NoAcknowledge(
                    NoAcknowledgeSource::Address,
                )))
            }
            Some(SensorFault::StuckBus) => return Err(BusError(ErrorKind::Bus)),
            _ => {}
        }
        if address != ADDRESS {
            return Err(BusError(ErrorKind::NoAcknowledge(
                NoAcknowledgeSource::Address,
            )));
        }
        for op in operations {
            match op {
                Operation::Write(bytes) => self.write_bytes(bytes)?,
                Operation::Read(buf) => {
                    let value = self.read_register().to_be_bytes();
                    for (b, v) in buf.iter_mut().zip(value.iter().cycle()) {
                        *b = *v;
                    }
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use firmware::thermal::sensor::{SensorConfig, SensorMonitor, SensorState};
    use firmware::thermal::tmp117::Tmp117;

    fn sensor() -> Tmp117<SimTmp117> {
        let profile = TemperatureProfile::ramp(0.0, 20.0, 10.0, 30.0).unwrap();
        Tmp117::new(SimTmp117::new(profile, 0.02, 0.0078, 7), ADDRESS)
    }

    /// The states a run reported with their times (ms), and its readings (ms, °C).
    type Seen = (Vec<(u64, SensorState)>, Vec<(u64, f32)>);

    /// Runs the monitor every 10 ms from `from_ms` to `to_ms`: the states it reported with
    /// their times, and the readings.
    fn run(m: &mut SensorMonitor, s: &mut Tmp117<SimTmp117>, from_ms: u64, to_ms: u64) -> Seen {
        let (mut states, mut readings) = (Vec::new(), Vec::new());
        for ms in (from_ms..to_ms).step_by(10) {
            s.i2c_mut().set_time_s(ms as f64 * 1e-3);
            if let Some(u) = m.poll(&SensorConfig::DEFAULT, s, ms) {
                states.push((ms, u.state));
                if let Some(r) = u.reading {
                    readings.push((ms, r.temp_c()));
                }
            }
        }
        (states, readings)
    }

    /// The firmware's driver and monitor against the simulated part: eight readings a second
    /// following the ramp (1 °C/s) within the offset, noise and the result's age (at most
    /// 125 ms + one poll: 0.18 °C); then each fault shows within its stated time
    /// (`firmware::thermal::sensor`), and the part comes back when it ends.
    #[test]
    fn readings_and_every_fault_within_its_time() {
        let (mut m, mut s) = (SensorMonitor::new(), sensor());
        let (_, readings) = run(&mut m, &mut s, 0, 2000);
        assert!((14..=17).contains(&readings.len()), "{}", readings.len());
        for &(ms, temp) in &readings {
            let truth = 20.0 + ms as f32 * 1e-3;
            assert!((temp - truth).abs() < 0.2, "{ms}: {temp} vs {truth}");
        }
        assert_eq!(m.state(), SensorState::Ok);
        for (i, (fault, state, within_ms)) in [
            (SensorFault::Nack, SensorState::Nack, 100),
            (SensorFault::StuckBus, SensorState::Bus, 100),
            (SensorFault::Frozen, SensorState::Frozen, 425),
            (SensorFault::StuckCode, SensorState::Frozen, 8100),
        ]
        .into_iter()
        .enumerate()
        {
            let t0 = 5000 + 20_000 * i as u64;
            let _ = run(&mut m, &mut s, t0 - 3000, t0);
            assert_eq!(m.state(), SensorState::Ok, "{fault:?}: healthy before");
            s.i2c_mut().set_fault(Some(fault));
            let (states, readings) = run(&mut m, &mut s, t0, t0 + 10_000);
            let (at, got) = states
                .iter()
                .copied()
                .find(|(_, st)| st.is_fault())
                .unwrap_or_else(|| panic!("{fault:?}: {states:?}"));
            assert_eq!(got, state, "{fault:?}");
            assert!(at - t0 <= within_ms, "{fault:?} after {} ms", at - t0);
            assert!(
                readings.iter().all(|&(ms, _)| ms < at),
                "no reading after the fault"
            );
            s.i2c_mut().set_fault(None);
            let (_, readings) = run(&mut m, &mut s, t0 + 10_000, t0 + 13_000);
            assert!(!readings.is_empty(), "{fault:?}: back");
            assert_eq!(m.state(), SensorState::Ok);
        }
    }
}
