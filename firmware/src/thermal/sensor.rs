//! The sensor's monitor: when to poll the TMP117, and what its answers (or silences) mean.
//!
//! The main loop calls [`SensorMonitor::poll`] every pass; the monitor talks to the part at
//! most every [`SensorConfig::poll_ms`] and says what changed: a new reading, or a new state.
//! The states and how soon each fault shows (with the default [`SensorConfig`]):
//!
//! | state | cause | shown after |
//! |---|---|---|
//! | [`SensorState::Starting`] | power-up, or a restart after a fault: the part configured, no result yet | |
//! | [`SensorState::Ok`] | fresh, changing results | |
//! | [`SensorState::Nack`] | the address is not acknowledged (part absent, unpowered, wrong address) | 2 failed polls: 50-100 ms |
//! | [`SensorState::Bus`] | the transaction cannot complete (SDA or SCL held low, arbitration lost, the controller's time-out) | 2 failed polls: 50-100 ms plus the controller's time-out |
//! | [`SensorState::Frozen`] | no new result for [`SensorConfig::stale_ms`] (the conversion stopped), or the same code [`SensorConfig::frozen_codes`] times in a row (the converter stuck) | 375-425 ms; 64 results = 8 s |
//! | [`SensorState::WrongDevice`] | the device ID is not the TMP117's | at the start |
//!
//! A fault is declared after two failed polls in a row, not one: a single disturbed transfer
//! (a glitch on a long cable) costs one poll, not the thermal correction. While in a fault the
//! monitor tries to start the part again every [`SensorConfig::restart_ms`] (a part that lost
//! power has lost its configuration); a started part is `Starting` until its first result.
//!
//! The stuck-code rule needs a part whose results move: the TMP117 with 8 averages shows about
//! one LSB (7.8 m°C) of noise, so 64 equal codes in a row do not happen to a live part (hal-sim's
//! sensor models that noise, `hal_sim::tmp117`).

use embedded_hal::i2c::{ErrorKind, I2c};

use super::tmp117::{Tmp117, Tmp117Error, CONVERSION_MS, NO_RESULT};

/// The monitor's settings (immutable).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SensorConfig {
    /// Least time between two polls, ms.
    pub poll_ms: u32,
    /// Failed polls in a row that declare a fault.
    pub fail_after: u8,
    /// A healthy part delivers a result at least this often, ms (else: frozen).
    pub stale_ms: u32,
    /// Equal codes in a row that declare the converter stuck (frozen).
    pub frozen_codes: u16,
    /// Time between restart attempts while in a fault, ms.
    pub restart_ms: u32,
}

impl SensorConfig {
    /// The board's settings: polls every 50 ms (a result is read within 50 ms of its end), a
    /// fault after two failed polls, stale after three conversion times (375 ms), stuck after
    /// 64 equal codes, a restart attempt every second.
    pub const DEFAULT: Self = Self {
        poll_ms: 50,
        fail_after: 2,
        stale_ms: 3 * CONVERSION_MS,
        frozen_codes: 64,
        restart_ms: 1000,
    };
}

/// What the monitor knows of the sensor.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum SensorState {
    /// Not started yet, or started and waiting for its first result.
    #[default]
    Starting,
    /// Fresh results.
    Ok,
    /// The address is not acknowledged.
    Nack,
    /// The bus transaction cannot complete (stuck bus, lost arbitration, time-out).
    Bus,
    /// No new result, or the same code for too long.
    Frozen,
    /// Another part answers at the address.
    WrongDevice,
}

impl SensorState {
    /// A fault: the readings cannot be trusted (no thermal correction).
    pub fn is_fault(self) -> bool {
        !matches!(self, Self::Starting | Self::Ok)
    }

    /// The word `thermal` answers.
    pub fn name(self) -> &'static str {
        match self {
            Self::Starting => "starting",
            Self::Ok => "ok",
            Self::Nack => "nack",
            Self::Bus => "bus",
            Self::Frozen => "frozen",
            Self::WrongDevice => "wrong_device",
        }
    }
}

/// One result of the sensor.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Reading {
    /// The result register, 1/128 °C.
    pub raw: i16,
    /// When it was read, ms since boot.
    pub at_ms: u64,
}

