//! The controller's configuration: immutable, built once from the board profile
//! ([`DitherConfig::for_profile`]), apart from the controller's state (STYLE.md). Each part
//! lives beside the code that uses it; this file only assembles them.

use super::amplitude::AmplitudeLoopConfig;
use super::frequency::FrequencyLoopConfig;
use super::startup::StartupConfig;
use super::supervisor::FaultLimits;
use crate::profile::BoardProfile;
use crate::sample::AdcCode;

/// Crossover of the amplitude loop once locked, Hz. The loop's measurement noise (the
/// half-cycle fit of a 1 mV rms pick-off: 0.4 code rms) reaches the amplitude within the loop's
/// bandwidth, and the amplitude's change between two turnarounds grows with the bandwidth
/// squared: at the acquisition loop's 4 Hz it is 0.013 arcsec per dither cycle (0.043 rad of
/// beat phase in the readout's per-cycle output, twice the lock-in correction it is
/// calibrated against); at 0.25 Hz it is below the photodiode noise. The resonator's own
/// bandwidth (f0 / 2Q = 0.19 Hz at Q = 1000) is of the same order, so drift is still held.
pub const LOCKED_AMPLITUDE_CROSSOVER_HZ: f32 = 0.25;

/// Everything the dither controller needs to know that does not change while it runs.
#[derive(Clone, Debug)]
pub struct DitherConfig {
    /// Tick rate f_s, Hz (the board profile's `drive_tick_hz`).
    pub tick_hz: f32,
    /// Pick-off sensitivity, arcsec per ADC code.
    pub pickoff_arcsec_per_code: f32,
    /// The pick-off code of zero angle (nominal; the fit measures the real offset).
    pub pickoff_mid_code: AdcCode,
    /// The DAC's zero-drive code.
    pub dac_mid_code: u16,
    /// The DAC's full scale.
    pub dac_full_scale: u16,
    /// The pick-off's sampling instant after its tick, ticks in Q16: the ADC's aperture less
    /// any pick-off lag (a board calibration; enters the phase detector and the estimates).
    pub sample_delay_q16: u32,
    /// Corner of the drive amplifier's output low-pass, Hz (the board profile's): its lag is
    /// compensated in the phase detector ([`DitherConfig::drive_lag`]).
    pub drive_lowpass_hz: f32,
    /// Settable amplitude setpoints, arcsec (inclusive).
    pub setpoint_range_arcsec: (f32, f32),
    /// The setpoint after reset, arcsec.
    pub default_setpoint_arcsec: f32,
    /// Start-up: search range, sweep, ring detection, lock criteria.
    pub startup: StartupConfig,
    /// The amplitude loop while acquiring (fast: from the ring-up to the setpoint).
    pub amplitude: AmplitudeLoopConfig,
    /// The amplitude loop while locked (slow: every change of the drive moves the dither
    /// between two turnarounds, which the readout's per-cycle output carries, so the locked
    /// loop passes as little pick-off noise into the amplitude as holding it allows).
    pub amplitude_locked: AmplitudeLoopConfig,
    /// The frequency loop.
    pub frequency: FrequencyLoopConfig,
    /// Fault limits and the back-off.
    pub faults: FaultLimits,
}

impl DitherConfig {
    /// The controller on `profile`'s board: its tick, pick-off, DAC and search range; the
    /// nominal gyro's amplitude as the default setpoint, settable in 50-650 arcsec; the drive
    /// limited to the DAC's linear range ([`drive_limit_codes`]); loop crossovers 4 Hz
    /// (amplitude) and 2 Hz (frequency), integral corners a quarter of those.
    pub fn for_profile(profile: &BoardProfile) -> Self {
        let tick_hz = profile.drive_tick_hz as f64;
        let dither_hz = profile.nominal_dither_hz as f32;
        let drive_limit = drive_limit_codes(profile);
        let startup = StartupConfig::new(profile.dither_search_hz, tick_hz, drive_limit);
        let sensitivity = profile.pickoff_arcsec_per_code as f32;
        let pickoff_mid_code = profile.pickoff_mid_code;
        let pickoff_half_range = pickoff_mid_code
            .to_f32()
            .min((AdcCode::FULL_SCALE - pickoff_mid_code) as f32);
        Self {
            tick_hz: tick_hz as f32,
            pickoff_arcsec_per_code: sensitivity,
            pickoff_mid_code,
            dac_mid_code: (profile.dac_full_scale / 2 + 1),
            dac_full_scale: profile.dac_full_scale,
            sample_delay_q16: ((profile.aperture_delay_ticks as u64) << 16)
                .div_ceil(profile.drive_tick_period_timer_ticks() as u64)
                as u32,
            drive_lowpass_hz: profile.drive_lowpass_hz as f32,
            setpoint_range_arcsec: (50.0, 650.0),
            default_setpoint_arcsec: profile.nominal_dither_amplitude_arcsec as f32,
            startup,
            amplitude: AmplitudeLoopConfig::new(4.0, 4.0, dither_hz, drive_limit),
            amplitude_locked: AmplitudeLoopConfig::new(
                LOCKED_AMPLITUDE_CROSSOVER_HZ,
                1.0,
                dither_hz,
                drive_limit,
            ),
            frequency: FrequencyLoopConfig::new(
                2.0,
                4.0,
                dither_hz,
                tick_hz as f32,
                startup.search_steps,
            ),
            faults: FaultLimits::new(tick_hz as f32, 0xFFF, 0.92 * pickoff_half_range),
        }
    }

