//! `dither on|off`, `dither amp <arcsec>`, `dither noise <percent>`, `dither status`: the
//! dither drive's setpoints and status.
//!
//! A setpoint command changes one field of the drive's [`DitherSetpoints`](crate::storage::DitherSetpoints) and hands them to
//! the device whole ([`DeviceLink::apply_dither`]), which range-checks every field before it
//! changes anything: a refused value (`ERR 5` out of range, `ERR 4` not finite) leaves the
//! drive as it was. The setpoints are unsaved until `store`, which writes them into the
//! calibration record with the coefficients; at power-up and on `reload` the stored ones are
//! applied (a record without them leaves the board's defaults).

use super::{ok_with, Answer};
use crate::dither::{CommandError, DitherState, DitherStatus, FaultKind, StartPhase};
use crate::protocol::link::{DeviceLink, Identity};
use crate::protocol::parse::DitherCommand;
use crate::protocol::ErrorCode;

/// One `dither` command.
pub fn command<D: DeviceLink>(device: &mut D, id: &Identity, command: DitherCommand) -> Answer {
    let mut setpoints = device.dither_setpoints();
    match command {
        DitherCommand::Status => {
            // The independent check: the readout's dither amplitude from the fringe count's
            // excursion between turnarounds, in arcsec through the scale factor.
            let count_rad = device.status().dither_amplitude_rad;
            let count_arcsec = count_rad * id.scale_factor_arcsec / core::f32::consts::TAU;
            return Ok(status(&device.dither_status(), count_arcsec));
        }
        DitherCommand::Enable(on) => setpoints.enabled = on,
        DitherCommand::Amplitude(arcsec) => setpoints.amplitude_arcsec = arcsec,
        DitherCommand::Noise(percent) => setpoints.noise_percent = percent,
    }
    device.apply_dither(setpoints).map_err(|e| match e {
        CommandError::NotFinite => ErrorCode::NotFinite,
        CommandError::OutOfRange => ErrorCode::OutOfRange,
        CommandError::Inhibited => ErrorCode::WrongState,
    })?;
    let s = device.dither_setpoints();
    Ok(ok_with(format_args!(
        "dither={} amp_arcsec={} noise_pct={}",
        if s.enabled { "on" } else { "off" },
        s.amplitude_arcsec,
        s.noise_percent
    )))
}

/// The state as one word: `off`, `starting`, `locked`, `fault`, or `inhibited`.
pub fn state_word(state: DitherState) -> &'static str {
    match state {
        DitherState::Off => "off",
        DitherState::Starting => "starting",
        DitherState::Locked => "locked",
        DitherState::Fault(_) => "fault",
        DitherState::Inhibited => "inhibited",
    }
}

fn fault_word(kind: FaultKind) -> &'static str {
    match kind {
        FaultKind::PickoffLost => "pickoff_lost",
        FaultKind::PickoffSaturated => "pickoff_saturated",
        FaultKind::NoOscillation => "no_oscillation",
        FaultKind::DriveSaturated => "drive_saturated",
        FaultKind::AmplitudeOutOfRange => "amplitude_out_of_range",
    }
}

/// `dither status`: `state=` (with `fault=<kind>` in a fault, `start=<phase>` while starting),
/// the measured amplitude and the setpoint (arcsec), the drive frequency (Hz), the drive level
/// (fraction of the DAC's half range), the phase error (rad), the noise depth (percent), the
/// fault counters per kind (pick-off lost, pick-off saturated, no oscillation, drive saturated,
/// amplitude out of range), the faults in a row and the back-off (s); then the amplitude the
/// fringe count measures (`count_amp_arcsec`, from the readout) and the pick-off's gain against
/// it (`pickoff_gain`, pick-off amplitude / count amplitude: 1 for a calibrated pick-off; `-`
/// without a count amplitude).
fn status(s: &DitherStatus, count_arcsec: f32) -> crate::protocol::respond::Response {
    let detail = match (s.state, s.start_phase) {
        (DitherState::Fault(kind), _) => ("fault", fault_word(kind)),
        (DitherState::Starting, Some(StartPhase::Listen)) => ("start", "listen"),
        (DitherState::Starting, Some(StartPhase::Sweep)) => ("start", "sweep"),
        (DitherState::Starting, Some(StartPhase::RingUp)) => ("start", "ring_up"),
        (DitherState::Starting, Some(StartPhase::SelfTest)) => ("start", "selftest"),
        _ => ("detail", "-"),
    };
    let f = s.faults.0;
    ok_with(format_args!(
        "state={} {}={} amp_arcsec={:.2} setpoint_arcsec={:.2} freq_hz={:.4} drive={:.4} \
phase_err_rad={:.5} noise_pct={:.2} faults={},{},{},{},{} in_a_row={} backoff_s={:.1} \
count_amp_arcsec={:.2} pickoff_gain={}",
        state_word(s.state),
        detail.0,
        detail.1,
        s.amplitude_arcsec,
        s.setpoint_arcsec,
        s.frequency_hz,
        s.drive_level,
        s.phase_error_rad,
        s.noise_depth_percent,
        f[0],
        f[1],
        f[2],
        f[3],
        f[4],
        s.faults_in_a_row,
        s.retry_backoff_s,
        count_arcsec,
        GainText(s.amplitude_arcsec, count_arcsec),
    ))
}

