//! The hardware/logic boundary: plain data that interrupt handlers copy out of the peripherals.
//!
//! Raw codes only (encoder register, 12-bit ADC codes as [`AdcCode`], timer ticks); conversion to physical
//! units happens in the signal chain. `hal-sim` builds exactly these structs from the simulated
//! gyro, so the logic downstream is the same code on the board and on the host.

/// Which way the lock-in-free rate crosses zero at a dither turnaround (docs/physics.md).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum TurnaroundKind {
    /// Rate goes from negative to positive: beat phase at a minimum.
    Plus,
    /// Rate goes from positive to negative: beat phase at a maximum.
    Minus,
}

/// One conversion of the F405's 12-bit ADCs (photodiodes, pick-off): a code in
/// `0..=`[`AdcCode::FULL_SCALE`], by construction. Codes stay codes through the interrupts;
/// the signal chain scales them (the Lissajous fit, the pick-off's arcsec per code).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct AdcCode(u16);

impl AdcCode {
    /// Resolution of the conversion, bits.
    pub const BITS: u32 = 12;
    /// The lowest code (input at or below V_REF-).
    pub const ZERO: Self = Self(0);
    /// The highest code, 2^12 - 1 (input at or above V_REF+ minus one LSB).
    pub const FULL_SCALE: Self = Self((1 << Self::BITS) - 1);
    /// The mid-scale code, 2^11 (input V_REF / 2): the origin of signed code arithmetic.
    pub const MID: Self = Self(1 << (Self::BITS - 1));

    /// The code `code`, or `None` if it is above [`Self::FULL_SCALE`].
    #[inline]
    pub const fn new(code: u16) -> Option<Self> {
        if code <= Self::FULL_SCALE.0 {
            Some(Self(code))
        } else {
            None
        }
    }

    /// The code `code`, clipped to [`Self::FULL_SCALE`] as the converter clips its input.
    #[inline]
    pub const fn saturating(code: u16) -> Self {
        if code <= Self::FULL_SCALE.0 {
            Self(code)
        } else {
            Self::FULL_SCALE
        }
    }

    /// The code in a data register of a right-aligned conversion without offset (ADC_CR2.ALIGN
    /// = 0, ADC_JOFRx = 0; RM0090 13.8: bits 11:0, the bits above read 0): its low 12 bits
    /// (also the lower half of a dual-mode ADC_CDR word).
    #[inline(always)]
    pub const fn from_register(bits: u32) -> Self {
        Self((bits & Self::FULL_SCALE.0 as u32) as u16)
    }

    /// The code, in `0..=4095`.
    #[inline(always)]
    pub const fn to_bits(self) -> u16 {
        self.0
    }

    /// The code as `f32` (exact).
    #[inline(always)]
    pub fn to_f32(self) -> f32 {
        f32::from(self.0)
    }

    /// The code as `f64` (exact).
    #[inline(always)]
    pub fn to_f64(self) -> f64 {
        f64::from(self.0)
    }
}

impl core::ops::Sub for AdcCode {
    type Output = i32;
    /// The signed difference `self - other`, codes (in `-4095..=4095`).
    #[inline(always)]
    fn sub(self, other: Self) -> i32 {
        i32::from(self.0) - i32::from(other.0)
    }
}

/// What the turnaround interrupt latches: counter, both photodiode levels, and the time.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TurnaroundSample {
    /// Which turnaround the latch was scheduled for (beat phase at a minimum or a maximum).
    pub kind: TurnaroundKind,
    /// Raw x4 up/down encoder register (16- or 32-bit timer; wraps).
    pub encoder_count: u32,
    /// Photodiode channel A (~cos psi_H), ADC code.
    pub adc_a_code: AdcCode,
    /// Photodiode channel B (~sin psi_H), ADC code.
    pub adc_b_code: AdcCode,
    /// Capture timer value at the turnaround instant (free-running, wraps).
    pub timestamp_ticks: u32,
    /// The dither drive was locked when the latch fired (the drive tick's last state; on a
    /// board without a drive, or with the prescribed dither of the simulator, always true).
    pub drive_locked: bool,
}

/// What the output latch takes at the end of an output period (the sync input's edge, or the
/// board's internal output timer): the registers of a turnaround latch plus the dither
/// pick-off, converted at the same instant (docs/physics.md section 12).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct OutputSample {
    /// Raw x4 up/down encoder register (wraps).
    pub encoder_count: u32,
    /// Photodiode channel A (~cos psi_H), ADC code.
    pub adc_a_code: AdcCode,
    /// Photodiode channel B (~sin psi_H), ADC code.
    pub adc_b_code: AdcCode,
    /// The dither pick-off, ADC code, converted at the latch (checked against the model
    /// of the pick-off stream, `signal::output::dither_model`, which gives the dither angle at
    /// `timestamp_ticks`).
    pub pickoff_code: AdcCode,
    /// Capture timer value at the latch (free-running, wraps; extended to 64 bits downstream).
    pub timestamp_ticks: u32,
    /// The dither drive was locked and its supervisor saw no fault (as in
    /// [`TurnaroundSample::drive_locked`]).
    pub drive_locked: bool,
}

#[cfg(test)]
mod tests {
    use super::AdcCode;

    #[test]
    fn adc_code_is_twelve_bits() {
        assert_eq!(AdcCode::FULL_SCALE.to_bits(), 4095);
        assert_eq!(AdcCode::MID.to_bits(), 2048);
        assert_eq!(AdcCode::new(4095), Some(AdcCode::FULL_SCALE));
        assert_eq!(AdcCode::new(4096), None);
        assert_eq!(AdcCode::saturating(u16::MAX), AdcCode::FULL_SCALE);
        assert_eq!(AdcCode::saturating(7).to_bits(), 7);
        // A dual-mode ADC_CDR word: ADC2's code in the upper half, ADC1's in the lower.
        let cdr = (3000u32 << 16) | 1234;
        assert_eq!(AdcCode::from_register(cdr).to_bits(), 1234);
        assert_eq!(AdcCode::from_register(cdr >> 16).to_bits(), 3000);
        assert_eq!(AdcCode::ZERO - AdcCode::FULL_SCALE, -4095);
        assert_eq!(AdcCode::FULL_SCALE.to_f32(), 4095.0);
    }
}
