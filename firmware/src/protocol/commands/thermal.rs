//! `thermal`: the block's temperature, its rate, the sensor and the thermal model in force
//! (the reads `thermal`, `thermal model`), and the protected commands that set the model and
//! switch it.
//!
//! A model has eleven coefficients, more than one 96-byte line holds at full precision, so
//! `thermal set <name> <value>` edits one coefficient of a copy kept here ([`ThermalEdit`]; the
//! first edit starts it from the model in force), as `set a` does for a, and `thermal apply`
//! checks the copy whole (`ThermalModel::check`: finite, a range inside the sensor's that holds
//! T_ref, corrections no gyro needs more of; else `ERR 5`) and puts it in force, switched on.
//! The output stage only ever gets a checked model, whole (the atomic swap of STYLE.md).
//! `thermal on|off` switches the model in force (`ERR 11` without one). Like `comp`, each marks
//! the calibration unsaved until `store`, which writes the model and its switch with the
//! calibration; power-up and `reload` put the stored one in force.

use super::provenance::{Provenance, Source};
use super::{ok_with, Answer};
use crate::protocol::link::DeviceLink;
use crate::protocol::parse::ThermalCommand;
use crate::protocol::respond::Response;
use crate::protocol::ErrorCode;
use crate::thermal::model::ThermalModel;

/// The model being edited (`None` until the first edit).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ThermalEdit {
    model: Option<ThermalModel>,
}

/// One `thermal` command (the executor has checked the access rules).
pub fn command<D: DeviceLink>(
    edit: &mut ThermalEdit,
    device: &mut D,
    provenance: &mut Provenance,
    command: ThermalCommand,
) -> Answer {
    let in_force = device.thermal();
    let edited = edit.model.or(in_force.model()).unwrap_or_default();
    match command {
        ThermalCommand::Read => Ok(read(device)),
        ThermalCommand::Model => Ok(model(device)),
        ThermalCommand::Set(index, value) => {
            let mut values = edited.values();
            let slot = values
                .get_mut(usize::from(index))
                .ok_or(ErrorCode::Syntax)?;
            *slot = value;
            let name = ThermalModel::NAMES.get(usize::from(index)).unwrap_or(&"?");
            edit.model = Some(ThermalModel::from_values(values));
            Ok(ok_with(format_args!("{name}={value} model=edited")))
        }
        ThermalCommand::Apply => {
            edited.check().map_err(|_| ErrorCode::OutOfRange)?;
            device.set_thermal_model(Some(edited), true);
            edit.model = Some(edited);
            provenance.source = Source::Unsaved;
            Ok(model(device))
        }
        ThermalCommand::Enable(on) => {
            let model_in_force = in_force.model().ok_or(ErrorCode::WrongState)?;
            device.set_thermal_model(Some(model_in_force), on);
            provenance.source = Source::Unsaved;
            Ok(model(device))
        }
    }
}

/// `thermal model`: `thermal=on|off|none`, then the coefficients in force in the protocol's
/// order (`t_ref t_min t_max b0 b1 b2 b3 b_rate s0 s1 s2`) and whether they apply now.
pub fn model<D: DeviceLink>(device: &mut D) -> Response {
    let t = device.thermal();
    let switch = match (t.model(), t.enabled()) {
        (None, _) => "none",
        (Some(_), true) => "on",
        (Some(_), false) => "off",
    };
    let mut r = ok_with(format_args!("thermal={switch}"));
    if let Some(m) = t.model() {
        for (name, value) in ThermalModel::NAMES.iter().zip(m.values().iter()) {
            r.field(format_args!("{name}={value}"));
        }
    }
    r.field(format_args!("model={}", t.model_state().name()));
    r
}

