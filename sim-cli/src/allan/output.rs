//! What `rlg-sim allan` writes: the table (stdout), the CSV and the log-log figure.
//!
//! The CSV has exactly the columns `tau_s,adev_deg_h,ci_low_deg_h,ci_high_deg_h` in 13
//! significant digits (the allantools comparison in `.ci/run` checks 1e-9 relative). The
//! figure draws the deviation with its interval, the fitted model, and each fitted term as
//! its straight line with its slope and value in the legend.

use super::estimator::NoiseType;
use super::fit::{Term, FLOOR_FACTOR};
use super::input::RateRecord;
use super::Analysis;
use host_cli::plot::{Axes, Figure, Panel, Series, Style};
use std::fmt::Write;

/// The CSV header.
pub const CSV_HEADER: &str = "tau_s,adev_deg_h,ci_low_deg_h,ci_high_deg_h";

fn noise_name(noise: NoiseType) -> &'static str {
    match noise {
        NoiseType::Quantisation => "quantisation",
        NoiseType::AngleRandomWalk => "ARW",
        NoiseType::BiasInstability => "bias inst.",
        NoiseType::RateRandomWalk => "RRW",
    }
}

/// The term's value and interval, or `not resolved`.
fn term_text(term: Option<Term>, unit: &str) -> String {
    let text = term_interval(term, unit);
    match term {
        Some(t) if !t.significant => format!("{text}  (not significant: below 2 sigma)"),
        _ => text,
    }
}

fn term_interval(term: Option<Term>, unit: &str) -> String {
    match term {
        // Fewer than about one degree of freedom: the upper end is meaningless.
        Some(t) if t.high > 1e3 * t.value => {
            format!("{:.4e} {unit}  [{:.4e}, unbounded]", t.value, t.low)
        }
        Some(t) => format!("{:.4e} {unit}  [{:.4e}, {:.4e}]", t.value, t.low, t.high),
        None => "not resolved (the fit needs no such term)".into(),
    }
}

/// How the record was read: rows, period, gaps and how they are handled.
pub fn record_summary(record: &RateRecord) -> String {
    let segments = record.segments().len();
    format!(
        "{} rows, sample period {:.9} s ({:.3} Hz), {} valid samples; {} invalid or lost rows \
         and {} missing samples are gaps: {} runs of valid samples, Allan differences only \
         within a run (no angle spliced across a gap)",
        record.rows,
        record.period_s,
        1.0 / record.period_s,
        record.valid_samples(),
        record.invalid_rows,
        record.missing_samples,
        segments,
    )
}

/// The table and the fitted terms, as printed on stdout.
pub fn table(analysis: &Analysis) -> String {
    let mut s = String::new();
    let pct = 100.0 * analysis.fit.confidence;
    let _ = writeln!(
        s,
        "{:>14} {:>14} {:>14} {:>14} {:>12} {:>13} {:>12}",
        "tau_s", "adev_deg_h", "ci_low_deg_h", "ci_high_deg_h", "edf", "noise (edf)", "differences"
    );
    for r in &analysis.rows {
        let _ = writeln!(
            s,
            "{:>14.6e} {:>14.6e} {:>14.6e} {:>14.6e} {:>12.1} {:>13} {:>12}",
            r.tau_s,
            r.adev_deg_h,
            r.ci_low_deg_h,
            r.ci_high_deg_h,
            r.edf,
            noise_name(r.noise),
            r.terms
        );
    }
    let f = &analysis.fit;
    let _ = writeln!(
        s,
        "\nnoise terms (IEEE 952 model fitted to the Allan variance, {pct:.1} % intervals):"
    );
    let _ = writeln!(
        s,
        "  quantisation      Q = {}",
        term_text(f.quantisation_arcsec, "arcsec")
    );
    let _ = writeln!(
        s,
        "  angle random walk N = {}",
        term_text(f.arw_deg_rt_h, "deg/sqrt(h)")
    );
    let _ = writeln!(
        s,
        "  bias instability  B = {}",
        term_text(f.bias_instability_deg_h, "deg/h")
    );
    if let Some(b) = f.bias_instability_deg_h {
        let _ = writeln!(
            s,
            "                    (the floor 0.664 B = {:.4e} deg/h)",
            FLOOR_FACTOR * b.value
        );
    }
    let _ = writeln!(
        s,
        "  rate random walk  K = {}",
        term_text(f.rrw_deg_h_rt_h, "deg/h/sqrt(h)")
    );
    s
}

