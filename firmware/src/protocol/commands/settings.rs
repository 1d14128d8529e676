//! `set a|b <rad/s>`, `comp on|off`, `track on|off`, `defaults`: the commands that change the
//! compensation in force by hand. Each stages whole settings into the readout (they take effect
//! at the next cycle boundary) and marks the coefficients unsaved.

use super::calibration::CalibrationState;
use super::provenance::{Provenance, Source};
use super::{ok_with, Answer};
use crate::protocol::link::DeviceLink;
use crate::protocol::parse::Coefficient;
use crate::protocol::respond::Response;
use crate::protocol::ErrorCode;
use crate::signal::compensation::Coefficients;
use crate::storage::CalibrationRecord;

/// `set a|b <rad/s>`: a value the Q15.16 format cannot hold is refused (`ERR 5`).
pub fn set<D: DeviceLink>(
    device: &mut D,
    provenance: &mut Provenance,
    which: Coefficient,
    value_rad_per_s: f32,
) -> Answer {
    let mut settings = device.active_settings();
    let (a, b) = (
        settings.coefficients.a_rad_per_s(),
        settings.coefficients.b_rad_per_s(),
    );
    let (a, b) = match which {
        Coefficient::A => (value_rad_per_s, b),
        Coefficient::B => (a, value_rad_per_s),
    };
    settings.coefficients =
        Coefficients::from_rad_per_s(a, b).map_err(|_| ErrorCode::OutOfRange)?;
    device.stage_settings(settings);
    provenance.changed();
    Ok(match which {
        Coefficient::A => ok_with(format_args!("a={}", settings.coefficients.a_rad_per_s())),
        Coefficient::B => ok_with(format_args!("b={}", settings.coefficients.b_rad_per_s())),
    })
}

/// `comp on|off`: the coefficients (and the fit behind them) stay, only the switch changes.
pub fn compensation<D: DeviceLink>(
    device: &mut D,
    provenance: &mut Provenance,
    on: bool,
) -> Response {
    let mut settings = device.active_settings();
    settings.enabled = on;
    device.stage_settings(settings);
    provenance.source = Source::Unsaved;
    ok_with(format_args!("comp={}", if on { "on" } else { "off" }))
}

/// `track on|off`: on starts the loop from the coefficients in force.
pub fn tracking<D: DeviceLink>(
    device: &mut D,
    calibration: &mut CalibrationState,
    on: bool,
) -> Response {
    match calibration.set_tracking(on, device.active_settings().coefficients) {
        Some(memory_cycles) => ok_with(format_args!(
            "track=on memory_cycles={}",
            memory_cycles as f32
        )),
        None => ok_with(format_args!("track=off")),
    }
}

/// `defaults`: zero coefficients, compensation off.
pub fn defaults<D: DeviceLink>(device: &mut D, provenance: &mut Provenance) -> Response {
    device.stage_settings(CalibrationRecord::DEFAULTS.settings);
    provenance.changed();
    ok_with(format_args!("a=0 b=0 comp=off"))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibration::validation::AcceptanceLimits;
    use crate::protocol::commands::testing::{report, text, MemDevice};
    use crate::storage::{FitSummary, LoadOutcome};

    fn from_flash() -> Provenance {
        let fit = FitSummary {
            runs: 1,
            ..FitSummary::default()
        };
        Provenance::new(&report(LoadOutcome::Loaded { sequence: 2 }), Some(fit), 1)
    }

    #[test]
    fn set_stages_one_coefficient_and_marks_unsaved() {
        let (mut device, mut p) = (MemDevice::default(), from_flash());
        let answer = set(&mut device, &mut p, Coefficient::B, 0.25).unwrap();
        assert_eq!(text(answer).trim_end(), "OK b=0.25");
        assert_eq!(device.settings.coefficients.b_rad_per_s(), 0.25);
        assert_eq!(device.settings.coefficients.a_rad_per_s(), 0.0);
        assert_eq!(device.staged, 1);
        assert_eq!((p.source, p.fit), (Source::Unsaved, None));
    }

    #[test]
    fn set_out_of_range_is_refused_and_changes_nothing() {
        let (mut device, mut p) = (MemDevice::default(), from_flash());
        let refused = set(&mut device, &mut p, Coefficient::A, 1.0e6);
        assert_eq!(refused.unwrap_err(), ErrorCode::OutOfRange);
        assert_eq!(device, MemDevice::default());
        assert_eq!(p, from_flash());
    }

    #[test]
    fn comp_switches_and_keeps_the_fit() {
        let (mut device, mut p) = (MemDevice::default(), from_flash());
        assert_eq!(
            text(compensation(&mut device, &mut p, true)).trim_end(),
            "OK comp=on"
        );
        assert!(device.settings.enabled);
        assert_eq!(p.source, Source::Unsaved);
        assert!(p.fit.is_some());
        assert_eq!(
            text(compensation(&mut device, &mut p, false)).trim_end(),
            "OK comp=off"
        );
        assert!(!device.settings.enabled);
    }

    #[test]
    fn track_answers_on_with_memory_and_off() {
        let mut device = MemDevice::default();
        let mut cal = CalibrationState::new(AcceptanceLimits::DEFAULT);
        let on = text(tracking(&mut device, &mut cal, true));
        assert_eq!(on.trim_end(), "OK track=on memory_cycles=20000");
        assert!(cal.tracking());
        assert_eq!(
            text(tracking(&mut device, &mut cal, false)).trim_end(),
            "OK track=off"
        );
        assert!(!cal.tracking());
    }

    #[test]
    fn defaults_stage_zero_and_off() {
        let mut device = MemDevice::default();
        device.settings.coefficients = Coefficients::from_rad_per_s(1.0, 2.0).unwrap();
        device.settings.enabled = true;
        let mut p = from_flash();
        assert_eq!(
            text(defaults(&mut device, &mut p)).trim_end(),
            "OK a=0 b=0 comp=off"
        );
        assert_eq!(device.settings, CalibrationRecord::DEFAULTS.settings);
        assert_eq!((p.source, p.fit), (Source::Unsaved, None));
    }
}
