//! Stage 6b, the fixed-rate output: one [`OutputRecord`] per output period, ended by the sync
//! input's edge (a navigation computer's sample instant) or the board's own output timer.
//!
//! A record carries the stripped, compensated angle increment since the previous latch (the
//! navigation computer's input), the integrated angle, the rate over the period, a status word
//! and a 64-bit sequence number; the wire frame adds a CRC (`protocol::output_frame`).
//!
//! # Formats
//!
//! - Angles are fringes in Q16 (LSB 2^-16 fringe = 2.85e-5 arcsec at the nominal 1.8655
//!   arcsec per fringe): the increment in an `i32` (+-32768 fringes, 17 deg: 1700 deg/s at a
//!   100 Hz sync), the integrated angle in an `i64` (2^47 fringes: never wraps in the field).
//!   The integrated angle is kept exactly (Q32 in an `i128`) and each increment is the
//!   difference of two rounded values, so the increments sum to the integrated angle without
//!   drift.
//! - Time is the capture timer extended to 64 bits (84 MHz: no wrap in 6900 years); an output
//!   period must not exceed one wrap of the 32-bit register (51 s), far beyond the slowest sync.
//! - The rate is `f32` deg/h over the period, with the configured scale factor.
//!
//! # Validity: never a silent wrong angle
//!
//! A period with a counter glitch, a lost photodiode signal, a pick-off at a rail or failing the
//! innovation gate (`strip`), an unlocked
//! or faulted dither drive, or no previous latch (start, or a resynchronisation after a stall)
//! is invalid: its increment is 0, the integrated angle holds, and [`OutputStatus::VALID`] is
//! clear. The angle of that period is lost, and says so; it is never replaced by a guess.

use super::dither_model::DitherModelConfig;
use super::strip::StripConfig;
use crate::thermal::state::{ThermalInput, NO_VALUE};
use crate::units::{PhaseDelta, TotalPhase};

/// The output stage's settings (immutable).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OutputConfig {
    /// The model of the pick-off stream (the dither at a latch).
    pub model: DitherModelConfig,
    /// Dither stripping.
    pub strip: StripConfig,
    /// Capture-timer frequency, Hz.
    pub timer_hz: u32,
    /// Scale factor, arcsec per fringe (the rate in deg/h).
    pub scale_factor_arcsec: f32,
}

/// The status word of a record (bits).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct OutputStatus(pub u16);

crate::flags::flag_set_ops!(OutputStatus);

impl OutputStatus {
    /// The increment is good: none of the fault bits, a locked drive, a previous latch.
    pub const VALID: Self = Self(1 << 0);
    /// The dither drive was locked (and its supervisor saw no fault) at the latch.
    pub const DITHER_LOCKED: Self = Self(1 << 1);
    /// The lock-in compensation is on.
    pub const COMPENSATION_ON: Self = Self(1 << 2);
    /// The eps tracker is running (set by the command service).
    pub const TRACKING: Self = Self(1 << 3);
    /// The stripping coefficient K has converged.
    pub const K_CONVERGED: Self = Self(1 << 4);
    /// A counter or fringe-phase glitch in the period.
    pub const COUNTER_GLITCH: Self = Self(1 << 5);
    /// The photodiode signal was lost in the period.
    pub const SIGNAL_LOST: Self = Self(1 << 6);
    /// The pick-off read at a rail of its converter at the latch, or its increment disagreed
    /// with the count's (the innovation gate, `strip`): it did not report the dither angle.
    pub const PICKOFF_FAULT: Self = Self(1 << 7);
    /// No previous latch to difference against (start, resynchronisation).
    pub const RESTART: Self = Self(1 << 8);
    /// The board's timing watch had a fault raised at the latch (a periodic event stopped or
    /// off its rate, or the clock lost: `board_timing::monitor`).
    pub const TIMING_FAULT: Self = Self(1 << 9);
    /// The model of the pick-off stream was not valid at the latch (start, a gap in the
    /// stream, a re-seed): the dither angle there is not known to the output's precision.
    pub const NO_DITHER_MODEL: Self = Self(1 << 10);
    /// The gyro block's temperature sensor has a fault (`thermal::sensor`): no temperature, no
    /// thermal correction. The increment stays valid (uncorrected).
    pub const THERMAL_SENSOR_FAULT: Self = Self(1 << 11);
    /// The thermal model corrected the record's increment (bias and scale factor at the
    /// sensor's temperature and rate, `thermal::model`); clear: uncorrected.
    pub const THERMAL_CORRECTED: Self = Self(1 << 12);

