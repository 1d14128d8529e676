//! `rlg-sim characterize --thermal`: IEEE Std 647's bias and scale factor over temperature
//! ([`crate::thermal::procedure`]: the thermal calibration, then its check with the model off
//! and on), written as `thermal.csv`, `thermal.svg` and the report's section.

use crate::thermal::procedure::{ThermalOutcome, ThermalPlan};
use host_cli::plot::{Axes, Figure, Panel, Series, Style};
use std::fmt::Write as _;

/// `thermal.csv`'s header (one row per check soak).
pub const CSV_HEADER: &str = "temperature_c,bias_raw_deg_h,bias_compensated_deg_h,\
scale_factor_raw_ppm,scale_factor_compensated_ppm";

/// `thermal.csv`: each check soak, model off (raw) and on (compensated).
pub fn csv(outcome: &ThermalOutcome) -> String {
    let mut s = format!("{CSV_HEADER}\n");
    for p in &outcome.soaks {
        let _ = writeln!(
            s,
            "{:.3},{:.6},{:.6},{:.4},{:.4}",
            p.temperature_c,
            p.bias_raw_deg_h,
            p.bias_compensated_deg_h,
            p.scale_factor_raw_ppm,
            p.scale_factor_compensated_ppm
        );
    }
    s
}

/// `thermal.svg`: bias and scale-factor error against temperature, model off and on.
pub fn chart(outcome: &ThermalOutcome, title: &str) -> Figure {
    let series =
        |label: &str, color, f: &dyn Fn(&crate::thermal::procedure::SoakCheck) -> f64| Series {
            label: label.into(),
            points: outcome
                .soaks
                .iter()
                .map(|p| (p.temperature_c, f(p)))
                .collect(),
            color,
            style: Style::LineAndMarkers,
        };
    Figure {
        title: title.into(),
        x_label: "block temperature (C)".into(),
        panels: vec![
            Panel {
                title: "bias at each soak (static, Earth rate)".into(),
                y_label: "bias (deg/h)".into(),
                series: vec![
                    series("model off", "#d62728", &|p| p.bias_raw_deg_h),
                    series("model on", "#1f77b4", &|p| p.bias_compensated_deg_h),
                ],
                weight: 1.0,
            },
            Panel {
                title: "scale-factor error at each soak (+-R on the table)".into(),
                y_label: "scale-factor error (ppm)".into(),
                series: vec![
                    series("model off", "#d62728", &|p| p.scale_factor_raw_ppm),
                    series("model on", "#1f77b4", &|p| p.scale_factor_compensated_ppm),
                ],
                weight: 1.0,
            },
        ],
        width_px: 900.0,
        height_px: 700.0,
        axes: Axes::Linear,
    }
}

fn worst(values: impl Iterator<Item = f64>) -> f64 {
    values.map(f64::abs).fold(0.0, f64::max)
}

/// The report's section.
pub fn markdown(outcome: &ThermalOutcome, plan: &ThermalPlan) -> String {
    let m = &outcome.calibration.model;
    let r = &outcome.ramp;
    let soaks = &outcome.soaks;
    let mut s = String::from("## Bias and scale factor over temperature (IEEE 647)\n\n");
    let _ = writeln!(
        s,
        "The thermal calibration (the board's `thermal set`/`thermal apply` model, fitted by \
         `firmware::thermal::fit`): bias on ramps between {} and {} C at up to {} C/s with the \
         gyro at {} deg/h, scale factor on soaks at {:?} C with the table at +-{} deg/s. Model \
         (T_ref {} C, valid {:.2}..{:.2} C): bias {:.3e} + {:.3e} x + {:.3e} x^2 + {:.3e} x^3 \
         + {:.3e} dT/dt deg/h (x = T - T_ref in C, dT/dt in C/min); scale factor {:.3} + {:.4} x \
         + {:.5} x^2 ppm.\n",
        plan_extreme(plan, f64::min),
        plan_extreme(plan, f64::max),
        max_ramp_c_per_s(&plan.calibration_knots),
        plan.static_input_deg_h,
        plan.calibration_soaks_c,
        plan.table_deg_h / 3600.0,
        m.reference_c,
        m.min_c,
        m.max_c,
        m.bias_deg_h[0],
        m.bias_deg_h[1],
        m.bias_deg_h[2],
        m.bias_deg_h[3],
        m.bias_deg_h_per_c_per_min,
        m.scale_ppm[0],
        m.scale_ppm[1],
        m.scale_ppm[2],
    );
    let _ = writeln!(
        s,
        "| check | model off | model on |\n| --- | --- | --- |\n\
         | ramp {:?}: bias, rms of every {} s window (deg/h) | {:.5} | {:.5} ({:.1}x smaller) |\n\
         | the same clear of the ramp's start, where the rate estimate lags (deg/h) | {:.5} | \
         {:.5} |\n\
         | soaks {:.0}..{:.0} C: worst bias (deg/h) | {:.5} | {:.5} |\n\
         | soaks: worst scale-factor error (ppm) | {:.3} | {:.3} |\n",
        plan.check_knots,
        crate::thermal::procedure::BIAS_WINDOW_S,
        r.raw_rms_all_deg_h,
        r.corrected_rms_all_deg_h,
        r.raw_rms_all_deg_h / r.corrected_rms_all_deg_h,
        r.raw_rms_deg_h,
        r.corrected_rms_deg_h,
        soaks.first().map_or(f64::NAN, |p| p.temperature_c),
        soaks.last().map_or(f64::NAN, |p| p.temperature_c),
        worst(soaks.iter().map(|p| p.bias_raw_deg_h)),
        worst(soaks.iter().map(|p| p.bias_compensated_deg_h)),
        worst(soaks.iter().map(|p| p.scale_factor_raw_ppm)),
        worst(soaks.iter().map(|p| p.scale_factor_compensated_ppm)),
    );
    s.push_str(
        "Each soak: 2 s transition, 3 s settling, 5 s static (the bias: the slope of the \
         integrated angle error), then +R and -R for 2.5 s each (the scale factor, the bias \
         cancelling). The profiles are compressed in time against a thermal chamber's; the \
         rows are in `thermal.csv`.\n\n![bias and scale factor over temperature](thermal.svg)\n\n",
    );
    s
}

fn plan_extreme(plan: &ThermalPlan, pick: fn(f64, f64) -> f64) -> f64 {
    plan.calibration_knots
        .iter()
        .map(|k| k.1)
        .fold(plan.calibration_knots[0].1, pick)
}

fn max_ramp_c_per_s(knots: &[(f64, f64)]) -> f64 {
    knots
        .windows(2)
        .map(|w| ((w[1].1 - w[0].1) / (w[1].0 - w[0].0)).abs())
        .fold(0.0, f64::max)
}
