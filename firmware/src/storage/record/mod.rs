//! The calibration record: fixed 144-byte little-endian layout (96 bytes in version 3, 80 in
//! version 2 and 64 in version 1, all still read), CRC-32, commit marker and the
//! plausibility checks applied both before storing and after loading.
//!
//! # Frame (every format version, present and future)
//! What the scanner relies on to find, check and skip a record without knowing its version:
//!
//! | word | content |
//! |---|---|
//! | 0 | magic `0xCA1B` (u16), format version (u8), length in 32-bit words (u8) |
//! | 1 | sequence number (u32): +1 per store, over both sectors |
//! | 2 .. n-3 | the version's body |
//! | n-2 | CRC-32/ISO-HDLC of bytes 0 .. 4(n-2) (header and body) |
//! | n-1 | commit marker [`COMMIT_MARKER`], programmed last |
//!
//! A frame starts on a [`ALIGN_BYTES`] boundary of its sector and is a multiple of
//! [`ALIGN_BYTES`] long (at most [`MAX_FRAME_BYTES`]). A frame is *valid* when the magic,
//! the length, the CRC and the marker all check; a valid frame of an unknown version is skipped
//! by its length and left alone.
//!
//! # Format version 4 ([`RECORD_BYTES`] = 144 bytes, 36 words), written by this firmware
//!
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 2 | magic `0xCA1B` |
//! | 2 | 1 | format version = 4 |
//! | 3 | 1 | length = 36 words |
//! | 4 | 4 | sequence number (u32) |
//! | 8 | 4 | gyro serial number (u32) |
//! | 12 | 4 | boot count at the time of storing (u32, supplied by the caller) |
//! | 16 | 4 | a, Q15.16 rad/s (i32) |
//! | 20 | 4 | b, Q15.16 rad/s (i32) |
//! | 24 | 1 | compensation enabled: 0 or 1 |
//! | 25 | 1 | flags: bit 0 fit summary present, bit 1 reset-to-defaults record, bit 2 dither setpoints present, bit 3 stripping coefficients present, bit 4 the second stripping tap is the quadrature tap, bit 5 thermal model present; others 0 |
//! | 26 | 2 | fit: runs pooled (u16, saturated) |
//! | 28 | 4 | fit: cycles (u32, saturated) |
//! | 32 | 4 | fit: standard error of a, rad/s (f32) |
//! | 36 | 4 | fit: standard error of b, rad/s (f32) |
//! | 40 | 4 | fit: residual standard deviation of the per-cycle output, rad (f32) |
//! | 44 | 4 | fit: variance reduction (f32) |
//! | 48 | 4 | fit: condition number (f32) |
//! | 52 | 4 | fit: mean input rate, rad/s of beat phase (f32) |
//! | 56 | 4 | dither: amplitude setpoint, arcsec peak of body angle (f32) |
//! | 60 | 4 | dither: random-noise depth, percent of the setpoint (f32) |
//! | 64 | 1 | dither: drive enabled at power-up, 0 or 1 |
//! | 65 | 7 | reserved, 0 |
//! | 72 | 4 | stripping: K, Q8.24 fringes per pick-off code (i32) |
//! | 76 | 4 | stripping: K_q, the tap on the modelled dither in quadrature (flag bit 4; without it, an older firmware's tap on the previous latch's code, not loaded), Q8.24 fringes per code (i32) |
//! | 80 | 8 | reserved, 0 |
//! | 88 | 1 | thermal model applied (`thermal on`), 0 or 1 |
//! | 89 | 3 | reserved, 0 |
//! | 92 | 44 | thermal model: 11 f32 in the protocol's order `t_ref t_min t_max b0 b1 b2 b3 b_rate s0 s1 s2` (°C; deg/h per °C^k, deg/h per °C/min; ppm per °C^k: `thermal::model`) |
//! | 136 | 4 | CRC-32 of bytes 0..136 |
//! | 140 | 4 | commit marker |
//!
//! The thermal model is stored as the f32 it is applied in (it is evaluated in f32 on the
//! board); without one (flag bit 5 clear) bytes 88..136 are zero.
//!
//! # Format version 3 (96 bytes, 24 words), still read
//!
//! Bytes 0..88 as in version 4 (flag bit 5 unknown, so never set), then the CRC-32 of bytes
//! 0..88 at 88 and the commit marker at 92. It loads with no thermal model (`thermal: None`: no
//! correction until one is set); the next store writes version 4.
//!
//! # Format version 2 (80 bytes, 20 words), still read
//!
//! Bytes 0..72 as in version 4 (flag bits 3-5 unknown, so never set), then the CRC-32 of bytes
//! 0..72 at 72 and the commit marker at 76. It loads with no stripping coefficients (`strip:
//! None`: the profile's nominal K applies and the fit learns it); the next store writes
//! version 3. The stripping coefficients are fixed point, as a and b: Q8.24 spans +-128
//! fringes per code (the F405's pick-off with the docs/physics.md gyro: 0.214) at 6e-8, 3e-7
//! of K, far below the fit's own 2e-5.
//!
//! # Format version 1 (64 bytes, 16 words), still read
//!
//! Bytes 0..56 as in version 2 (flag bit 2 unknown, so never set), then the CRC-32 of bytes
//! 0..56 at 56 and the commit marker at 60. A version-1 record loads with no dither setpoints
//! (`dither: None`: the board's defaults apply); the next store writes version 2. A firmware
//! that only knows version 1 skips version-2 frames by their length and keeps loading its own
//! newest record (the frame rule above), so a downgrade loses the newer records' contents but
//! never loads garbage.
//!
//! The fit's statistics are stored as f32: they are reports for the host, never fed back into
//! the signal chain, and 24 bits of mantissa are far more than their own uncertainty. The fit's
//! a and b are not repeated: the record holds them as the applied Q15.16 coefficients, and
//! Omega_L and eps follow from those ([`CalibrationRecord::lock_in_rad_per_s`],
//! [`CalibrationRecord::eps_rad`]). Without a fit (coefficients set by hand, or a reset) the fit
//! bytes are zero and flag bit 0 is clear; without dither setpoints (never set, or a reset) the
//! dither bytes are zero and flag bit 2 is clear.
//!
//! Size (over 600 lines): the offsets of every format version and their decoders stay together, so
//! each offset is read against its neighbours; the field types are in `fields.rs`.