    /// Every bit with its name, in bit order: the output frame's status table
    /// (docs/protocol.md, checked against this list by `hal-sim/tests/protocol_doc.rs`).
    pub const NAMED: [(&'static str, Self); 13] = [
        ("VALID", Self::VALID),
        ("DITHER_LOCKED", Self::DITHER_LOCKED),
        ("COMPENSATION_ON", Self::COMPENSATION_ON),
        ("TRACKING", Self::TRACKING),
        ("K_CONVERGED", Self::K_CONVERGED),
        ("COUNTER_GLITCH", Self::COUNTER_GLITCH),
        ("SIGNAL_LOST", Self::SIGNAL_LOST),
        ("PICKOFF_FAULT", Self::PICKOFF_FAULT),
        ("RESTART", Self::RESTART),
        ("TIMING_FAULT", Self::TIMING_FAULT),
        ("NO_DITHER_MODEL", Self::NO_DITHER_MODEL),
        ("THERMAL_SENSOR_FAULT", Self::THERMAL_SENSOR_FAULT),
        ("THERMAL_CORRECTED", Self::THERMAL_CORRECTED),
    ];

    /// Bits that make a period invalid.
    pub const FAULTS: Self = Self(
        Self::COUNTER_GLITCH.0
            | Self::SIGNAL_LOST.0
            | Self::PICKOFF_FAULT.0
            | Self::RESTART.0
            | Self::TIMING_FAULT.0
            | Self::NO_DITHER_MODEL.0,
    );
}

/// One output period.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct OutputRecord {
    /// +1 per record made (a gap on the host = records lost on the way).
    pub sequence: u64,
    /// The latch that ended the period, capture-timer ticks since start (64-bit).
    pub time_ticks: u64,
    /// The period's length, ticks (0 for the first record).
    pub period_ticks: u32,
    /// Stripped, compensated angle increment over the period, Q16 fringes (0 when invalid).
    pub delta_angle_q16: i32,
    /// Integrated angle of the valid periods, Q16 fringes.
    pub angle_q16: i64,
    /// Rate over the period, deg/h (0 when invalid).
    pub rate_deg_per_h: f32,
    /// Status bits.
    pub status: OutputStatus,
    /// The gyro block's temperature at the latch, 1/128 °C (the sensor's last result;
    /// `thermal::state::NO_VALUE` without one).
    pub temperature_q7: i16,
    /// The temperature's rate at the latch, 0.01 °C/min (`NO_VALUE` while unknown).
    pub temperature_rate_centi_c_per_min: i16,
}

impl OutputRecord {
    /// The increment in fringes.
    pub fn delta_angle_fringes(&self) -> f64 {
        f64::from(self.delta_angle_q16) / 65536.0
    }
    /// True when the increment is good.
    pub fn is_valid(&self) -> bool {
        self.status.contains(OutputStatus::VALID)
    }
    /// The temperature, °C, if the record carries one.
    pub fn temperature_c(&self) -> Option<f64> {
        (self.temperature_q7 != NO_VALUE).then(|| f64::from(self.temperature_q7) / 128.0)
    }
    /// The temperature's rate, °C/min, if the record carries one.
    pub fn temperature_rate_c_per_min(&self) -> Option<f64> {
        (self.temperature_rate_centi_c_per_min != NO_VALUE)
            .then(|| f64::from(self.temperature_rate_centi_c_per_min) / 100.0)
    }
}