    /// The drive amplifier's phase lag at drive step `step`: atan(f / f_c), Q32 turns (`f32`
    /// arithmetic, once per half cycle).
    pub fn drive_lag(&self, step: crate::units::Phase) -> crate::units::Phase {
        let f_hz = step.to_bits() as f32 / crate::units::Q32_PER_TURN_F32 * self.tick_hz;
        let turns = libm::atanf(f_hz / self.drive_lowpass_hz) / core::f32::consts::TAU;
        crate::units::Phase::from_bits(crate::math::round_f32_to_i32(
            turns * crate::units::Q32_PER_TURN_F32,
        ) as u32)
    }

    /// Arcsec of dither per pick-off code.
    pub fn codes_to_arcsec(&self, codes: f32) -> f32 {
        codes * self.pickoff_arcsec_per_code
    }

    /// The pick-off's sampling delay, ticks.
    pub fn sample_delay_ticks(&self) -> f32 {
        self.sample_delay_q16 as f32 / 65_536.0
    }

    /// Pick-off codes of `arcsec` of dither.
    pub fn arcsec_to_codes(&self, arcsec: f32) -> f32 {
        arcsec / self.pickoff_arcsec_per_code
    }
}

/// The drive's largest amplitude, DAC codes: the smaller of 93 % of the DAC's half range and
/// the distance from the mid-code to the nearer end of the DAC's linear range (the buffered
/// output clips beyond it: a clipped drive is a distorted drive, and its harmonics and its
/// lower fundamental are not what the loops assume). 1798 codes on the F405 (the linear
/// range), 4x what 450 arcsec needs at Q = 1000.
pub fn drive_limit_codes(profile: &BoardProfile) -> f32 {
    let mid = profile.dac_full_scale / 2 + 1;
    let (lo, hi) = profile.dac_linear_codes;
    let linear = mid.saturating_sub(lo).min(hi.saturating_sub(mid));
    let half_range = (profile.dac_full_scale as f32 + 1.0) / 2.0;
    (0.93 * half_range).min(linear as f32)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn f405_config_is_consistent() {
        let c = DitherConfig::for_profile(&BoardProfile::F405);
        assert_eq!(c.tick_hz, 40_000.0);
        assert_eq!(c.dac_mid_code, 2048);
        assert_eq!(c.amplitude.drive_limit_codes(), 1798.0);
        // The largest setpoint stays inside the out-of-range limit, which stays off the rails.
        let max_codes = c.arcsec_to_codes(c.setpoint_range_arcsec.1);
        assert!(max_codes * (1.0 + c.faults.band) < c.faults.max_amplitude_codes);
        assert!(c.faults.max_amplitude_codes < 2047.0);
        assert_eq!(c.sample_delay_q16, 2185); // 70 / 2100 ticks
    }

    /// The largest drive the loops can command, at its peaks and with the noise dither's
    /// clamp, stays inside the buffered DAC's linear range (0.2 V to VDDA - 0.2 V): no clipping
    /// during the ring-up.
    #[test]
    fn the_drive_stays_inside_the_dacs_linear_range() {
        let p = BoardProfile::F405;
        let c = DitherConfig::for_profile(&p);
        let mut drive = super::super::Drive::off(0, c.dac_mid_code, c.dac_full_scale);
        drive.amplitude_q16 = c.amplitude.drive_limit_q16;
        for config in [&c.amplitude, &c.amplitude_locked] {
            assert!(config.drive_limit_q16 <= c.amplitude.drive_limit_q16);
        }
        let (lo, hi) = p.dac_linear_codes;
        for sin in [i32::MAX, i32::MIN + 1, 0, i32::MAX / 2] {
            let code = drive.code_from_sin(sin);
            assert!((lo..=hi).contains(&code), "{code} outside {lo}..={hi}");
        }
        assert_eq!(drive.code_from_sin(i32::MAX), 3846);
        assert_eq!(drive.code_from_sin(i32::MIN + 1), 250);
    }
}
