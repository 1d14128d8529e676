//! The hardware/logic boundary: plain data that interrupt handlers copy out of the peripherals.
//!
//! Raw codes only (encoder register, 12-bit ADC codes, timer ticks); conversion to physical
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

/// Full-scale code of the 12-bit photodiode ADC.
pub const ADC_FULL_SCALE_CODE: u16 = 4095;

/// What the turnaround interrupt latches: counter, both photodiode levels, and the time.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TurnaroundSample {
    /// Which turnaround the latch was scheduled for (beat phase at a minimum or a maximum).
    pub kind: TurnaroundKind,
    /// Raw x4 up/down encoder register (16- or 32-bit timer; wraps).
    pub encoder_count: u32,
    /// Photodiode channel A (~cos psi_H), 12-bit ADC code.
    pub adc_a_code: u16,
    /// Photodiode channel B (~sin psi_H), 12-bit ADC code.
    pub adc_b_code: u16,
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
    /// Photodiode channel A (~cos psi_H), 12-bit ADC code.
    pub adc_a_code: u16,
    /// Photodiode channel B (~sin psi_H), 12-bit ADC code.
    pub adc_b_code: u16,
    /// The dither pick-off, 12-bit ADC code, converted at the latch (checked against the model
    /// of the pick-off stream, `signal::output::dither_model`, which gives the dither angle at
    /// `timestamp_ticks`).
    pub pickoff_code: u16,
    /// Capture timer value at the latch (free-running, wraps; extended to 64 bits downstream).
    pub timestamp_ticks: u32,
    /// The dither drive was locked and its supervisor saw no fault (as in
    /// [`TurnaroundSample::drive_locked`]).
    pub drive_locked: bool,
}