/// `thermal`: the block's temperature (°C, the sensor's last result), its rate (°C/min), the
/// sensor's state, the sensor faults since boot, and whether the thermal model is applied now
/// (`applied`, or why not), with its bias (deg/h) and scale-factor (ppm) corrections when it is.
pub fn read<D: DeviceLink>(device: &mut D) -> Response {
    let t = device.thermal();
    let mut r = Response::ok();
    match t.temperature_c() {
        Some(c) => r.field(format_args!("temp_c={c:.4}")),
        None => r.field(format_args!("temp_c=none")),
    };
    match t.rate_c_per_s() {
        Some(rate) => r.field(format_args!("rate_c_min={:.3}", rate * 60.0)),
        None => r.field(format_args!("rate_c_min=none")),
    };
    r.field(format_args!(
        "sensor={} sensor_faults={} model={}",
        t.sensor().name(),
        t.faults(),
        t.model_state().name()
    ));
    if let Some(c) = t.input().correction {
        let sf = device.thermal_scale_factor_arcsec();
        r.field(format_args!(
            "bias_deg_h={:.5} sf_ppm={:.3}",
            c.bias_fringes_per_s * sf,
            c.scale_error * 1e6
        ));
    }
    r
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::protocol::commands::testing::{report, text, MemDevice};
    use crate::storage::LoadOutcome;

    fn provenance() -> Provenance {
        Provenance::new(&report(LoadOutcome::Loaded { sequence: 1 }), None, 7)
    }

    fn run(
        e: &mut ThermalEdit,
        d: &mut MemDevice,
        p: &mut Provenance,
        c: ThermalCommand,
    ) -> String {
        match command(e, d, p, c) {
            Ok(r) => text(r).trim_end().to_owned(),
            Err(code) => format!("ERR {}", code.code()),
        }
    }

    /// Edits change nothing in force; `apply` checks the whole model and puts it in force,
    /// switched on, unsaved; `off`/`on` switch it; an implausible model is refused and the one
    /// in force stays.
    #[test]
    fn edit_apply_and_switch() {
        let (mut e, mut d, mut p) = (ThermalEdit::default(), MemDevice::default(), provenance());
        let on = ThermalCommand::Enable(true);
        assert_eq!(
            run(&mut e, &mut d, &mut p, on),
            "ERR 11",
            "nothing to switch on"
        );
        let values = [
            25.0, -20.0, 60.0, 0.001, 0.002, 2e-5, -1.25e-7, 0.002, 0.0, 0.5, 0.005,
        ];
        for (i, v) in values.into_iter().enumerate() {
            let answer = run(&mut e, &mut d, &mut p, ThermalCommand::Set(i as u8, v));
            let name = ThermalModel::NAMES[i];
            assert_eq!(answer, format!("OK {name}={v} model=edited"));
        }
        let b3 = run(&mut e, &mut d, &mut p, ThermalCommand::Set(6, -1.25e-7));
        assert_eq!(b3, "OK b3=-0.000000125 model=edited");
        let beyond = run(&mut e, &mut d, &mut p, ThermalCommand::Set(11, 1.0));
        assert_eq!(beyond, "ERR 2");
        assert_eq!(d.thermal_model, None, "edits are not in force");
        assert_eq!(p, provenance());
        let applied = run(&mut e, &mut d, &mut p, ThermalCommand::Apply);
        assert!(
            applied.starts_with("OK thermal=on t_ref=25 t_min=-20 t_max=60 b0=0.001"),
            "{applied}"
        );
        assert!(applied.ends_with("s2=0.005 model=no_sensor"), "{applied}");
        let in_force = d.thermal_model.unwrap();
        assert_eq!(in_force.0.bias_deg_h, [0.001, 0.002, 2e-5, -1.25e-7]);
        assert!(in_force.1);
        assert_eq!(p.source, Source::Unsaved);

        let off = run(&mut e, &mut d, &mut p, ThermalCommand::Enable(false));
        assert!(off.starts_with("OK thermal=off"), "{off}");
        assert_eq!(d.thermal_model.map(|m| m.1), Some(false));
        assert!(run(&mut e, &mut d, &mut p, on).starts_with("OK thermal=on"));

        // A range that does not hold T_ref: refused, the model in force unchanged.
        run(&mut e, &mut d, &mut p, ThermalCommand::Set(0, 70.0));
        assert_eq!(run(&mut e, &mut d, &mut p, ThermalCommand::Apply), "ERR 5");
        assert_eq!(d.thermal_model, Some((in_force.0, true)));
        // 1000 ppm/°C over 80 °C: implausible.
        run(&mut e, &mut d, &mut p, ThermalCommand::Set(0, 25.0));
        run(&mut e, &mut d, &mut p, ThermalCommand::Set(9, 1000.0));
        assert_eq!(run(&mut e, &mut d, &mut p, ThermalCommand::Apply), "ERR 5");
        assert_eq!(d.thermal_model, Some((in_force.0, true)));
    }

    /// The first edit starts from the model in force: one edit and `apply` change one
    /// coefficient.
    #[test]
    fn the_first_edit_starts_from_the_model_in_force() {
        let (mut d, mut p) = (MemDevice::default(), provenance());
        let model = ThermalModel {
            reference_c: 20.0,
            min_c: 0.0,
            max_c: 40.0,
            bias_deg_h: [0.01, 0.0, 0.0, 0.0],
            bias_deg_h_per_c_per_min: 0.0,
            scale_ppm: [1.0, 0.0, 0.0],
        };
        d.set_thermal_model(Some(model), false);
        let mut e = ThermalEdit::default();
        run(&mut e, &mut d, &mut p, ThermalCommand::Set(8, 2.0));
        run(&mut e, &mut d, &mut p, ThermalCommand::Apply);
        let want = ThermalModel {
            scale_ppm: [2.0, 0.0, 0.0],
            ..model
        };
        assert_eq!(d.thermal_model, Some((want, true)));
        assert_eq!(
            run(&mut e, &mut d, &mut p, ThermalCommand::Model),
            "OK thermal=on t_ref=20 t_min=0 t_max=40 b0=0.01 b1=0 b2=0 b3=0 b_rate=0 s0=2 s1=0 \
             s2=0 model=no_sensor"
        );
    }
}
