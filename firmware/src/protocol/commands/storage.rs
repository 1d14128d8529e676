//! `store` and `reload`: the coefficients in force to flash and back. The device pauses the
//! readout only around a sector erase ([`DeviceLink::store`]); here only the record is
//! assembled, the [`Provenance`] updated and the answer says which it was.

use super::provenance::{Provenance, Source, SourceText};
use super::{ok_with, Answer};
use crate::protocol::link::{DeviceLink, Identity};
use crate::protocol::respond::Response;
use crate::protocol::ErrorCode;
use crate::storage::{CalibrationRecord, ThermalCalibration};

/// `store`: the settings in force with the fit behind them; a flash failure is `ERR 13` and
/// leaves the provenance as it was. `readout=continuous`: no sector was erased, the readout
/// went on through the store; `readout=resynchronised`: an erase paused it (its output marks
/// the pause: a restart record).
pub fn store<D: DeviceLink>(device: &mut D, provenance: &mut Provenance, id: &Identity) -> Answer {
    let record = CalibrationRecord {
        serial_number: id.serial_number,
        boot_count: provenance.boot_count,
        settings: device.active_settings(),
        fit: provenance.fit,
        reset_to_defaults: false,
        dither: Some(device.dither_setpoints()),
        strip: device.strip_coefficients(),
        thermal: thermal_calibration(device),
    };
    let stored = device.store(&record).map_err(|_| ErrorCode::FlashError)?;
    provenance.source = Source::Flash {
        sequence: stored.sequence,
    };
    let readout = if stored.erased {
        "resynchronised"
    } else {
        "continuous"
    };
    Ok(ok_with(format_args!(
        "stored seq={} readout={readout}",
        stored.sequence
    )))
}

/// The thermal model in force and its switch, as `store` writes them.
fn thermal_calibration<D: DeviceLink>(device: &mut D) -> Option<ThermalCalibration> {
    let state = device.thermal();
    state.model().map(|model| ThermalCalibration {
        model,
        enabled: state.enabled(),
    })
}

