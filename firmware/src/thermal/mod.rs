//! Temperature: the gyro block's sensor, the temperature's rate, and the thermal model of the
//! bias and scale factor that the board applies to its output.
//!
//! A ring laser gyro's bias, scale factor and lock-in move with temperature (docs/physics.md
//! section 13). The board reads a TI TMP117 on the gyro block over I2C: ±0.1 °C from -20 to
//! +50 °C without calibration (±0.15 °C to -40/+70 °C), 1/128 °C resolution, a result every
//! 125 ms, four addresses on one bus, no analog front end to calibrate or drift; a PT100 with a
//! ratiometric ADC front end reaches the same accuracy only after calibration, and a thermistor
//! does not over -40..+85 °C. The rooms:
//!
//! - [`tmp117`]: the driver, generic over `embedded_hal::i2c::I2c` (embedded-hal 1.0), and why
//!   it is not the `tmp117` crate;
//! - [`bus_recovery`]: the I2C bus clear (up to nine clocks while SDA is low, then START and
//!   STOP), over embedded-hal's pin traits; the board runs it on I2C1's pins;
//! - [`sensor`]: when to poll, and the faults (NACK, stuck bus, frozen reading) with the time
//!   each takes to show;
//! - [`rate`]: the temperature's rate;
//! - [`model`]: the stored model (bias: cubic in T plus a rate term; scale factor: quadratic)
//!   and the correction it makes;
//! - [`state`]: what the main loop keeps and hands the output stage ([`state::ThermalInput`]);
//! - [`fit`]: the thermal calibration's fits and checks (host tools).
//!
//! Where it runs: the board's main loop polls the sensor (`board::app`, never an interrupt:
//! an I2C transfer takes ~100-200 us), hands each update to the command service
//! (`service::Service::on_sensor`), which keeps the [`state::ThermalState`] and stages the
//! [`state::ThermalInput`] into the readout (`Readout::set_thermal`), whose output latch applies
//! it to the next records. hal-sim runs the same code against its simulated TMP117.

pub mod bus_recovery;
pub mod fit;
pub mod model;
pub mod rate;
pub mod sensor;
pub mod state;
pub mod tmp117;
