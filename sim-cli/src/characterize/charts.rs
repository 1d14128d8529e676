//! The report's SVG figures (drawn by [`host_cli::plot`]): the scale-factor residuals against
//! the input rate, and the output near zero with the dead band. The Allan deviation plots are
//! the `allan` module's own ([`crate::allan::output::figure`]).

use super::figures::{resolved, RatePoint};
use super::procedure::ConfigurationResult;
use crate::allan::output::adev_figure;
use host_cli::plot::{Axes, Figure, Panel, Series, Style};

/// One colour per configuration, in order.
const COLORS: [&str; 4] = ["#d62728", "#1f77b4", "#2ca02c", "#9467bd"];

fn color(i: usize) -> &'static str {
    COLORS[i % COLORS.len()]
}

/// Residuals from each configuration's least-squares line, ppm of full scale, against the
/// input rate in deg/s.
pub fn residuals(results: &[ConfigurationResult], title: &str) -> Figure {
    let series = results
        .iter()
        .enumerate()
        .filter_map(|(i, r)| {
            let sf = r.scale_factor.as_ref()?;
            Some(Series {
                label: format!(
                    "{}: non-linearity {:.3} ppm FS",
                    r.configuration.name, sf.nonlinearity_ppm
                ),
                points: sf
                    .residuals_ppm
                    .iter()
                    .map(|&(x, ppm)| (x / 3600.0, ppm))
                    .collect(),
                color: color(i),
                style: Style::LineAndMarkers,
            })
        })
        .collect();
    Figure {
        title: title.into(),
        x_label: "input rate (deg/s)".into(),
        panels: vec![Panel {
            title: "residual from the least-squares scale factor (linear-range points)".into(),
            y_label: "residual (ppm of full scale)".into(),
            series,
            weight: 1.0,
        }],
        width_px: 900.0,
        height_px: 600.0,
        axes: Axes::Linear,
    }
}

/// The dense points near zero: the bias-corrected output against the input with the
/// scale-factor line (dashed), and the error from that line; resolved points (the 50 %
/// criterion) as markers on the error panel.
pub fn dead_band(results: &[ConfigurationResult], title: &str) -> Figure {
    let mut output = Vec::new();
    let mut error = Vec::new();
    for (i, r) in results.iter().enumerate() {
        let (Some(sf), Some(f)) = (&r.scale_factor, &r.static_figures) else {
            continue;
        };
        let (k, bias) = (sf.line.slope, f.bias_deg_h);
        let dense: Vec<&RatePoint> = r.points.iter().filter(|p| !p.linear_range).collect();
        output.push(Series {
            label: r.configuration.name.clone(),
            points: dense
                .iter()
                .map(|p| (p.input_deg_h, p.output_deg_h - bias))
                .collect(),
            color: color(i),
            style: Style::LineAndMarkers,
        });
        error.push(Series {
            label: format!("{}: output - bias - SF x input", r.configuration.name),
            points: dense
                .iter()
                .map(|p| (p.input_deg_h, p.output_deg_h - bias - k * p.input_deg_h))
                .collect(),
            color: color(i),
            style: Style::Line,
        });
        error.push(Series {
            label: format!("{}: resolved (within 50 %)", r.configuration.name),
            points: dense
                .iter()
                .filter(|p| resolved(p, k, bias))
                .map(|p| (p.input_deg_h, p.output_deg_h - bias - k * p.input_deg_h))
                .collect(),
            color: color(i),
            style: Style::Markers,
        });
    }
    let span = results
        .iter()
        .flat_map(|r| r.points.iter().filter(|p| !p.linear_range))
        .map(|p| p.input_deg_h.abs())
        .fold(0.0, f64::max);
    output.push(Series {
        label: "ideal (output = input)".into(),
        points: vec![(-span, -span), (span, span)],
        color: "#888888",
        style: Style::DashedLine,
    });
    Figure {
        title: title.into(),
        x_label: "input rate (deg/h)".into(),
        panels: vec![
            Panel {
                title: "output near zero (bias removed)".into(),
                y_label: "output (deg/h)".into(),
                series: output,
                weight: 2.0,
            },
            Panel {
                title: "error from the scale-factor line".into(),
                y_label: "error (deg/h)".into(),
                series: error,
                weight: 1.0,
            },
        ],
        width_px: 900.0,
        height_px: 800.0,
        axes: Axes::Linear,
    }
}

/// The static records' Allan deviations on one log-log plot (one colour per configuration),
/// each significant fitted ARW as its dashed -1/2 line `60 N / sqrt(tau)`; `None` when no
/// record has a deviation.
pub fn allan_compare(results: &[ConfigurationResult], title: &str) -> Option<Figure> {
    let mut series = Vec::new();
    for (i, r) in results.iter().enumerate() {
        let Some(Ok(a)) = r.static_figures.as_ref().map(|f| &f.allan) else {
            continue;
        };
        let taus: Vec<f64> = a.rows.iter().map(|row| row.tau_s).collect();
        series.push(Series {
            label: format!("{}: overlapping ADEV", r.configuration.name),
            points: a
                .rows
                .iter()
                .map(|row| (row.tau_s, row.adev_deg_h))
                .collect(),
            color: color(i),
            style: Style::LineAndMarkers,
        });
        if let Some(n) = a.fit.arw_deg_rt_h.filter(|n| n.significant) {
            series.push(Series {
                label: format!(
                    "{}: ARW N = {:.3e} deg/sqrt(h)",
                    r.configuration.name, n.value
                ),
                points: taus
                    .iter()
                    .map(|&t| (t, 60.0 * n.value / t.sqrt()))
                    .collect(),
                color: color(i),
                style: Style::DashedLine,
            });
        }
    }
    (!series.is_empty())
        .then(|| adev_figure(title, "Allan deviation of the static records", series))
}