mod fields;

use super::crc::crc32;
use crate::signal::compensation::{Coefficients, CompensationSettings};
use crate::thermal::model::ThermalModel;
pub use fields::{
    DitherSetpoints, FitSummary, StripCoefficients, ThermalCalibration, MAX_DITHER_AMPLITUDE_ARCSEC,
};

/// First half-word of every frame.
pub const MAGIC: u16 = 0xCA1B;
/// The format version this firmware writes.
pub const FORMAT_VERSION: u8 = 4;
/// Length of a record of [`FORMAT_VERSION`].
pub const RECORD_BYTES: usize = 144;
/// The previous format version, still read.
pub const V3_FORMAT_VERSION: u8 = 3;
/// Length of a version-3 record.
pub const V3_RECORD_BYTES: usize = 96;
/// An older format version, still read.
pub const V2_FORMAT_VERSION: u8 = 2;
/// Length of a version-2 record.
pub const V2_RECORD_BYTES: usize = 80;
/// The older format version this firmware still reads.
pub const V1_FORMAT_VERSION: u8 = 1;
/// Length of a version-1 record.
pub const V1_RECORD_BYTES: usize = 64;

/// The length of a record of `version`, if this firmware can read that version.
pub const fn readable_length(version: u8) -> Option<usize> {
    match version {
        V1_FORMAT_VERSION => Some(V1_RECORD_BYTES),
        V2_FORMAT_VERSION => Some(V2_RECORD_BYTES),
        V3_FORMAT_VERSION => Some(V3_RECORD_BYTES),
        FORMAT_VERSION => Some(RECORD_BYTES),
        _ => None,
    }
}
/// Frames start on, and are a whole number of, these units.
pub const ALIGN_BYTES: usize = 16;
/// Longest frame the length byte can describe in whole [`ALIGN_BYTES`] units: 252 words.
pub const MAX_FRAME_BYTES: usize = 252 * 4;
/// The last word of a frame, programmed only after the rest has been read back and verified.
/// A power cut leaves it erased or partially programmed (a subset of its bit clears), which
/// never equals this value.
pub const COMMIT_MARKER: u32 = 0xA5C3_3C5A;