/// The record builder's state.
#[derive(Clone, Copy, Debug, Default)]
pub struct OutputRecorder {
    sequence: u64,
    /// Extended time of the last latch, and its raw register value.
    clock: Option<(u64, u32)>,
    /// The previous latch's stripped phase, if the chain holds.
    previous: Option<TotalPhase>,
    /// Integrated angle of the valid periods, Q32 fringes.
    angle_q32: i128,
    /// The temperature, its rate and the thermal correction in force.
    thermal: ThermalInput,
}

impl OutputRecorder {
    /// No record made yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// Records made so far (the next record's sequence number).
    pub fn records(&self) -> u64 {
        self.sequence
    }

    /// The temperature, its rate and the thermal correction for the records from the next one
    /// on (the main loop's thermal state, staged whole).
    pub fn set_thermal(&mut self, thermal: ThermalInput) {
        self.thermal = thermal;
    }

    /// Breaks the chain (a resynchronised count): the next record is a restart.
    pub fn restart(&mut self) {
        self.previous = None;
    }

    /// The record of the period that the latch at `timestamp_ticks` ends, with the stripped
    /// phase there and the status bits gathered over the period (`status` without VALID or
    /// RESTART; they are set here).
    pub fn record(
        &mut self,
        config: &OutputConfig,
        timestamp_ticks: u32,
        stripped: TotalPhase,
        status: OutputStatus,
    ) -> OutputRecord {
        let (time_ticks, period_ticks) = match self.clock {
            Some((t, raw)) => {
                let d = timestamp_ticks.wrapping_sub(raw);
                (t + u64::from(d), d)
            }
            None => (u64::from(timestamp_ticks), 0),
        };
        self.clock = Some((time_ticks, timestamp_ticks));
        let mut status = status.without(OutputStatus::VALID.union(OutputStatus::RESTART));
        if self.previous.is_none() {
            status = status.union(OutputStatus::RESTART);
        }
        let valid = status.contains(OutputStatus::DITHER_LOCKED)
            && !status.intersects(OutputStatus::FAULTS);
        let thermal = self.thermal;
        if thermal.sensor_fault {
            status = status.union(OutputStatus::THERMAL_SENSOR_FAULT);
        }
        if thermal.correction.is_some() {
            status = status.union(OutputStatus::THERMAL_CORRECTED);
        }
        let before_q16 = (self.angle_q32 >> 16) as i64;
        if valid {
            if let Some(previous) = self.previous {
                let increment = stripped - previous;
                let corrected = match &thermal.correction {
                    Some(c) => thermal_corrected(increment, period_ticks, config.timer_hz, c),
                    None => increment,
                };
                self.angle_q32 += i128::from(corrected.to_q32());
            }
            status = status.union(OutputStatus::VALID);
        }
        // A faulted latch is no reference for the next period either.
        let faulted = status.intersects(OutputStatus::FAULTS.without(OutputStatus::RESTART))
            || !status.contains(OutputStatus::DITHER_LOCKED);
        self.previous = if faulted { None } else { Some(stripped) };
        let angle_q16 = (self.angle_q32 >> 16) as i64;
        let delta = angle_q16 - before_q16;
        let delta_angle_q16 = delta.clamp(i32::MIN as i64, i32::MAX as i64) as i32;
        let rate_deg_per_h = if valid && period_ticks > 0 {
            let fringes = delta as f64 / 65536.0;
            let seconds = f64::from(period_ticks) / f64::from(config.timer_hz);
            // 1 fringe/s = SF arcsec/s = SF deg/h.
            (fringes / seconds * f64::from(config.scale_factor_arcsec)) as f32
        } else {
            0.0
        };
        let record = OutputRecord {
            sequence: self.sequence,
            time_ticks,
            period_ticks,
            delta_angle_q16,
            angle_q16,
            rate_deg_per_h,
            status,
            temperature_q7: thermal.temperature_q7,
            temperature_rate_centi_c_per_min: thermal.rate_centi_c_per_min,
        };
        self.sequence += 1;
        record
    }
}

