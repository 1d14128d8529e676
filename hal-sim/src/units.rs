//! Unit conversions between the gyro's physical quantities and the beat phase.
//!
//! The simulator integrates the beat phase `psi` in radians: one fringe = 2 pi rad = one
//! counter pulse = one scale factor `SF` of body angle (arcsec/pulse). Everything physical
//! (input rate in deg/h, dither amplitude in arcsec, angle random walk in deg/sqrt(h)) is
//! converted once, at the edge, by the functions here.
//!
//! The key identity: 1 deg/h = 3600 arcsec / 3600 s = 1 arcsec/s, so a body rate of
//! `r` deg/h produces `r / SF` fringes per second, i.e. `2 pi r / SF` rad/s of beat phase.

use core::f64::consts::TAU;

/// Arcseconds in one degree.
pub const ARCSEC_PER_DEG: f64 = 3600.0;
/// Seconds in one hour.
pub const SECONDS_PER_HOUR: f64 = 3600.0;
/// Earth's rotation rate in deg/h with the solar-day convention (360 deg / 24 h). With it,
/// `15 cos(22.2 deg) = 13.888 deg/h`, the paper's input range.
pub const EARTH_RATE_SOLAR_DEG_PER_H: f64 = 15.0;
/// Earth's sidereal rotation rate in deg/h (360 deg per sidereal day, 23.934 h).
pub const EARTH_RATE_SIDEREAL_DEG_PER_H: f64 = 15.041_067;

/// Body rate in deg/h to beat-phase rate in rad/s.
pub fn deg_per_h_to_beat_rad_per_s(rate_deg_per_h: f64, scale_factor_arcsec: f64) -> f64 {
    TAU * rate_deg_per_h / scale_factor_arcsec
}

/// Beat-phase rate in rad/s to body rate in deg/h.
pub fn beat_rad_per_s_to_deg_per_h(rate_rad_per_s: f64, scale_factor_arcsec: f64) -> f64 {
    rate_rad_per_s * scale_factor_arcsec / TAU
}

/// Body angle in arcsec to beat phase in rad.
pub fn arcsec_to_beat_rad(angle_arcsec: f64, scale_factor_arcsec: f64) -> f64 {
    TAU * angle_arcsec / scale_factor_arcsec
}

/// Beat phase in rad to body angle in arcsec.
pub fn beat_rad_to_arcsec(phase_rad: f64, scale_factor_arcsec: f64) -> f64 {
    phase_rad * scale_factor_arcsec / TAU
}

/// Frequency in Hz to angular frequency in rad/s.
pub fn hz_to_rad_per_s(freq_hz: f64) -> f64 {
    TAU * freq_hz
}

/// Angle random walk in deg/sqrt(h) to beat phase in rad/sqrt(s).
///
/// 1 deg/sqrt(h) = 3600 arcsec / 60 sqrt(s) = 60 arcsec/sqrt(s).
pub fn arw_deg_per_rt_h_to_beat_rad_per_rt_s(
    arw_deg_per_rt_h: f64,
    scale_factor_arcsec: f64,
) -> f64 {
    arcsec_to_beat_rad(60.0 * arw_deg_per_rt_h, scale_factor_arcsec)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trips_and_paper_numbers() {
        let sf = 1.8655;
        let r = deg_per_h_to_beat_rad_per_s(200.0, sf);
        assert!((r - 673.6).abs() < 0.05, "Omega_L = {r}");
        assert!((beat_rad_per_s_to_deg_per_h(r, sf) - 200.0).abs() < 1e-12);
        let a = arcsec_to_beat_rad(450.0, sf);
        assert!((beat_rad_to_arcsec(a, sf) - 450.0).abs() < 1e-12);
        // Peak dither rate ~ 3.70e6 rad/s at 389 Hz, 450 arcsec.
        let peak = a * hz_to_rad_per_s(389.0);
        assert!((peak / 3.70e6 - 1.0).abs() < 0.01, "peak {peak}");
        // Earth rate at 22.2 deg latitude: the paper's 13.888 deg/h.
        let e = EARTH_RATE_SOLAR_DEG_PER_H * (22.2f64).to_radians().cos();
        assert!((e - 13.888).abs() < 1e-3, "{e}");
        assert!(
            (arw_deg_per_rt_h_to_beat_rad_per_rt_s(1.0, sf) - arcsec_to_beat_rad(60.0, sf)).abs()
                < 1e-12
        );
    }
}