/// Byte offsets of the version-4 fields (see the module table); the older versions share
/// their prefixes.
pub mod offset {
    /// Magic [`super::MAGIC`], u16.
    pub const MAGIC: usize = 0;
    /// Format version, u8.
    pub const VERSION: usize = 2;
    /// Frame length in 32-bit words, u8.
    pub const LENGTH_WORDS: usize = 3;
    /// Sequence number, u32.
    pub const SEQUENCE: usize = 4;
    /// Gyro serial number, u32.
    pub const SERIAL_NUMBER: usize = 8;
    /// Boot count at the time of storing, u32.
    pub const BOOT_COUNT: usize = 12;
    /// Coefficient a, Q15.16 rad/s, i32.
    pub const A_Q16: usize = 16;
    /// Coefficient b, Q15.16 rad/s, i32.
    pub const B_Q16: usize = 20;
    /// Compensation enabled, u8: 0 or 1.
    pub const ENABLED: usize = 24;
    /// Flags, u8: bit 0 fit present, bit 1 reset record.
    pub const FLAGS: usize = 25;
    /// Fit: runs pooled, u16.
    pub const FIT_RUNS: usize = 26;
    /// Fit: dither cycles, u32.
    pub const FIT_CYCLES: usize = 28;
    /// Fit: standard error of a, rad/s, f32.
    pub const FIT_A_STD: usize = 32;
    /// Fit: standard error of b, rad/s, f32.
    pub const FIT_B_STD: usize = 36;
    /// Fit: residual standard deviation, rad, f32.
    pub const FIT_RESIDUAL_STD: usize = 40;
    /// Fit: variance reduction, f32.
    pub const FIT_VARIANCE_REDUCTION: usize = 44;
    /// Fit: condition number, f32.
    pub const FIT_CONDITION_NUMBER: usize = 48;
    /// Fit: mean input rate, rad/s of beat phase, f32.
    pub const FIT_MEAN_RATE: usize = 52;
    /// Dither amplitude setpoint, arcsec peak of body angle, f32.
    pub const DITHER_AMPLITUDE: usize = 56;
    /// Random-noise dither depth, percent of the setpoint, f32.
    pub const DITHER_NOISE: usize = 60;
    /// Dither drive enabled at power-up, u8: 0 or 1.
    pub const DITHER_ENABLED: usize = 64;
    /// Reserved bytes, 0, up to [`STRIP_K`].
    pub const RESERVED: usize = 65;
    /// Stripping coefficient K, Q8.24 fringes per pick-off code, i32.
    pub const STRIP_K: usize = 72;
    /// Stripping coefficient K_q (the quadrature tap), Q8.24, i32.
    pub const STRIP_K_QUADRATURE: usize = 76;
    /// Reserved bytes after the stripping coefficients, 0, up to [`THERMAL_ENABLED`].
    pub const RESERVED_2: usize = 80;
    /// Thermal model applied, u8: 0 or 1.
    pub const THERMAL_ENABLED: usize = 88;
    /// Reserved bytes after it, 0, up to [`THERMAL_MODEL`].
    pub const RESERVED_3: usize = 89;
    /// The thermal model, 11 f32 in `ThermalModel::NAMES`' order.
    pub const THERMAL_MODEL: usize = 92;
    /// CRC of `[0, CRC)`; in any frame of length n bytes it sits at n - 8.
    pub const CRC: usize = 136;
    /// Commit marker; in any frame of length n bytes it sits at n - 4.
    pub const COMMIT: usize = 140;
    /// Version 3: CRC of `[0, V3_CRC)`.
    pub const V3_CRC: usize = 88;
    /// Version 2: CRC of `[0, V2_CRC)`.
    pub const V2_CRC: usize = 72;
    /// Version 1: CRC of `[0, V1_CRC)`.
    pub const V1_CRC: usize = 56;
}

