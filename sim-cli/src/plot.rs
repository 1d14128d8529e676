//! A small, dependency-free SVG line chart: stacked panels sharing one x axis.
//!
//! Enough for the paper's figures (output vs input with a residual panel) and streamed rates:
//! linear axes with "nice" ticks, polylines and/or markers, a legend per panel. Pure string
//! output, so it is testable and needs no font or rendering library.

use std::fmt::Write;

/// How a series is drawn.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Style {
    Line,
    DashedLine,
    Markers,
    LineAndMarkers,
}

/// One curve.
#[derive(Clone, Debug)]
pub struct Series {
    pub label: String,
    pub points: Vec<(f64, f64)>,
    pub color: &'static str,
    pub style: Style,
}

/// One panel: its own y axis, the x axis shared with the figure.
#[derive(Clone, Debug)]
pub struct Panel {
    pub title: String,
    pub y_label: String,
    pub series: Vec<Series>,
    /// Relative height (the residual panel is usually smaller).
    pub weight: f64,
}

/// A figure of stacked panels.
#[derive(Clone, Debug)]
pub struct Figure {
    pub title: String,
    pub x_label: String,
    pub panels: Vec<Panel>,
    pub width_px: f64,
    pub height_px: f64,
}

const MARGIN_LEFT: f64 = 90.0;
const MARGIN_RIGHT: f64 = 30.0;
const MARGIN_TOP: f64 = 75.0;
const MARGIN_BOTTOM: f64 = 60.0;
const PANEL_GAP: f64 = 50.0;

/// "Nice" tick positions covering [lo, hi]: steps of 1, 2 or 5 x 10^n, about `target` of them.
pub fn nice_ticks(lo: f64, hi: f64, target: usize) -> Vec<f64> {
    if !(lo.is_finite() && hi.is_finite()) || hi <= lo {
        return vec![lo];
    }
    let raw = (hi - lo) / target.max(1) as f64;
    let magnitude = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 5.0, 10.0]
        .iter()
        .map(|m| m * magnitude)
        .find(|s| *s >= raw)
        .unwrap_or(10.0 * magnitude);
    let first = (lo / step).ceil() as i64;
    let last = (hi / step).floor() as i64;
    (first..=last).map(|i| i as f64 * step).collect()
}

fn format_tick(v: f64) -> String {
    if v == 0.0 {
        return "0".into();
    }
    let a = v.abs();
    if !(1e-3..1e5).contains(&a) {
        format!("{v:.1e}")
    } else {
        let s = format!("{v:.6}");
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    }
}

fn escape(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// Data range of some points, widened a little (and made non-empty).
fn range(points: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = points
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), v| {
            (l.min(v), h.max(v))
        });
    if !lo.is_finite() {
        return (-1.0, 1.0);
    }
    if hi - lo < 1e-12 * lo.abs().max(1e-300) {
        let pad = if lo == 0.0 { 1.0 } else { lo.abs() * 0.1 };
        return (lo - pad, hi + pad);
    }
    let pad = 0.05 * (hi - lo);
    (lo - pad, hi + pad)
}