impl Reading {
    /// The temperature, °C.
    pub fn temp_c(&self) -> f32 {
        f32::from(self.raw) * super::tmp117::C_PER_LSB
    }
}

/// What a poll found: the state after it, and a new result if there was one.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SensorUpdate {
    /// The sensor's state after the poll.
    pub state: SensorState,
    /// A new result (only while the state is `Ok`).
    pub reading: Option<Reading>,
}

/// The monitor's state.
#[derive(Clone, Copy, Debug, Default)]
pub struct SensorMonitor {
    state: SensorState,
    started: bool,
    failures: u8,
    next_poll_ms: u64,
    next_restart_ms: u64,
    /// When the last result arrived (or the part was started), ms.
    last_result_ms: u64,
    last_raw: Option<i16>,
    same_codes: u16,
}

impl SensorMonitor {
    /// Not started; the first poll starts the part.
    pub fn new() -> Self {
        Self::default()
    }

    /// The state now.
    pub fn state(&self) -> SensorState {
        self.state
    }

    /// One step at `now_ms` (monotonic): talks to the part if a poll is due; returns what
    /// changed (a new reading, or another state), `None` if nothing did.
    pub fn poll<I: I2c>(
        &mut self,
        config: &SensorConfig,
        sensor: &mut Tmp117<I>,
        now_ms: u64,
    ) -> Option<SensorUpdate> {
        if now_ms < self.next_poll_ms {
            return None;
        }
        self.next_poll_ms = now_ms.saturating_add(u64::from(config.poll_ms));
        let before = self.state;
        let mut reading = None;
        if !self.started {
            if self.state.is_fault() && now_ms < self.next_restart_ms {
                return None;
            }
            self.next_restart_ms = now_ms.saturating_add(u64::from(config.restart_ms));
            match sensor.start() {
                Ok(()) => {
                    self.started = true;
                    self.failures = 0;
                    self.state = SensorState::Starting;
                    self.last_result_ms = now_ms;
                    self.last_raw = None;
                    self.same_codes = 0;
                }
                Err(e) => self.failed(config, e),
            }
        } else {
            match sensor.poll() {
                Ok(Some(raw)) => reading = self.result(config, raw, now_ms),
                Ok(None) => {
                    self.failures = 0;
                    let silent = now_ms.saturating_sub(self.last_result_ms);
                    if silent > u64::from(config.stale_ms) {
                        self.fault(SensorState::Frozen);
                    }
                }
                Err(e) => self.failed(config, e),
            }
        }
        (reading.is_some() || self.state != before).then_some(SensorUpdate {
            state: self.state,
            reading,
        })
    }

    fn result(&mut self, config: &SensorConfig, raw: i16, now_ms: u64) -> Option<Reading> {
        self.failures = 0;
        self.last_result_ms = now_ms;
        if raw == NO_RESULT {
            // The power-on value: the part was reset behind our back; start it again.
            self.started = false;
            self.state = SensorState::Starting;
            return None;
        }
        self.same_codes = if self.last_raw == Some(raw) {
            self.same_codes.saturating_add(1)
        } else {
            0
        };
        self.last_raw = Some(raw);
        if self.same_codes.saturating_add(1) >= config.frozen_codes {
            self.fault(SensorState::Frozen);
            return None;
        }
        self.state = SensorState::Ok;
        Some(Reading { raw, at_ms: now_ms })
    }

    fn failed<E: embedded_hal::i2c::Error>(&mut self, config: &SensorConfig, e: Tmp117Error<E>) {
        let state = match e {
            Tmp117Error::WrongDevice(_) => SensorState::WrongDevice,
            Tmp117Error::Bus(e) => match e.kind() {
                ErrorKind::NoAcknowledge(_) => SensorState::Nack,
                _ => SensorState::Bus,
            },
        };
        self.failures = self.failures.saturating_add(1);
        if self.failures >= config.fail_after || state == SensorState::WrongDevice {
            self.fault(state);
        }
    }

    /// Enters a fault: the part is started again before the next reading is believed (a
    /// frozen part keeps being polled: fresh, changing codes end the fault).
    fn fault(&mut self, state: SensorState) {
        self.state = state;
        if state != SensorState::Frozen {
            self.started = false;
        }
    }
}