const FLAG_FIT_PRESENT: u8 = 1 << 0;
const FLAG_RESET: u8 = 1 << 1;
const FLAG_DITHER_PRESENT: u8 = 1 << 2;
const FLAG_STRIP_PRESENT: u8 = 1 << 3;
/// The second stripping tap is the quadrature tap (`signal::output::strip`). A version-3 record
/// without it holds an older firmware's tap on the previous latch's pick-off code, which means
/// nothing to the quadrature fit: it loads as 0 (K is kept), and the fit learns the tap anew.
const FLAG_STRIP_QUADRATURE: u8 = 1 << 4;
const FLAG_THERMAL_PRESENT: u8 = 1 << 5;
const V1_KNOWN_FLAGS: u8 = FLAG_FIT_PRESENT | FLAG_RESET;
const V2_KNOWN_FLAGS: u8 = V1_KNOWN_FLAGS | FLAG_DITHER_PRESENT;
const V3_KNOWN_FLAGS: u8 = V2_KNOWN_FLAGS | FLAG_STRIP_PRESENT | FLAG_STRIP_QUADRATURE;
const KNOWN_FLAGS: u8 = V3_KNOWN_FLAGS | FLAG_THERMAL_PRESENT;

/// Why bytes are not a usable record, or a record may not be stored.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum RecordError {
    /// No magic, or a length that is not a whole frame.
    NotAFrame,
    /// The CRC does not match the header and body.
    Crc,
    /// The commit marker is not (fully) programmed: a write that did not finish.
    NotCommitted,
    /// A valid frame of a format version this firmware cannot read.
    UnknownVersion {
        /// The frame's format version.
        version: u8,
    },
    /// The enabled byte is neither 0 nor 1, or unknown flag bits are set.
    BadFlags,
    /// A fit statistic is NaN or outside its possible range, or fit bytes without a fit.
    ImplausibleFit,
    /// A reset record that carries anything but the default settings.
    ImplausibleReset,
    /// Dither setpoints that are not finite or outside their ranges, bytes without setpoints,
    /// or reserved bytes that are not 0.
    ImplausibleDither,
    /// Stripping coefficients with a zero K, bytes without coefficients, or reserved bytes
    /// after them that are not 0.
    ImplausibleStrip,
    /// A thermal model that fails its checks (`ThermalModel::check`), an enabled byte that is
    /// neither 0 nor 1, bytes without a model, or reserved bytes that are not 0.
    ImplausibleThermal,
}

/// What is stored: the compensation settings and where they came from.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CalibrationRecord {
    /// The gyro this calibration belongs to.
    pub serial_number: u32,
    /// The board's boot count when the record was stored (the caller's counter; the store does
    /// not keep one, since writing at every boot would wear the flash and stall the CPU).
    pub boot_count: u32,
    /// The coefficients and the on/off switch, as applied.
    pub settings: CompensationSettings,
    /// The fit that produced the coefficients; `None` when they were set by hand.
    pub fit: Option<FitSummary>,
    /// Written by `reset_to_defaults`: the settings are the defaults, on purpose.
    pub reset_to_defaults: bool,
    /// The dither drive's setpoints; `None` when never set (or a version-1 record): the board's
    /// defaults apply.
    pub dither: Option<DitherSetpoints>,
    /// The dither stripping's coefficients; `None` when never stored (or an older record): the
    /// profile's nominal K applies until the fit learns it.
    pub strip: Option<StripCoefficients>,
    /// The thermal model and its switch; `None` when never stored (or an older record): no
    /// thermal correction.
    pub thermal: Option<ThermalCalibration>,
}

