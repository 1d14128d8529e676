//! Sweep results: the table on stdout, the CSV, and the figure (the paper's Fig. 3 and Fig. 4
//! in one plot, with a residual panel).

use host_cli::plot::{Figure, Panel, Series, Style};
use std::io::Write;
use std::path::Path;

/// One input rate of a sweep. Rates as beat frequency in Hz, as in the paper's figures.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SweepRow {
    /// The table's input rate, deg/h.
    pub input_deg_h: f64,
    /// The ideal output, input / scale factor: fringes per second, Hz.
    pub ideal_hz: f64,
    /// The gyro's output without compensation (lock-in included), Hz.
    pub uncompensated_hz: f64,
    /// The output with the firmware's a P1 + b P2 compensation, Hz.
    pub compensated_hz: f64,
}

/// The CSV header, exactly as the issue specifies.
pub const CSV_HEADER: &str = "input_deg_h,ideal_hz,uncompensated_hz,compensated_hz";

/// Writes the rows to `path` as CSV under [`CSV_HEADER`] (full precision, no rounding).
pub fn write_csv(path: &Path, rows: &[SweepRow]) -> std::io::Result<()> {
    let mut out = std::io::BufWriter::new(std::fs::File::create(path)?);
    writeln!(out, "{CSV_HEADER}")?;
    for r in rows {
        writeln!(
            out,
            "{},{},{},{}",
            r.input_deg_h, r.ideal_hz, r.uncompensated_hz, r.compensated_hz
        )?;
    }
    out.flush()
}

/// The table printed on stdout: Hz columns plus the deviations from ideal in deg/h.
pub fn table(rows: &[SweepRow], scale_factor_arcsec: f64) -> String {
    let mut s = format!(
        "{:>12} {:>12} {:>16} {:>14} {:>14} {:>14}\n",
        "input_deg_h",
        "ideal_hz",
        "uncompensated_hz",
        "compensated_hz",
        "uncomp_err_dph",
        "comp_err_dph"
    );
    for r in rows {
        s.push_str(&format!(
            "{:>12.4} {:>12.6} {:>16.6} {:>14.6} {:>14.5} {:>14.5}\n",
            r.input_deg_h,
            r.ideal_hz,
            r.uncompensated_hz,
            r.compensated_hz,
            (r.uncompensated_hz - r.ideal_hz) * scale_factor_arcsec,
            (r.compensated_hz - r.ideal_hz) * scale_factor_arcsec,
        ));
    }
    s
}

/// The figure: output vs input for ideal, uncompensated and compensated; the deviations from
/// ideal (deg/h) below; and the compensated deviation alone, at its own scale.
pub fn figure(rows: &[SweepRow], scale_factor_arcsec: f64, title: &str) -> Figure {
    let pts = |f: &dyn Fn(&SweepRow) -> f64| rows.iter().map(|r| (r.input_deg_h, f(r))).collect();
    Figure {
        title: title.into(),
        x_label: "input rate (deg/h)".into(),
        width_px: 900.0,
        height_px: 960.0,
        axes: host_cli::plot::Axes::Linear,
        panels: vec![
            Panel {
                title: "gyro output (Fig. 3 uncompensated, Fig. 4 compensated)".into(),
                y_label: "output (Hz)".into(),
                weight: 2.0,
                series: vec![
                    Series {
                        label: "ideal".into(),
                        points: pts(&|r| r.ideal_hz),
                        color: "#888888",
                        style: Style::DashedLine,
                    },
                    Series {
                        label: "uncompensated".into(),
                        points: pts(&|r| r.uncompensated_hz),
                        color: "#d62728",
                        style: Style::LineAndMarkers,
                    },
                    Series {
                        label: "compensated".into(),
                        points: pts(&|r| r.compensated_hz),
                        color: "#1f77b4",
                        style: Style::LineAndMarkers,
                    },
                ],
            },
            Panel {
                title: "deviation from ideal".into(),
                y_label: "output - ideal (deg/h)".into(),
                weight: 1.0,
                series: vec![
                    Series {
                        label: "uncompensated".into(),
                        points: pts(&|r| (r.uncompensated_hz - r.ideal_hz) * scale_factor_arcsec),
                        color: "#d62728",
                        style: Style::LineAndMarkers,
                    },
                    Series {
                        label: "compensated".into(),
                        points: pts(&|r| (r.compensated_hz - r.ideal_hz) * scale_factor_arcsec),
                        color: "#1f77b4",
                        style: Style::LineAndMarkers,
                    },
                ],
            },
            Panel {
                title: "compensated deviation, at its own scale".into(),
                y_label: "output - ideal (deg/h)".into(),
                weight: 1.0,
                series: vec![Series {
                    label: "compensated".into(),
                    points: pts(&|r| (r.compensated_hz - r.ideal_hz) * scale_factor_arcsec),
                    color: "#1f77b4",
                    style: Style::LineAndMarkers,
                }],
            },
        ],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn csv_has_exactly_the_specified_columns() {
        let dir = std::env::temp_dir().join(format!("rlg-sim-csv-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("sweep.csv");
        let rows = [SweepRow {
            input_deg_h: -1.5,
            ideal_hz: -0.804,
            uncompensated_hz: 0.0,
            compensated_hz: -0.8039,
        }];
        write_csv(&path, &rows).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        let mut lines = text.lines();
        assert_eq!(lines.next(), Some(CSV_HEADER));
        let fields: Vec<f64> = lines
            .next()
            .unwrap()
            .split(',')
            .map(|f| f.parse().unwrap())
            .collect();
        assert_eq!(fields, vec![-1.5, -0.804, 0.0, -0.8039]);
        assert_eq!(lines.next(), None);
        std::fs::remove_dir_all(dir).unwrap();
    }
}
