//! The event bytes the line-driven targets (`protocol`, `service`, `device`) take out of the
//! serial stream, so that one input also drives time, the readout, the flash and the link.
//! One language for the three, so their seeds and dictionary are shared. Every byte value
//! here is a control character the protocol refuses anyway (`ERR 8`), so little is lost.

/// A minute passes (unlock timeouts, the unlock windows' period).
pub const TICK: u8 = 0x01;
/// Dither cycles reach the service (calibration runs, streaming, staged settings); in the
/// `service` target through the board's 32-record queue, overfilled so some are dropped.
pub const CYCLES: u8 = 0x02;
/// The next flash store (or OTP write) fails.
pub const FAIL_STORE: u8 = 0x03;
/// As the input's first byte: the board boots with blank OTP (no key; `key provision` writes
/// one, once).
pub const BLANK_OTP: u8 = 0x04;
/// A new client on the link (a served board's new connection): a new session.
pub const NEW_SESSION: u8 = 0x05;
/// The board resets (the `service` target: backup RAM kept; the `device` target: a power
/// cycle, the flash kept).
pub const RESET: u8 = 0x06;
/// Three seconds pass (to reach an unlock window, 250 ms every 10 s).
pub const TICK_SHORT: u8 = 0x07;
/// Output records reach the service (`stream output`); in the `device` target: 50 ms pass.
pub const OUTPUTS: u8 = 0x08;