impl CalibrationRecord {
    /// What runs when nothing valid is stored: compensation off, a = b = 0, serial 0 (unknown).
    pub const DEFAULTS: Self = Self {
        serial_number: 0,
        boot_count: 0,
        settings: CompensationSettings {
            coefficients: Coefficients { a_q16: 0, b_q16: 0 },
            enabled: false,
        },
        fit: None,
        reset_to_defaults: false,
        dither: None,
        strip: None,
        thermal: None,
    };

    /// The record `reset_to_defaults` writes.
    pub const fn reset(serial_number: u32, boot_count: u32) -> Self {
        Self {
            serial_number,
            boot_count,
            reset_to_defaults: true,
            ..Self::DEFAULTS
        }
    }

    /// Omega_L = hypot(a, b) of the stored coefficients, rad/s.
    pub fn lock_in_rad_per_s(&self) -> f32 {
        let c = self.settings.coefficients;
        libm::hypotf(c.a_rad_per_s(), c.b_rad_per_s())
    }

    /// eps = atan2(b, a) - pi/4 of the stored coefficients, rad.
    pub fn eps_rad(&self) -> f32 {
        let c = self.settings.coefficients;
        libm::atan2f(c.b_rad_per_s(), c.a_rad_per_s()) - core::f32::consts::FRAC_PI_4
    }

    /// The plausibility checks (the CRC and the frame are checked by [`decode`]).
    pub fn check(&self) -> Result<(), RecordError> {
        if let Some(fit) = &self.fit {
            fit.check()?;
        }
        if let Some(dither) = &self.dither {
            dither.check()?;
        }
        if let Some(strip) = &self.strip {
            strip.check()?;
        }
        if let Some(thermal) = &self.thermal {
            thermal.check()?;
        }
        let is_default = self.settings == Self::DEFAULTS.settings
            && self.fit.is_none()
            && self.dither.is_none()
            && self.strip.is_none()
            && self.thermal.is_none();
        if self.reset_to_defaults && !is_default {
            return Err(RecordError::ImplausibleReset);
        }
        Ok(())
    }
}

/// The header of any frame, as far as the first [`ALIGN_BYTES`] tell (CRC not yet checked).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FrameHeader {
    /// Format version (any; only [`FORMAT_VERSION`] can be decoded).
    pub version: u8,
    /// Frame length, bytes: a whole number of [`ALIGN_BYTES`] units, at most [`MAX_FRAME_BYTES`].
    pub length_bytes: usize,
    /// Sequence number.
    pub sequence: u32,
}

/// Reads a frame header: the magic and a length that is a whole number of units.
pub fn parse_header(unit: &[u8; ALIGN_BYTES]) -> Option<FrameHeader> {
    let length_bytes = usize::from(byte_at(unit, offset::LENGTH_WORDS)).saturating_mul(4);
    let whole = length_bytes >= ALIGN_BYTES && length_bytes.is_multiple_of(ALIGN_BYTES);
    (get_u16(unit, offset::MAGIC) == MAGIC && whole).then(|| FrameHeader {
        version: byte_at(unit, offset::VERSION),
        length_bytes,
        sequence: get_u32(unit, offset::SEQUENCE),
    })
}

