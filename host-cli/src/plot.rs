//! Line charts as SVG, drawn with `plotters` (SVG backend only): stacked panels sharing one x
//! axis, for the paper's figures (output vs input with residual panels, `rlg-sim sweep`) and
//! streamed rates (`rlg-cal stream`, `rlg-cal sweep`). The one plotting module of the project.
//!
//! The description ([`Figure`], [`Panel`], [`Series`]) is plain data; [`Figure::to_svg`] lays
//! it out: panel heights by weight, one x range over all panels, each panel its own y range
//! (padded 5 %), tick labels on the bottom panel only, a legend per panel. plotters chooses
//! the ticks and writes the SVG; non-finite points are skipped. plotters (4 small crates, no
//! font or rendering library with these features) does the axes, ticks, legends and escaping.

use plotters::prelude::*;

/// How a series is drawn.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Style {
    /// A solid line through the points.
    Line,
    /// A dashed line (6 px dash, 4 px gap), e.g. the ideal or expected curve.
    DashedLine,
    /// A dot at each point, no line.
    Markers,
    /// A solid line with a dot at each point.
    LineAndMarkers,
}

/// One curve.
#[derive(Clone, Debug)]
pub struct Series {
    /// Legend text.
    pub label: String,
    /// (x, y) in the axes' units; non-finite points are skipped.
    pub points: Vec<(f64, f64)>,
    /// `#rrggbb`; anything else draws black.
    pub color: &'static str,
    /// Line, dashes, markers or both.
    pub style: Style,
}

/// One panel: its own y axis, the x axis shared with the figure.
#[derive(Clone, Debug)]
pub struct Panel {
    /// Caption above the panel.
    pub title: String,
    /// Y axis label, with its unit.
    pub y_label: String,
    /// The curves, drawn in order; the legend lists them.
    pub series: Vec<Series>,
    /// Relative height (the residual panel is usually smaller).
    pub weight: f64,
}

/// A figure of stacked panels.
#[derive(Clone, Debug)]
pub struct Figure {
    /// Title above all panels.
    pub title: String,
    /// X axis label, with its unit (shown under the bottom panel).
    pub x_label: String,
    /// The panels, top to bottom.
    pub panels: Vec<Panel>,
    /// SVG width, px (truncated to whole pixels).
    pub width_px: f64,
    /// SVG height, px (truncated to whole pixels).
    pub height_px: f64,
    /// Linear axes, or logarithmic x and y (the Allan deviation).
    pub axes: Axes,
}

/// The scale of the axes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Axes {
    /// Linear x and y.
    #[default]
    Linear,
    /// Decades on x and y: points are drawn at `log10` of their coordinates (those not
    /// positive are skipped) and the ticks are labelled with the values.
    LogLog,
}

/// Left label area (tick labels and the rotated y label), px.
const Y_LABEL_AREA_PX: u32 = 80;
/// Bottom label area of the last panel (tick labels and the x label), px.
const X_LABEL_AREA_PX: u32 = 45;
const GRID: RGBColor = RGBColor(0xdd, 0xdd, 0xdd);
const ZERO_LINE: RGBColor = RGBColor(0x99, 0x99, 0x99);
const FRAME: RGBColor = RGBColor(0x44, 0x44, 0x44);

/// Tick label: `0`, plain decimals, or exponent form outside 1e-3..1e5.
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

/// Tick label of a log axis at `log10` value `v`: the value to 2 significant digits.
fn format_decade(v: f64) -> String {
    let x = 10f64.powf(v);
    if !(1e-3..1e5).contains(&x) {
        return format!("{x:.1e}");
    }
    let digits = (1.0 - x.log10().floor()).max(0.0) as usize;
    format!("{x:.digits$}")
}