/// `pick-off / count` to 5 decimals, or `-` when there is no count amplitude.
struct GainText(f32, f32);

impl core::fmt::Display for GainText {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        if self.1 > 1.0 && self.0.is_finite() {
            write!(f, "{:.5}", self.0 / self.1)
        } else {
            f.write_str("-")
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::protocol::commands::testing::{text, MemDevice, ID};
    use crate::protocol::respond::MAX_RESPONSE;
    use crate::storage::DitherSetpoints;

    fn answer(device: &mut MemDevice, c: DitherCommand) -> Result<String, ErrorCode> {
        command(device, &ID, c).map(|r| text(r).trim_end().to_owned())
    }

    #[test]
    fn setpoints_change_one_field_and_answer_what_is_in_force() {
        let mut device = MemDevice::default();
        assert_eq!(
            answer(&mut device, DitherCommand::Amplitude(420.0)).unwrap(),
            "OK dither=on amp_arcsec=420 noise_pct=0"
        );
        assert_eq!(
            answer(&mut device, DitherCommand::Noise(12.5)).unwrap(),
            "OK dither=on amp_arcsec=420 noise_pct=12.5"
        );
        assert_eq!(
            answer(&mut device, DitherCommand::Enable(false)).unwrap(),
            "OK dither=off amp_arcsec=420 noise_pct=12.5"
        );
        assert_eq!(
            device.dither_setpoints(),
            DitherSetpoints {
                enabled: false,
                amplitude_arcsec: 420.0,
                noise_percent: 12.5
            }
        );
    }

    /// The drive's ranges (50-650 arcsec, 0-50 %): a refused value changes nothing.
    #[test]
    fn out_of_range_values_are_refused_and_change_nothing() {
        let mut device = MemDevice::default();
        let before = device.dither_setpoints();
        for c in [
            DitherCommand::Amplitude(49.9),
            DitherCommand::Amplitude(650.1),
            DitherCommand::Amplitude(-450.0),
            DitherCommand::Noise(-1.0),
            DitherCommand::Noise(50.5),
        ] {
            assert_eq!(answer(&mut device, c), Err(ErrorCode::OutOfRange), "{c:?}");
            assert_eq!(device.dither_setpoints(), before, "{c:?}");
        }
        assert_eq!(
            answer(&mut device, DitherCommand::Amplitude(f32::NAN)),
            Err(ErrorCode::NotFinite)
        );
        assert_eq!(device.dither_setpoints(), before);
    }

    #[test]
    fn status_names_the_state_and_fits_one_answer() {
        let mut device = MemDevice::default();
        let line = answer(&mut device, DitherCommand::Status).unwrap();
        assert!(
            line.starts_with("OK state=locked detail=- amp_arcsec=0.00 setpoint_arcsec=450.00"),
            "{line}"
        );
        assert!(line.contains(" faults=0,0,0,0,0 in_a_row=0 "), "{line}");
        assert!(
            line.ends_with(" count_amp_arcsec=0.00 pickoff_gain=-"),
            "{line}"
        );
        // The longest the line can get: every counter at u32::MAX, every float wide.
        let mut s = device.dither_status();
        s.state = DitherState::Fault(FaultKind::AmplitudeOutOfRange);
        s.faults.0 = [u32::MAX; 5];
        s.faults_in_a_row = u32::MAX;
        s.amplitude_arcsec = -1.0e7;
        s.setpoint_arcsec = -1.0e7;
        s.frequency_hz = -1.0e7;
        s.drive_level = -1.0e7;
        s.phase_error_rad = -1.0e7;
        s.noise_depth_percent = -1.0e7;
        s.retry_backoff_s = 1.0e7;
        let long = status(&s, -1.0e7).finish(true);
        assert!(long.len() <= MAX_RESPONSE, "{} bytes: {long}", long.len());
        assert!(
            long.contains("state=fault fault=amplitude_out_of_range"),
            "{long}"
        );
    }
}