/// The version-4 bytes of `record` with sequence number `sequence`, CRC and commit marker.
/// Does not check the record (the store does, before it writes).
pub fn encode(record: &CalibrationRecord, sequence: u32) -> [u8; RECORD_BYTES] {
    let mut bytes = [0u8; RECORD_BYTES];
    put(&mut bytes, offset::MAGIC, &MAGIC.to_le_bytes());
    bytes[offset::VERSION] = FORMAT_VERSION;
    bytes[offset::LENGTH_WORDS] = (RECORD_BYTES / 4) as u8;
    put(&mut bytes, offset::SEQUENCE, &sequence.to_le_bytes());
    put(
        &mut bytes,
        offset::SERIAL_NUMBER,
        &record.serial_number.to_le_bytes(),
    );
    put(
        &mut bytes,
        offset::BOOT_COUNT,
        &record.boot_count.to_le_bytes(),
    );
    let coefficients = record.settings.coefficients;
    put(&mut bytes, offset::A_Q16, &coefficients.a_q16.to_le_bytes());
    put(&mut bytes, offset::B_Q16, &coefficients.b_q16.to_le_bytes());
    bytes[offset::ENABLED] = record.settings.enabled as u8;
    let mut flags = 0;
    if let Some(fit) = &record.fit {
        flags |= FLAG_FIT_PRESENT;
        encode_fit(&mut bytes, fit);
    }
    if record.reset_to_defaults {
        flags |= FLAG_RESET;
    }
    if let Some(dither) = &record.dither {
        flags |= FLAG_DITHER_PRESENT;
        put(
            &mut bytes,
            offset::DITHER_AMPLITUDE,
            &dither.amplitude_arcsec.to_le_bytes(),
        );
        put(
            &mut bytes,
            offset::DITHER_NOISE,
            &dither.noise_percent.to_le_bytes(),
        );
        bytes[offset::DITHER_ENABLED] = dither.enabled as u8;
    }
    if let Some(strip) = &record.strip {
        flags |= FLAG_STRIP_PRESENT | FLAG_STRIP_QUADRATURE;
        put(&mut bytes, offset::STRIP_K, &strip.k_q24.to_le_bytes());
        put(
            &mut bytes,
            offset::STRIP_K_QUADRATURE,
            &strip.k_quadrature_q24.to_le_bytes(),
        );
    }
    if let Some(thermal) = &record.thermal {
        flags |= FLAG_THERMAL_PRESENT;
        bytes[offset::THERMAL_ENABLED] = thermal.enabled as u8;
        for (k, value) in thermal.model.values().iter().enumerate() {
            put(
                &mut bytes,
                offset::THERMAL_MODEL.saturating_add(k.saturating_mul(4)),
                &value.to_le_bytes(),
            );
        }
    }
    bytes[offset::FLAGS] = flags;
    seal(&mut bytes);
    bytes
}

/// Writes the CRC of `frame[..len - 8]` at `len - 8` and the commit marker at `len - 4`:
/// the closing words of any frame.
pub fn seal(frame: &mut [u8]) {
    let Some(crc_at) = frame.len().checked_sub(8) else {
        return;
    };
    let crc = crc32(frame.get(..crc_at).unwrap_or_default());
    put(frame, crc_at, &crc.to_le_bytes());
    put(
        frame,
        crc_at.saturating_add(4),
        &COMMIT_MARKER.to_le_bytes(),
    );
}

fn encode_fit(bytes: &mut [u8], fit: &FitSummary) {
    put(bytes, offset::FIT_RUNS, &fit.runs.to_le_bytes());
    put(bytes, offset::FIT_CYCLES, &fit.cycles.to_le_bytes());
    let floats = [
        (offset::FIT_A_STD, fit.a_std_rad_per_s),
        (offset::FIT_B_STD, fit.b_std_rad_per_s),
        (offset::FIT_RESIDUAL_STD, fit.residual_std_rad),
        (offset::FIT_VARIANCE_REDUCTION, fit.variance_reduction),
        (offset::FIT_CONDITION_NUMBER, fit.condition_number),
        (offset::FIT_MEAN_RATE, fit.mean_rate_rad_per_s),
    ];
    for (at, value) in floats {
        put(bytes, at, &value.to_le_bytes());
    }
}

/// Checks a frame of a readable version (1 to 4) completely (magic, version, length, CRC,
/// marker, plausibility) and returns its sequence number and record. `bytes` is the whole
/// frame: [`V1_RECORD_BYTES`], [`V2_RECORD_BYTES`], [`V3_RECORD_BYTES`] or [`RECORD_BYTES`]
/// long.
pub fn decode(bytes: &[u8]) -> Result<(u32, CalibrationRecord), RecordError> {
    let header: &[u8; ALIGN_BYTES] = bytes
        .get(..ALIGN_BYTES)
        .and_then(|h| h.try_into().ok())
        .ok_or(RecordError::NotAFrame)?;
    let header = parse_header(header).ok_or(RecordError::NotAFrame)?;
    if header.length_bytes != bytes.len() {
        return Err(RecordError::NotAFrame);
    }
    let (body, closing) = bytes
        .split_last_chunk::<8>()
        .ok_or(RecordError::NotAFrame)?;
    if get_u32(closing, 4) != COMMIT_MARKER {
        return Err(RecordError::NotCommitted);
    }
    if get_u32(closing, 0) != crc32(body) {
        return Err(RecordError::Crc);
    }
    if readable_length(header.version) != Some(bytes.len()) {
        return Err(RecordError::UnknownVersion {
            version: header.version,
        });
    }
    let record = decode_body(bytes, header.version)?;
    record.check()?;
    Ok((header.sequence, record))
}