/// `#rrggbb` to a colour; anything else is black.
fn color(text: &str) -> RGBColor {
    let hex = text.strip_prefix('#').filter(|h| h.len() == 6);
    let channel = |i: usize| hex.and_then(|h| u8::from_str_radix(&h[i..i + 2], 16).ok());
    match (channel(0), channel(2), channel(4)) {
        (Some(r), Some(g), Some(b)) => RGBColor(r, g, b),
        _ => BLACK,
    }
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

type Area<'a> = DrawingArea<SVGBackend<'a>, plotters::coord::Shift>;

impl Figure {
    /// Renders the figure as a standalone SVG document.
    pub fn to_svg(&self) -> String {
        if self.axes == Axes::LogLog {
            return self.logarithms().render(true);
        }
        self.render(false)
    }

    /// The figure with `log10` of every coordinate (not positive: NaN, skipped).
    fn logarithms(&self) -> Figure {
        let log = |v: f64| if v > 0.0 { v.log10() } else { f64::NAN };
        let mut fig = self.clone();
        fig.axes = Axes::Linear;
        for series in fig.panels.iter_mut().flat_map(|p| p.series.iter_mut()) {
            for p in &mut series.points {
                *p = (log(p.0), log(p.1));
            }
        }
        fig
    }

    /// The SVG; `decades`: the coordinates are `log10` of the values the ticks show.
    fn render(&self, decades: bool) -> String {
        let mut svg = String::new();
        let size = (self.width_px as u32, self.height_px as u32);
        {
            let root = SVGBackend::with_string(&mut svg, size).into_drawing_area();
            // Errors of the string backend cannot happen (it only appends to a String).
            let _ = self.draw(&root, decades);
            let _ = root.present();
        }
        svg.push('\n');
        svg
    }

    fn draw(&self, root: &Area<'_>, decades: bool) -> Result<(), Box<dyn std::error::Error>> {
        root.fill(&WHITE)?;
        let body = root.titled(&self.title, ("sans-serif", 17))?;
        let xs = self
            .panels
            .iter()
            .flat_map(|p| p.series.iter().flat_map(|s| s.points.iter().map(|p| p.0)));
        let x_range = range(xs);
        let total_weight: f64 = self.panels.iter().map(|p| p.weight).sum::<f64>().max(1e-9);
        let height_px = body.dim_in_pixel().1 as f64;
        let mut rest = body;
        for (i, panel) in self.panels.iter().enumerate() {
            let last = i + 1 == self.panels.len();
            let area = if last {
                rest.clone()
            } else {
                let h = (height_px * panel.weight / total_weight).round() as u32;
                let (area, below) = rest.split_vertically(h);
                rest = below;
                area
            };
            self.draw_panel(&area, panel, x_range, last, decades)?;
        }
        Ok(())
    }

    fn draw_panel(
        &self,
        area: &Area<'_>,
        panel: &Panel,
        (x_lo, x_hi): (f64, f64),
        last: bool,
        decades: bool,
    ) -> Result<(), Box<dyn std::error::Error>> {
        let (y_lo, y_hi) = range(
            panel
                .series
                .iter()
                .flat_map(|s| s.points.iter().map(|p| p.1)),
        );
        let mut chart = ChartBuilder::on(area)
            .caption(&panel.title, ("sans-serif", 14))
            .margin_right(30)
            .margin_top(5)
            .margin_bottom(if last { 5 } else { 15 })
            .x_label_area_size(if last { X_LABEL_AREA_PX } else { 0 })
            .y_label_area_size(Y_LABEL_AREA_PX)
            .build_cartesian_2d(x_lo..x_hi, y_lo..y_hi)?;
        // A tick at zero may come out as 1e-20 or so: label it 0.
        let y_tick = |v: &f64| {
            if decades {
                return format_decade(*v);
            }
            format_tick(if v.abs() < 1e-9 * (y_hi - y_lo) {
                0.0
            } else {
                *v
            })
        };
        let x_tick = |v: &f64| {
            if decades {
                return format_decade(*v);
            }
            format_tick(if v.abs() < 1e-9 * (x_hi - x_lo) {
                0.0
            } else {
                *v
            })
        };
        let mut mesh = chart.configure_mesh();
        mesh.bold_line_style(GRID)
            .light_line_style(TRANSPARENT)
            .axis_style(FRAME)
            .x_labels(9)
            .y_labels(7)
            .x_label_formatter(&x_tick)
            .y_label_formatter(&y_tick)
            .label_style(("sans-serif", 13))
            .y_desc(&panel.y_label);
        if last {
            mesh.x_desc(&self.x_label);
        }
        mesh.draw()?;
        chart.plotting_area().draw(&Rectangle::new(
            [(x_lo, y_lo), (x_hi, y_hi)],
            FRAME.stroke_width(1),
        ))?;
        if !decades && y_lo < 0.0 && y_hi > 0.0 {
            chart.draw_series(LineSeries::new([(x_lo, 0.0), (x_hi, 0.0)], ZERO_LINE))?;
        }
        for series in &panel.series {
            let c = color(series.color);
            let line = c.stroke_width(2);
            let finite: Vec<(f64, f64)> = series
                .points
                .iter()
                .copied()
                .filter(|(x, y)| x.is_finite() && y.is_finite())
                .collect();
            let legend = match series.style {
                Style::DashedLine => {
                    chart.draw_series(DashedLineSeries::new(finite.clone(), 6, 4, line))?
                }
                Style::Line | Style::LineAndMarkers => {
                    chart.draw_series(LineSeries::new(finite.clone(), line))?
                }
                Style::Markers => {
                    chart.draw_series(std::iter::empty::<Circle<(f64, f64), i32>>())?
                }
            };
            legend.label(series.label.as_str());
            if series.style == Style::DashedLine {
                legend.legend(move |(x, y)| {
                    EmptyElement::at((x, y))
                        + PathElement::new([(0, 0), (8, 0)], line)
                        + PathElement::new([(14, 0), (22, 0)], line)
                });
            } else {
                legend.legend(move |(x, y)| PathElement::new([(x, y), (x + 24, y)], line));
            }
            if matches!(series.style, Style::Markers | Style::LineAndMarkers) {
                chart.draw_series(finite.iter().map(|&p| Circle::new(p, 3, c.filled())))?;
            }
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperLeft)
            .background_style(WHITE.mix(0.85))
            .border_style(TRANSPARENT)
            .label_font(("sans-serif", 13))
            .draw()?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
            axes: Axes::Linear,
        };
        let svg = fig.to_svg();
        assert!(svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"));
        assert!(svg.contains("a &lt; b &amp; c"));
        assert_eq!(svg.matches("<circle").count(), 2, "NaN points are skipped");
        assert_eq!(svg.matches('<').count(), svg.matches('>').count());
    }

    /// Log-log: points at their decades, non-positive ones skipped, ticks labelled with values.
    #[test]
    fn log_log_skips_non_positive_points_and_labels_values() {
        let fig = Figure {
            title: "adev".into(),
            x_label: "tau (s)".into(),
            panels: vec![Panel {
                title: String::new(),
                y_label: "deg/h".into(),
                series: vec![Series {
                    label: "adev".into(),
                    points: vec![
                        (0.01, 1.0),
                        (1.0, 0.1),
                        (100.0, 0.01),
                        (0.0, 1.0),
                        (1.0, -1.0),
                    ],
                    color: "#1f77b4",
                    style: Style::Markers,
                }],
                weight: 1.0,
            }],
            width_px: 800.0,
            height_px: 600.0,
            axes: Axes::LogLog,
        };
        let svg = fig.to_svg();
        assert_eq!(svg.matches("<circle").count(), 3);
        let labels: Vec<&str> = svg
            .split("</text>")
            .filter_map(|t| t.rsplit('>').next())
            .map(str::trim)
            .collect();
        for want in ["0.010", "0.032", "1.0", "3.2", "100"] {
            assert!(labels.contains(&want), "{want} not in {labels:?}");
        }
    }
}