/// `reload`: the newest valid record (or the defaults) staged, with where it came from; its
/// dither setpoints applied when it holds any (`dither=stored`), else the drive's stay
/// (`dither=kept`; also when the drive refuses the stored values, which a record of other
/// firmware could hold: `dither=refused`); its stripping coefficients likewise (`strip=stored`,
/// or `strip=kept`: the stripping goes on from where it is), and its thermal model
/// (`thermal=stored`, or `thermal=kept`: the model in force stays).
pub fn reload<D: DeviceLink>(device: &mut D, provenance: &mut Provenance) -> Response {
    let (record, report) = device.load();
    device.stage_settings(record.settings);
    provenance.source = Source::of(&report);
    provenance.fit = record.fit;
    let dither = match record.dither {
        Some(setpoints) if device.apply_dither(setpoints).is_ok() => "stored",
        Some(_) => "refused",
        None => "kept",
    };
    let strip = match record.strip {
        Some(strip) => {
            device.apply_strip(strip);
            "stored"
        }
        None => "kept",
    };
    let thermal = match record.thermal {
        Some(t) => {
            device.set_thermal_model(Some(t.model), t.enabled);
            "stored"
        }
        None => "kept",
    };
    ok_with(format_args!(
        "coeffs={} dither={dither} strip={strip} thermal={thermal}",
        SourceText(provenance.source)
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::protocol::commands::testing::{report, text, MemDevice, ID};
    use crate::signal::compensation::Coefficients;
    use crate::storage::{DefaultsReason, DitherSetpoints, FitSummary, LoadOutcome};

    fn unsaved() -> Provenance {
        let mut p = Provenance::new(&report(LoadOutcome::Loaded { sequence: 1 }), None, 7);
        p.source = Source::Unsaved;
        p.fit = Some(FitSummary {
            runs: 2,
            ..FitSummary::default()
        });
        p
    }

    #[test]
    fn store_writes_settings_fit_serial_and_boot_count() {
        let mut device = MemDevice::default();
        device.settings.coefficients = Coefficients::from_rad_per_s(3.0, 4.0).unwrap();
        let mut p = unsaved();
        let answer = text(store(&mut device, &mut p, &ID).unwrap());
        assert_eq!(answer.trim_end(), "OK stored seq=1 readout=continuous");
        let record = device.stored[0];
        assert_eq!(
            (record.serial_number, record.boot_count),
            (ID.serial_number, 7)
        );
        assert_eq!(record.settings, device.settings);
        assert_eq!(record.fit, unsaved().fit);
        assert!(!record.reset_to_defaults);
        assert_eq!(p.source, Source::Flash { sequence: 1 });
    }

    /// A store that erased a sector says the readout was re-synchronised.
    #[test]
    fn an_erasing_store_says_the_readout_was_resynchronised() {
        let mut device = MemDevice {
            store_erases: true,
            ..MemDevice::default()
        };
        let answer = text(store(&mut device, &mut unsaved(), &ID).unwrap());
        assert_eq!(answer.trim_end(), "OK stored seq=1 readout=resynchronised");
    }

    #[test]
    fn failed_store_is_refused_and_changes_nothing() {
        let mut device = MemDevice {
            fail_store: true,
            ..MemDevice::default()
        };
        let mut p = unsaved();
        let refused = store(&mut device, &mut p, &ID);
        assert_eq!(refused.unwrap_err(), ErrorCode::FlashError);
        assert_eq!(p, unsaved());
        assert!(device.stored.is_empty());
    }

    #[test]
    fn reload_stages_the_record_and_reports_its_source() {
        let mut device = MemDevice::default();
        let mut p = unsaved();
        assert_eq!(
            text(reload(&mut device, &mut p)).trim_end(),
            "OK coeffs=defaults:erased dither=kept strip=kept thermal=kept"
        );
        assert_eq!(p.source, Source::Defaults(DefaultsReason::Erased));
        assert_eq!((p.fit, device.staged), (None, 1));

        device.settings.enabled = true;
        store(&mut device, &mut p, &ID).unwrap();
        device.settings = CalibrationRecord::DEFAULTS.settings;
        assert_eq!(
            text(reload(&mut device, &mut p)).trim_end(),
            "OK coeffs=flash:1 dither=stored strip=kept thermal=kept"
        );
        assert!(device.settings.enabled);
    }

    #[test]
    fn store_saves_the_dither_setpoints_and_reload_applies_them() {
        let mut device = MemDevice::default();
        let mut p = unsaved();
        let chosen = DitherSetpoints {
            enabled: false,
            amplitude_arcsec: 380.0,
            noise_percent: 12.5,
        };
        device.apply_dither(chosen).unwrap();
        store(&mut device, &mut p, &ID).unwrap();
        assert_eq!(device.stored[0].dither, Some(chosen));
        let other = DitherSetpoints {
            enabled: true,
            amplitude_arcsec: 500.0,
            noise_percent: 0.0,
        };
        device.apply_dither(other).unwrap();
        let answer = text(reload(&mut device, &mut p));
        assert_eq!(
            answer.trim_end(),
            "OK coeffs=flash:1 dither=stored strip=kept thermal=kept"
        );
        assert_eq!(device.dither_setpoints(), chosen);
        // A record whose setpoints the drive refuses (another firmware's wider range): the
        // coefficients load, the drive keeps what it had.
        device.stored[0].dither = Some(DitherSetpoints {
            amplitude_arcsec: 5000.0,
            ..chosen
        });
        device.apply_dither(other).unwrap();
        let answer = text(reload(&mut device, &mut p));
        assert_eq!(
            answer.trim_end(),
            "OK coeffs=flash:1 dither=refused strip=kept thermal=kept"
        );
        assert_eq!(device.dither_setpoints(), other);
    }

    /// `store` saves the stripping coefficients once converged (none while learning), and
    /// `reload` starts the stripping from them.
    #[test]
    fn store_saves_the_stripping_coefficients_and_reload_applies_them() {
        use crate::storage::StripCoefficients;
        let mut device = MemDevice::default();
        let mut p = unsaved();
        store(&mut device, &mut p, &ID).unwrap();
        assert_eq!(
            device.stored[0].strip, None,
            "still learning: nothing saved"
        );
        let learned = StripCoefficients::from_fringes_per_code(0.2144, -0.001).unwrap();
        device.strip = Some(learned);
        store(&mut device, &mut p, &ID).unwrap();
        assert_eq!(device.stored[1].strip, Some(learned));
        device.strip = None;
        let answer = text(reload(&mut device, &mut p));
        assert_eq!(
            answer.trim_end(),
            "OK coeffs=flash:2 dither=stored strip=stored thermal=kept"
        );
        assert_eq!(device.strip, Some(learned));
    }

    /// `store` writes the thermal model in force with its switch; `reload` puts it back in
    /// force (`thermal=stored`).
    #[test]
    fn store_saves_the_thermal_model_and_reload_applies_it() {
        use crate::thermal::model::ThermalModel;
        let mut device = MemDevice::default();
        let model = ThermalModel {
            reference_c: 25.0,
            min_c: -20.0,
            max_c: 60.0,
            bias_deg_h: [0.001, 0.002, 0.0, 0.0],
            bias_deg_h_per_c_per_min: 0.0,
            scale_ppm: [0.0, 0.5, 0.0],
        };
        device.set_thermal_model(Some(model), false);
        let mut p = unsaved();
        store(&mut device, &mut p, &ID).unwrap();
        assert_eq!(
            device.stored[0].thermal,
            Some(ThermalCalibration {
                model,
                enabled: false
            })
        );
        device.set_thermal_model(None, false);
        assert_eq!(
            text(reload(&mut device, &mut p)).trim_end(),
            "OK coeffs=flash:1 dither=stored strip=kept thermal=stored"
        );
        assert_eq!(device.thermal_model, Some((model, false)));
    }
}