fn decode_body(bytes: &[u8], version: u8) -> Result<CalibrationRecord, RecordError> {
    let flags = byte_at(bytes, offset::FLAGS);
    let enabled = byte_at(bytes, offset::ENABLED);
    let known = match version {
        V1_FORMAT_VERSION => V1_KNOWN_FLAGS,
        V2_FORMAT_VERSION => V2_KNOWN_FLAGS,
        V3_FORMAT_VERSION => V3_KNOWN_FLAGS,
        _ => KNOWN_FLAGS,
    };
    if flags & !known != 0 || enabled > 1 {
        return Err(RecordError::BadFlags);
    }
    let fit = if flags & FLAG_FIT_PRESENT != 0 {
        Some(decode_fit(bytes))
    } else if !all_zero(bytes, offset::FIT_RUNS..offset::V1_CRC) {
        return Err(RecordError::ImplausibleFit);
    } else {
        None
    };
    let dither = if version == V1_FORMAT_VERSION {
        None
    } else {
        decode_dither(bytes, flags & FLAG_DITHER_PRESENT != 0)?
    };
    let strip = if version >= V3_FORMAT_VERSION {
        decode_strip(
            bytes,
            flags & FLAG_STRIP_PRESENT != 0,
            flags & FLAG_STRIP_QUADRATURE != 0,
        )?
    } else {
        None
    };
    let thermal = if version == FORMAT_VERSION {
        decode_thermal(bytes, flags & FLAG_THERMAL_PRESENT != 0)?
    } else {
        None
    };
    Ok(CalibrationRecord {
        serial_number: get_u32(bytes, offset::SERIAL_NUMBER),
        boot_count: get_u32(bytes, offset::BOOT_COUNT),
        settings: CompensationSettings {
            coefficients: Coefficients {
                a_q16: get_u32(bytes, offset::A_Q16) as i32,
                b_q16: get_u32(bytes, offset::B_Q16) as i32,
            },
            enabled: enabled == 1,
        },
        fit,
        reset_to_defaults: flags & FLAG_RESET != 0,
        dither,
        strip,
        thermal,
    })
}

/// The version-4 thermal bytes: a model when `present`, else zero; reserved bytes zero. The
/// model's own checks follow in `CalibrationRecord::check`.
fn decode_thermal(bytes: &[u8], present: bool) -> Result<Option<ThermalCalibration>, RecordError> {
    let enabled = byte_at(bytes, offset::THERMAL_ENABLED);
    if !all_zero(bytes, offset::RESERVED_3..offset::THERMAL_MODEL) || enabled > 1 {
        return Err(RecordError::ImplausibleThermal);
    }
    if !present {
        return if all_zero(bytes, offset::THERMAL_ENABLED..offset::CRC) {
            Ok(None)
        } else {
            Err(RecordError::ImplausibleThermal)
        };
    }
    let mut values = [0.0f32; 11];
    for (k, value) in values.iter_mut().enumerate() {
        let at = offset::THERMAL_MODEL.saturating_add(k.saturating_mul(4));
        *value = f32::from_bits(get_u32(bytes, at));
    }
    Ok(Some(ThermalCalibration {
        model: ThermalModel::from_values(values),
        enabled: enabled == 1,
    }))
}