/// The CSV: header and one row per tau.
pub fn csv(analysis: &Analysis) -> String {
    let mut s = format!("{CSV_HEADER}\n");
    for r in &analysis.rows {
        let _ = writeln!(
            s,
            "{:.12e},{:.12e},{:.12e},{:.12e}",
            r.tau_s, r.adev_deg_h, r.ci_low_deg_h, r.ci_high_deg_h
        );
    }
    s
}

/// The log-log figure: deviation, interval, model, and each term's line.
pub fn figure(analysis: &Analysis, title: &str) -> Figure {
    let rows = &analysis.rows;
    let (t_lo, t_hi) = (
        rows.first().map_or(1.0, |r| r.tau_s),
        rows.last().map_or(1.0, |r| r.tau_s),
    );
    // 8 points per decade over the taus, for the model's curve.
    let decades = (t_hi / t_lo).log10().max(0.0);
    let n = (decades * 8.0).ceil() as usize + 1;
    let taus: Vec<f64> = (0..n)
        .map(|i| t_lo * 10f64.powf(decades * i as f64 / (n - 1).max(1) as f64))
        .collect();
    let fit = &analysis.fit;
    let line = |label: String, color, points: Vec<(f64, f64)>, style| Series {
        label,
        points,
        color,
        style,
    };
    let mut series = vec![
        line(
            format!("overlapping ADEV, {:.1} % interval", 100.0 * fit.confidence),
            "#1f77b4",
            rows.iter().map(|r| (r.tau_s, r.adev_deg_h)).collect(),
            Style::LineAndMarkers,
        ),
        line(
            "interval, upper end".into(),
            "#9ecae1",
            rows.iter().map(|r| (r.tau_s, r.ci_high_deg_h)).collect(),
            Style::Markers,
        ),
        line(
            "interval, lower end".into(),
            "#9ecae1",
            rows.iter().map(|r| (r.tau_s, r.ci_low_deg_h)).collect(),
            Style::Markers,
        ),
        line(
            "fitted model".into(),
            "#000000",
            taus.iter().map(|&t| (t, fit.avar(t).sqrt())).collect(),
            Style::Line,
        ),
    ];
    let terms = [
        (
            0,
            fit.quantisation_arcsec,
            "slope -1: Q",
            "arcsec",
            "#9467bd",
        ),
        (
            1,
            fit.arw_deg_rt_h,
            "slope -1/2: N",
            "deg/sqrt(h)",
            "#d62728",
        ),
        (
            2,
            fit.bias_instability_deg_h,
            "slope 0: B",
            "deg/h (floor 0.664 B)",
            "#2ca02c",
        ),
        (
            3,
            fit.rrw_deg_h_rt_h,
            "slope +1/2: K",
            "deg/h/sqrt(h)",
            "#ff7f0e",
        ),
    ];
    for (k, term, name, unit, color) in terms {
        if let Some(t) = term {
            series.push(line(
                format!(
                    "{name} = {:.3e} {unit}{}",
                    t.value,
                    if t.significant {
                        ""
                    } else {
                        " (not significant)"
                    }
                ),
                color,
                taus.iter()
                    .map(|&tau| (tau, fit.term_avar(k, tau).sqrt()))
                    .collect(),
                Style::DashedLine,
            ));
        }
    }
    adev_figure(title, "Allan deviation of the rate", series)
}

/// The log-log ADEV-against-tau frame of `series` (this module's figure and `characterize`'s
/// comparison of the static records).
pub fn adev_figure(title: &str, panel_title: &str, series: Vec<Series>) -> Figure {
    Figure {
        title: title.into(),
        x_label: "tau (s)".into(),
        panels: vec![Panel {
            title: panel_title.into(),
            y_label: "ADEV (deg/h)".into(),
            series,
            weight: 1.0,
        }],
        width_px: 900.0,
        height_px: 650.0,
        axes: Axes::LogLog,
    }
}
