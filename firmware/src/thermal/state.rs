//! The thermal state the main loop keeps: the sensor's state and last reading, the rate, the
//! model in force, and what the output stage gets of them ([`ThermalInput`]).
//!
//! The model is applied when all of these hold, else the records go uncorrected and say so
//! (`OutputStatus::THERMAL_CORRECTED` clear; `THERMAL_SENSOR_FAULT` set for a sensor fault):
//! a model is in force and switched on, the sensor is `Ok`, the temperature lies in the model's
//! range, and the rate is known if the model uses it (a full rate window after a start or a
//! fault: 2 s).

use super::model::{ThermalCorrection, ThermalModel};
use super::rate::RateEstimator;
use super::sensor::{Reading, SensorState, SensorUpdate};

/// A temperature or rate word that holds no value (i16 minimum).
pub const NO_VALUE: i16 = i16::MIN;

/// Why the model is not applied now.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ModelState {
    /// Applied.
    Applied,
    /// No model in force.
    #[default]
    None,
    /// A model is in force but switched off.
    Off,
    /// The sensor has a fault, or has not delivered yet.
    NoSensor,
    /// The rate window is not full yet (the model uses the rate).
    NoRate,
    /// The temperature lies outside the model's range.
    OutOfRange,
}

impl ModelState {
    /// The word `thermal` answers.
    pub fn name(self) -> &'static str {
        match self {
            Self::Applied => "applied",
            Self::None => "none",
            Self::Off => "off",
            Self::NoSensor => "no_sensor",
            Self::NoRate => "no_rate",
            Self::OutOfRange => "out_of_range",
        }
    }
}

/// What the output stage takes from the thermal state, whole (`Readout::set_thermal`).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ThermalInput {
    /// The last reading, 1/128 °C ([`NO_VALUE`] without one or in a fault).
    pub temperature_q7: i16,
    /// The rate, 0.01 °C/min, saturated ([`NO_VALUE`] while unknown).
    pub rate_centi_c_per_min: i16,
    /// The sensor has a fault.
    pub sensor_fault: bool,
    /// The correction in force, if the model is applied.
    pub correction: Option<ThermalCorrection>,
}

impl ThermalInput {
    /// Nothing known (before the first reading).
    pub const NONE: Self = Self {
        temperature_q7: NO_VALUE,
        rate_centi_c_per_min: NO_VALUE,
        sensor_fault: false,
        correction: None,
    };
}

impl Default for ThermalInput {
    fn default() -> Self {
        Self::NONE
    }
}

/// The rate word of `rate_c_per_s`: 0.01 °C/min, saturated short of [`NO_VALUE`].
pub fn rate_word(rate_c_per_s: f32) -> i16 {
    let centi = libm::roundf(rate_c_per_s * 6000.0);
    centi.clamp(-32767.0, 32767.0) as i16
}

/// The main loop's thermal state.
#[derive(Clone, Copy, Debug, Default)]
pub struct ThermalState {
    sensor: SensorState,
    reading: Option<Reading>,
    rate: RateEstimator,
    model: Option<ThermalModel>,
    enabled: bool,
    input: ThermalInput,
    model_state: ModelState,
    /// Sensor faults entered since boot (saturating).
    faults: u32,
}

impl ThermalState {
    /// No reading, no model.
    pub fn new() -> Self {
        Self::default()
    }

    /// What the monitor found; returns the input for the output stage.
    pub fn on_sensor(&mut self, update: SensorUpdate, scale_factor_arcsec: f32) -> ThermalInput {
        if update.state.is_fault() && !self.sensor.is_fault() {
            self.faults = self.faults.saturating_add(1);
        }
        self.sensor = update.state;
        if update.state.is_fault() {
            self.reading = None;
            self.rate.clear();
        }
        if let Some(r) = update.reading {
            self.rate.push(&r);
            self.reading = Some(r);
        }
        self.refresh(scale_factor_arcsec)
    }

    /// Puts `model` in force (`None`: no model), switched on (`enabled`) or off.
    pub fn set_model(
        &mut self,
        model: Option<ThermalModel>,
        enabled: bool,
        scale_factor_arcsec: f32,
    ) -> ThermalInput {
        self.model = model;
        self.enabled = enabled && model.is_some();
        self.refresh(scale_factor_arcsec)
    }

    fn refresh(&mut self, scale_factor_arcsec: f32) -> ThermalInput {
        let ok = self.sensor == SensorState::Ok;
        let reading = self.reading.filter(|_| ok);
        let rate = self.rate.rate_c_per_s().filter(|_| ok);
        let temp_c = reading.map(|r| r.temp_c());
        self.model_state = match (self.model, self.enabled) {
            (None, _) => ModelState::None,
            (Some(_), false) => ModelState::Off,
            (Some(m), true) => match temp_c {
                None => ModelState::NoSensor,
                Some(t) if !m.holds_at(t) => ModelState::OutOfRange,
                Some(_) if m.uses_rate() && rate.is_none() => ModelState::NoRate,
                Some(_) => ModelState::Applied,
            },
        };
        let correction = match (self.model_state, self.model, temp_c) {
            (ModelState::Applied, Some(m), Some(t)) => Some(ThermalCorrection::of(
                &m,
                t,
                rate.unwrap_or(0.0) * 60.0,
                scale_factor_arcsec,
            )),
            _ => None,
        };
        self.input = ThermalInput {
            temperature_q7: reading.map_or(NO_VALUE, |r| r.raw),
            rate_centi_c_per_min: rate.map_or(NO_VALUE, rate_word),
            sensor_fault: self.sensor.is_fault(),
            correction,
        };
        self.input
    }

    /// The input the output stage was last given.
    pub fn input(&self) -> ThermalInput {
        self.input
    }

    /// The sensor's state.
    pub fn sensor(&self) -> SensorState {
        self.sensor
    }

    /// The last reading while the sensor is `Ok`, °C.
    pub fn temperature_c(&self) -> Option<f32> {
        self.reading
            .filter(|_| self.sensor == SensorState::Ok)
            .map(|r| r.temp_c())
    }

    /// The rate, °C/s, once known.
    pub fn rate_c_per_s(&self) -> Option<f32> {
        self.rate
            .rate_c_per_s()
            .filter(|_| self.sensor == SensorState::Ok)
    }

    /// The model in force, if any.
    pub fn model(&self) -> Option<ThermalModel> {
        self.model
    }

    /// Whether the model in force is switched on.
    pub fn enabled(&self) -> bool {
        self.enabled
    }

    /// Whether (and why not) the model is applied now.
    pub fn model_state(&self) -> ModelState {
        self.model_state
    }

    /// Sensor faults entered since boot.
    pub fn faults(&self) -> u32 {
        self.faults
    }
}