/// The stripping bytes (versions 3 and 4): coefficients when `present`, else zero; reserved
/// bytes zero.
fn decode_strip(
    bytes: &[u8],
    present: bool,
    quadrature: bool,
) -> Result<Option<StripCoefficients>, RecordError> {
    let reserved_clear = all_zero(bytes, offset::RESERVED_2..offset::V3_CRC);
    let strip = StripCoefficients {
        k_q24: get_u32(bytes, offset::STRIP_K) as i32,
        k_quadrature_q24: get_u32(bytes, offset::STRIP_K_QUADRATURE) as i32,
    };
    match (reserved_clear, present, quadrature) {
        (false, _, _) | (true, false, true) => Err(RecordError::ImplausibleStrip),
        (true, true, true) => Ok(Some(strip)),
        // An older firmware's previous-latch tap: K only.
        (true, true, false) => Ok(Some(StripCoefficients {
            k_quadrature_q24: 0,
            ..strip
        })),
        (true, false, false) if strip == StripCoefficients::default() => Ok(None),
        (true, false, false) => Err(RecordError::ImplausibleStrip),
    }
}

/// The dither bytes (versions 2 and 3): setpoints when `present`, else all zero; reserved bytes
/// zero.
fn decode_dither(bytes: &[u8], present: bool) -> Result<Option<DitherSetpoints>, RecordError> {
    let reserved_clear = all_zero(bytes, offset::RESERVED..offset::V2_CRC);
    let enabled = byte_at(bytes, offset::DITHER_ENABLED);
    if !reserved_clear || enabled > 1 {
        return Err(RecordError::ImplausibleDither);
    }
    if !present {
        let clear = all_zero(bytes, offset::DITHER_AMPLITUDE..offset::RESERVED);
        return if clear {
            Ok(None)
        } else {
            Err(RecordError::ImplausibleDither)
        };
    }
    let float = |at| f32::from_bits(get_u32(bytes, at));
    Ok(Some(DitherSetpoints {
        enabled: enabled == 1,
        amplitude_arcsec: float(offset::DITHER_AMPLITUDE),
        noise_percent: float(offset::DITHER_NOISE),
    }))
}

fn decode_fit(bytes: &[u8]) -> FitSummary {
    let float = |at| f32::from_bits(get_u32(bytes, at));
    FitSummary {
        cycles: get_u32(bytes, offset::FIT_CYCLES),
        runs: get_u16(bytes, offset::FIT_RUNS),
        a_std_rad_per_s: float(offset::FIT_A_STD),
        b_std_rad_per_s: float(offset::FIT_B_STD),
        residual_std_rad: float(offset::FIT_RESIDUAL_STD),
        variance_reduction: float(offset::FIT_VARIANCE_REDUCTION),
        condition_number: float(offset::FIT_CONDITION_NUMBER),
        mean_rate_rad_per_s: float(offset::FIT_MEAN_RATE),
    }
}

// The accessors below take offsets of the fixed layout, inside every frame they are used on
// (`decode` checked the frame's length for its version first); an offset outside would read
// as 0 (and fail the checks) or write nothing, never panic.

fn put(bytes: &mut [u8], at: usize, value: &[u8]) {
    if let Some(slot) = bytes.get_mut(at..).and_then(|r| r.get_mut(..value.len())) {
        slot.copy_from_slice(value);
    }
}

fn byte_at(bytes: &[u8], at: usize) -> u8 {
    bytes.get(at).copied().unwrap_or(0)
}

/// Whether `bytes[range]` exists and is all zero.
fn all_zero(bytes: &[u8], range: core::ops::Range<usize>) -> bool {
    bytes.get(range).is_some_and(|r| r.iter().all(|&b| b == 0))
}

fn get_u16(bytes: &[u8], at: usize) -> u16 {
    let word = bytes.get(at..).and_then(|r| r.first_chunk::<2>());
    word.map_or(0, |w| u16::from_le_bytes(*w))
}

/// The little-endian word at `at` (0 when the bytes end before it).
pub fn get_u32(bytes: &[u8], at: usize) -> u32 {
    let word = bytes.get(at..).and_then(|r| r.first_chunk::<4>());
    word.map_or(0, |w| u32::from_le_bytes(*w))
}

#[cfg(test)]
mod tests;