impl Figure {
    /// Renders the figure as a standalone SVG document.
    pub fn to_svg(&self) -> String {
        let mut svg = String::new();
        let (w, h) = (self.width_px, self.height_px);
        let _ = writeln!(
            svg,
            r#"<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" viewBox="0 0 {w} {h}" font-family="sans-serif" font-size="13">"#
        );
        let _ = writeln!(svg, r#"<rect width="{w}" height="{h}" fill="white"/>"#);
        let _ = writeln!(
            svg,
            r#"<text x="{}" y="28" text-anchor="middle" font-size="17">{}</text>"#,
            w / 2.0,
            escape(&self.title)
        );
        let xs = self
            .panels
            .iter()
            .flat_map(|p| p.series.iter().flat_map(|s| s.points.iter().map(|p| p.0)));
        let (x_lo, x_hi) = range(xs);
        let plot_w = w - MARGIN_LEFT - MARGIN_RIGHT;
        let total_weight: f64 = self.panels.iter().map(|p| p.weight).sum::<f64>().max(1e-9);
        let available = h
            - MARGIN_TOP
            - MARGIN_BOTTOM
            - PANEL_GAP * (self.panels.len().saturating_sub(1)) as f64;
        let mut top = MARGIN_TOP;
        for (i, panel) in self.panels.iter().enumerate() {
            let panel_h = available * panel.weight / total_weight;
            let last = i + 1 == self.panels.len();
            self.render_panel(
                &mut svg,
                panel,
                (x_lo, x_hi),
                (MARGIN_LEFT, top, plot_w, panel_h),
                last,
            );
            top += panel_h + PANEL_GAP;
        }
        svg.push_str("</svg>\n");
        svg
    }

    fn render_panel(
        &self,
        svg: &mut String,
        panel: &Panel,
        (x_lo, x_hi): (f64, f64),
        (left, top, width, height): (f64, f64, f64, f64),
        last: bool,
    ) {
        let (y_lo, y_hi) = range(
            panel
                .series
                .iter()
                .flat_map(|s| s.points.iter().map(|p| p.1)),
        );
        let px = |x: f64| left + (x - x_lo) / (x_hi - x_lo) * width;
        let py = |y: f64| top + height - (y - y_lo) / (y_hi - y_lo) * height;
        let _ = writeln!(
            svg,
            r##"<rect x="{left}" y="{top}" width="{width}" height="{height}" fill="none" stroke="#444"/>"##
        );
        for t in nice_ticks(x_lo, x_hi, 8) {
            let x = px(t);
            let _ = writeln!(
                svg,
                r##"<line x1="{x:.1}" y1="{top}" x2="{x:.1}" y2="{:.1}" stroke="#ddd"/>"##,
                top + height
            );
            if last {
                let _ = writeln!(
                    svg,
                    r#"<text x="{x:.1}" y="{:.1}" text-anchor="middle">{}</text>"#,
                    top + height + 18.0,
                    format_tick(t)
                );
            }
        }
        for t in nice_ticks(y_lo, y_hi, 6) {
            let y = py(t);
            let _ = writeln!(
                svg,
                r##"<line x1="{left}" y1="{y:.1}" x2="{:.1}" y2="{y:.1}" stroke="#ddd"/>"##,
                left + width
            );
            let _ = writeln!(
                svg,
                r#"<text x="{:.1}" y="{:.1}" text-anchor="end">{}</text>"#,
                left - 6.0,
                y + 4.0,
                format_tick(t)
            );
        }
        if y_lo < 0.0 && y_hi > 0.0 {
            let y = py(0.0);
            let _ = writeln!(
                svg,
                r##"<line x1="{left}" y1="{y:.1}" x2="{:.1}" y2="{y:.1}" stroke="#999"/>"##,
                left + width
            );
        }
        let _ = writeln!(
            svg,
            r#"<text x="{:.1}" y="{:.1}" text-anchor="middle" transform="rotate(-90 {:.1} {:.1})">{}</text>"#,
            left - 62.0,
            top + height / 2.0,
            left - 62.0,
            top + height / 2.0,
            escape(&panel.y_label)
        );
        let _ = writeln!(
            svg,
            r#"<text x="{:.1}" y="{:.1}" text-anchor="middle" font-size="14">{}</text>"#,
            left + width / 2.0,
            top - 8.0,
            escape(&panel.title)
        );
        if last {
            let _ = writeln!(
                svg,
                r#"<text x="{:.1}" y="{:.1}" text-anchor="middle">{}</text>"#,
                left + width / 2.0,
                top + height + 42.0,
                escape(&self.x_label)
            );
        }
        for (i, series) in panel.series.iter().enumerate() {
            draw_series(svg, series, &px, &py);
            let ly = top + 16.0 + 18.0 * i as f64;
            let lx = left + 12.0;
            let dash = if series.style == Style::DashedLine {
                r#" stroke-dasharray="6 4""#
            } else {
                ""
            };
            let _ = writeln!(
                svg,
                r#"<line x1="{lx}" y1="{ly}" x2="{}" y2="{ly}" stroke="{}" stroke-width="2"{dash}/><text x="{}" y="{}">{}</text>"#,
                lx + 24.0,
                series.color,
                lx + 30.0,
                ly + 4.0,
                escape(&series.label)
            );
        }
    }
}

fn draw_series(svg: &mut String, s: &Series, px: &dyn Fn(f64) -> f64, py: &dyn Fn(f64) -> f64) {
    let finite: Vec<(f64, f64)> = s
        .points
        .iter()
        .copied()
        .filter(|(x, y)| x.is_finite() && y.is_finite())
        .collect();
    if matches!(
        s.style,
        Style::Line | Style::DashedLine | Style::LineAndMarkers
    ) && finite.len() > 1
    {
        let path: Vec<String> = finite
            .iter()
            .map(|&(x, y)| format!("{:.2},{:.2}", px(x), py(y)))
            .collect();
        let dash = if s.style == Style::DashedLine {
            r#" stroke-dasharray="6 4""#
        } else {
            ""
        };
        let _ = writeln!(
            svg,
            r#"<polyline points="{}" fill="none" stroke="{}" stroke-width="1.8"{dash}/>"#,
            path.join(" "),
            s.color
        );
    }
    if matches!(s.style, Style::Markers | Style::LineAndMarkers) {
        for &(x, y) in &finite {
            let _ = writeln!(
                svg,
                r#"<circle cx="{:.2}" cy="{:.2}" r="3" fill="{}"/>"#,
                px(x),
                py(y),
                s.color
            );
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ticks_are_nice_and_cover_the_range() {
        assert_eq!(
            nice_ticks(-13.9, 13.9, 8),
            vec![-10.0, -5.0, 0.0, 5.0, 10.0]
        );
        let t = nice_ticks(0.0, 1.0, 5);
        assert_eq!(t.len(), 6);
        assert!((t[1] - 0.2).abs() < 1e-12);
        assert_eq!(nice_ticks(1.0, 1.0, 5), vec![1.0]);
    }

    #[test]
    fn svg_is_well_formed_and_escapes_text() {
        let fig = Figure {
            title: "a < b & c".into(),
            x_label: "input (deg/h)".into(),
            panels: vec![Panel {
                title: "out".into(),
                y_label: "Hz".into(),
                series: vec![Series {
                    label: "ideal".into(),
                    points: vec![(0.0, 0.0), (1.0, 2.0), (2.0, f64::NAN)],
                    color: "black",
                    style: Style::LineAndMarkers,
                }],
                weight: 1.0,
            }],
            width_px: 800.0,
            height_px: 600.0,
        };
        let svg = fig.to_svg();
        assert!(svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"));
        assert!(svg.contains("a &lt; b &amp; c"));
        assert_eq!(svg.matches("<circle").count(), 2, "NaN points are skipped");
        assert_eq!(svg.matches('<').count(), svg.matches('>').count());
    }
}