/// An increment over `period_ticks` corrected by the thermal model:
/// `(measured - bias dt) / (1 + scale_error)`. The correction itself is small (a bias of
/// 0.1 deg/h is 2e-4 fringe per ms; 10 ppm of 32768 fringes is 0.3 fringe), so it is formed in
/// `f32` (relative error 6e-8 of the correction) and subtracted from the exact increment.
fn thermal_corrected(
    increment: PhaseDelta,
    period_ticks: u32,
    timer_hz: u32,
    correction: &crate::thermal::model::ThermalCorrection,
) -> PhaseDelta {
    let q32 = crate::units::Q32_PER_FRINGE as f32;
    let bias_q32 = correction.bias_fringes_per_s * q32 * (period_ticks as f32 / timer_hz as f32);
    let s = correction.scale_error;
    let debiased = increment.to_q32() as f32 - bias_q32;
    // (m - b) / (1 + s) = m - b - (m - b) s / (1 + s)
    let total = bias_q32 + debiased * (s / (1.0 + s));
    increment - PhaseDelta::from_q32(total as i64)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::units::Q32_PER_FRINGE;

    fn config() -> OutputConfig {
        OutputConfig {
            model: DitherModelConfig::for_pickoff(
                40_000.0,
                84_000_000,
                crate::sample::AdcCode::MID,
            ),
            strip: StripConfig::for_pickoff(0.4, 1.8655),
            timer_hz: 84_000_000,
            scale_factor_arcsec: 1.8655,
        }
    }

    const OK: OutputStatus = OutputStatus::DITHER_LOCKED;

    /// Increments sum exactly to the integrated angle; a fault zeroes its period, holds the
    /// angle, and the period after it restarts the chain.
    #[test]
    fn increments_sum_to_the_angle_and_faults_hold_it() {
        let c = config();
        let mut r = OutputRecorder::new();
        let step = (1.25 * Q32_PER_FRINGE) as i64 + 12345;
        let first = r.record(&c, 0, TotalPhase::from_q32(0), OK);
        assert!(!first.is_valid() && first.status.contains(OutputStatus::RESTART));
        let mut sum = 0i64;
        let mut phase = 0i64;
        for i in 1..=10u32 {
            phase += step;
            let rec = r.record(&c, i * 84_000, TotalPhase::from_q32(phase), OK);
            assert!(rec.is_valid(), "{rec:?}");
            assert_eq!(rec.sequence, u64::from(i));
            sum += i64::from(rec.delta_angle_q16);
            assert_eq!(sum, rec.angle_q16);
        }
        // 1.25 fringes per ms at SF 1.8655: 1.25e3 * 1.8655 deg/h.
        phase += step;
        let rec = r.record(&c, 11 * 84_000, TotalPhase::from_q32(phase), OK);
        let expected = (step as f64 / Q32_PER_FRINGE) * 1e3 * 1.8655;
        // The increment is rounded to Q16: 2^-16 of 1.25 fringes, 1.2e-5.
        assert!((f64::from(rec.rate_deg_per_h) / expected - 1.0).abs() < 2e-5);
        let held = rec.angle_q16;
        phase += 1 << 40; // a glitch jumps the phase
        let bad = r.record(
            &c,
            12 * 84_000,
            TotalPhase::from_q32(phase),
            OK.union(OutputStatus::COUNTER_GLITCH),
        );
        assert!(!bad.is_valid() && bad.delta_angle_q16 == 0 && bad.angle_q16 == held);
        phase += step;
        let next = r.record(&c, 13 * 84_000, TotalPhase::from_q32(phase), OK);
        assert!(!next.is_valid() && next.status.contains(OutputStatus::RESTART));
        phase += step;
        let good = r.record(&c, 14 * 84_000, TotalPhase::from_q32(phase), OK);
        assert!(good.is_valid());
        assert_eq!(good.angle_q16, held + i64::from(good.delta_angle_q16));
    }

    /// An unlocked drive invalidates the period.
    #[test]
    fn an_unlocked_drive_invalidates() {
        let c = config();
        let mut r = OutputRecorder::new();
        r.record(&c, 0, TotalPhase::from_q32(0), OK);
        let rec = r.record(
            &c,
            84_000,
            TotalPhase::from_q32(1 << 32),
            OutputStatus::empty(),
        );
        assert!(!rec.is_valid() && rec.delta_angle_q16 == 0);
    }

    /// A timing fault (the board's watch) invalidates the period and holds the angle; the
    /// next period, without it, is a restart (no angle spliced across the fault).
    #[test]
    fn a_timing_fault_invalidates_and_holds_the_angle() {
        let c = config();
        let mut r = OutputRecorder::new();
        r.record(&c, 0, TotalPhase::from_q32(0), OK);
        let good = r.record(&c, 84_000, TotalPhase::from_q32(1 << 32), OK);
        assert!(good.is_valid());
        let bad = r.record(
            &c,
            168_000,
            TotalPhase::from_q32(2 << 32),
            OK.union(OutputStatus::TIMING_FAULT),
        );
        assert!(!bad.is_valid() && bad.delta_angle_q16 == 0 && bad.angle_q16 == good.angle_q16);
        assert!(bad.status.contains(OutputStatus::TIMING_FAULT));
        let next = r.record(&c, 252_000, TotalPhase::from_q32(3 << 32), OK);
        assert!(!next.is_valid() && next.status.contains(OutputStatus::RESTART));
    }

    /// With a correction in force, each increment is `(measured - bias dt) / (1 + s)` to the
    /// Q16 step, the records say so, and carry the temperature and its rate; a sensor fault
    /// marks them and no correction is made.
    #[test]
    fn the_thermal_correction_and_its_marks() {
        use crate::thermal::model::ThermalCorrection;
        let c = config();
        let mut r = OutputRecorder::new();
        let correction = ThermalCorrection {
            bias_fringes_per_s: 0.25,
            scale_error: 40e-6,
        };
        r.set_thermal(ThermalInput {
            temperature_q7: 30 * 128,
            rate_centi_c_per_min: 150,
            sensor_fault: false,
            correction: Some(correction),
        });
        r.record(&c, 0, TotalPhase::from_q32(0), OK);
        // 1000 fringes per 1 ms period.
        let step = 1000i64 << 32;
        let rec = r.record(&c, 84_000, TotalPhase::from_q32(step), OK);
        let want = (1000.0 - 0.25e-3) / (1.0 + 40e-6);
        assert!(
            (rec.delta_angle_fringes() - want).abs() < 2.0 / 65536.0,
            "{rec:?}"
        );
        assert!(rec.status.contains(OutputStatus::THERMAL_CORRECTED));
        assert_eq!(rec.temperature_c(), Some(30.0));
        assert_eq!(rec.temperature_rate_c_per_min(), Some(1.5));
        r.set_thermal(ThermalInput {
            sensor_fault: true,
            ..ThermalInput::NONE
        });
        let rec = r.record(&c, 168_000, TotalPhase::from_q32(2 * step), OK);
        assert_eq!(rec.delta_angle_q16, 1000 << 16, "uncorrected");
        assert!(rec.is_valid());
        assert!(rec.status.contains(OutputStatus::THERMAL_SENSOR_FAULT));
        assert!(!rec.status.contains(OutputStatus::THERMAL_CORRECTED));
        assert_eq!(rec.temperature_c(), None);
    }

    /// The 32-bit capture register wraps; the record's time does not.
    #[test]
    fn time_extends_across_the_register_wrap() {
        let c = config();
        let mut r = OutputRecorder::new();
        let mut raw = u32::MAX - 100_000;
        let mut last = r.record(&c, raw, TotalPhase::from_q32(0), OK).time_ticks;
        for _ in 0..5 {
            raw = raw.wrapping_add(84_000);
            let rec = r.record(&c, raw, TotalPhase::from_q32(0), OK);
            assert_eq!(rec.time_ticks, last + 84_000);
            assert_eq!(rec.period_ticks, 84_000);
            last = rec.time_ticks;
        }
        assert!(last > u64::from(u32::MAX));
    }
}
