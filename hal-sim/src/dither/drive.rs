//! The drive as the firmware's DDS writes it: [`DriveSegment`]s and how they reach a gyro
//! ([`DriveSink`]); `super::open_loop` is an open-loop source of them.
//!
//! The firmware's drive timer ticks at a fixed rate `f_s` and writes the DAC code
//! `mid + round(amp sin(phase + n step))` at every tick. Its DDS parameters change only at its
//! loop updates (at most about twice per dither cycle), so the drive reaches the simulator as
//! segments: from `start_s` on, these parameters, until the next segment's start. The
//! simulator takes them in volts at the DAC output (`DacParams::volts` converts codes).
//!
//! The drive is known only as far as the caller has said: a segment's end is the next
//! segment's start, and [`DriveSink::extend_drive_until`] states how long the last one is
//! known to hold. The gyro never plans beyond that time (see [`super::driven`] for the lead a
//! caller keeps).

use core::f64::consts::{PI, TAU};

/// Bits of the board's DAC (STM32F405 DAC1: 12 bits).
pub const DAC_BITS: u32 = 12;

/// The board's DAC and the drive timer that writes it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DacParams {
    /// Rate of the drive timer (one DAC write and one pick-off conversion per tick), Hz.
    /// Range [8 f0, 1e7] (the zero-order-hold model needs the images well above f0).
    pub tick_hz: f64,
    /// DAC reference (full scale), V. Range (0, 10].
    pub reference_v: f64,
}

impl Default for DacParams {
    /// The board's: the profile's drive tick (`BoardProfile::F405.drive_tick_hz`, 40 kHz) and
    /// 3.3 V (VREF+).
    fn default() -> Self {
        Self {
            tick_hz: f64::from(firmware::profile::BoardProfile::F405.drive_tick_hz),
            reference_v: 3.3,
        }
    }
}

impl DacParams {
    /// One DAC code, V.
    pub fn lsb_v(&self) -> f64 {
        self.reference_v / f64::from(1u32 << DAC_BITS)
    }

    /// The output for a (fractional) code, V.
    pub fn volts(&self, code: f64) -> f64 {
        code * self.lsb_v()
    }

    /// The tick period, s.
    pub fn tick_s(&self) -> f64 {
        1.0 / self.tick_hz
    }
}

/// The DDS parameters from one loop update to the next.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DriveSegment {
    /// The tick at which the first sample with these parameters is written, s (>= 0).
    pub start_s: f64,
    /// DDS phase of that first sample, rad.
    pub phase_rad: f64,
    /// DDS phase step per tick, rad: `2 pi f / f_s`. Range [0, pi) (below Nyquist).
    pub step_rad: f64,
    /// Sine amplitude at the DAC output, V (>= 0; `amp` codes times one LSB).
    pub amplitude_v: f64,
    /// Centre of the sine at the DAC output, V (the mid code times one LSB).
    pub offset_v: f64,
}

impl DriveSegment {
    /// A segment from DAC codes: amplitude `amplitude_codes` and centre `mid_code` (fractional
    /// codes allowed), at the DAC's LSB.
    pub fn from_codes(
        start_s: f64,
        phase_rad: f64,
        step_rad: f64,
        amplitude_codes: f64,
        mid_code: f64,
        dac: &DacParams,
    ) -> Self {
        Self {
            start_s,
            phase_rad,
            step_rad,
            amplitude_v: dac.volts(amplitude_codes),
            offset_v: dac.volts(mid_code),
        }
    }

    /// The DDS frequency `step f_s / (2 pi)`, Hz.
    pub fn freq_hz(&self, dac: &DacParams) -> f64 {
        self.step_rad * dac.tick_hz / TAU
    }

    /// Checks the fields (finite, amplitude >= 0, step in [0, pi), start >= 0).
    pub fn validate(&self) -> Result<(), DriveError> {
        let finite = [
            self.start_s,
            self.phase_rad,
            self.step_rad,
            self.amplitude_v,
            self.offset_v,
        ]
        .iter()
        .all(|x| x.is_finite());
        if !finite {
            return Err(DriveError::Invalid("a drive segment field is not finite"));
        }
        if self.start_s < 0.0 {
            return Err(DriveError::Invalid("a drive segment starts before t = 0"));
        }
        if !(0.0..PI).contains(&self.step_rad) {
            return Err(DriveError::Invalid("step_rad must be in [0, pi)"));
        }
        if self.amplitude_v < 0.0 {
            return Err(DriveError::Invalid("amplitude_v must be >= 0"));
        }
        Ok(())
    }
}

/// Why a drive segment was refused.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum DriveError {
    /// The gyro's dither is the prescribed sine: it takes no drive.
    NotDriven,
    /// A field is out of range; the text says which.
    Invalid(&'static str),
    /// The segment starts before the time up to which the drive is already known (the past,
    /// or a future the gyro may already have planned with).
    InThePast {
        /// The segment's start, s.
        start_s: f64,
        /// The drive was known until then, s.
        known_until_s: f64,
    },
}

impl core::fmt::Display for DriveError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::NotDriven => write!(f, "the dither is the prescribed sine: no drive input"),
            Self::Invalid(what) => write!(f, "invalid drive segment: {what}"),
            Self::InThePast {
                start_s,
                known_until_s,
            } => write!(
                f,
                "drive segment at {start_s} s starts before the drive known until {known_until_s} s"
            ),
        }
    }
}

impl std::error::Error for DriveError {}

/// The time asked for lies beyond the known drive.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DriveExhausted {
    /// The time asked for, s.
    pub asked_s: f64,
    /// The drive is known until then, s.
    pub known_until_s: f64,
}

impl core::fmt::Display for DriveExhausted {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(
            f,
            "asked for t = {} s but the drive is known only until {} s: push drive segments \
             ahead (keep a lead of two dither periods)",
            self.asked_s, self.known_until_s
        )
    }
}

impl std::error::Error for DriveExhausted {}

/// Whatever takes drive segments: the gyro, the board around it.
pub trait DriveSink {
    /// Appends a segment; it starts at or after [`Self::drive_known_until_s`], and the
    /// previous segment holds until its start.
    fn push_drive(&mut self, segment: DriveSegment) -> Result<(), DriveError>;
    /// States that the last segment holds at least until `t_s` (a later time than known so
    /// far; an earlier one is ignored).
    fn extend_drive_until(&mut self, t_s: f64) -> Result<(), DriveError>;
    /// The time up to which the drive is known, s.
    fn drive_known_until_s(&self) -> f64;
}
