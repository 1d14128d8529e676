//! The IEEE Std 647 figures computed from measured points: sans-IO, no simulator.
//!
//! - **Scale factor** ([`scale_factor`]): the least-squares line `output = k input + b` over the
//!   scale-factor points (the linear range: the log-spaced points, all well outside the dead
//!   band). Both sides are in deg/h: the output is the board's fringes/s times the scale factor
//!   the board is configured with (the simulator's true one), so `k = 1` is a perfect gyro and
//!   the measured scale factor is `SF_true / k`, its error `(1 / k - 1) 1e6` ppm.
//! - **Non-linearity**: the largest |residual| from that line over the same points, in ppm of
//!   the full-scale output (`k` times the largest |input|).
//! - **Asymmetry**: the scale factor of the positive points' own line against the negative
//!   points' own line, `(SF+ - SF-) / mean(SF+, SF-)`, ppm.
//! - **Threshold and dead band** ([`threshold`]): a point is resolved when its bias-corrected
//!   output is within [`THRESHOLD_TOLERANCE`] (50 %) of the output the fitted line predicts,
//!   `|(out - bias) - k in| <= 0.5 |k in|` (IEEE 647's threshold: the smallest input whose
//!   output is at least 50 % of the one the scale factor predicts). The threshold is the
//!   smallest tested |input| from which every tested point of equal or larger magnitude, of
//!   either sign, is resolved; the dead band is where points fail: up to the largest failing
//!   magnitude on each side. A threshold can only be bracketed by the tested rates: when every
//!   point is resolved it is reported as at most the smallest tested rate.
//! - **Bias stability** ([`block_std`]): the standard deviation of the means of consecutive
//!   blocks of the static record (IEEE 647's bias stability over a stated averaging time).

/// The tolerance of the threshold criterion: 50 % of the predicted output.
pub const THRESHOLD_TOLERANCE: f64 = 0.5;

/// One measured input rate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RatePoint {
    /// The true input rate, deg/h.
    pub input_deg_h: f64,
    /// The board's fixed-rate output at the configured scale factor, deg/h.
    pub output_deg_h: f64,
    /// A scale-factor (linear-range) point; false: a dense point near zero.
    pub linear_range: bool,
}

/// A least-squares straight line `y = slope x + intercept`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Line {
    /// Slope (output per input).
    pub slope: f64,
    /// Intercept, in the output's unit.
    pub intercept: f64,
}

impl Line {
    /// The line's value at `x`.
    pub fn at(&self, x: f64) -> f64 {
        self.slope * x + self.intercept
    }
}

/// The least-squares line through `(x, y)` points (centred sums); `None` with fewer than two
/// distinct x.
pub fn fit_line(points: impl Iterator<Item = (f64, f64)> + Clone) -> Option<Line> {
    let (n, sx, sy) = points.clone().fold((0.0, 0.0, 0.0), |(n, sx, sy), (x, y)| {
        (n + 1.0, sx + x, sy + y)
    });
    if n < 2.0 {
        return None;
    }
    let (mx, my) = (sx / n, sy / n);
    let (sxx, sxy) = points.fold((0.0, 0.0), |(sxx, sxy), (x, y)| {
        (sxx + (x - mx) * (x - mx), sxy + (x - mx) * (y - my))
    });
    (sxx > 0.0).then(|| {
        let slope = sxy / sxx;
        Line {
            slope,
            intercept: my - slope * mx,
        }
    })
}

/// The scale-factor figures of one configuration.
#[derive(Clone, Debug, PartialEq)]
pub struct ScaleFactor {
    /// The fitted line over the linear range (output deg/h against input deg/h).
    pub line: Line,
    /// The measured scale factor, arcsec/pulse.
    pub scale_factor_arcsec: f64,
    /// Its error against the truth, ppm.
    pub error_ppm: f64,
    /// Largest |input| of the linear range, deg/h.
    pub full_scale_deg_h: f64,
    /// Largest |residual| from the line, ppm of the full-scale output.
    pub nonlinearity_ppm: f64,
    /// `(SF+ - SF-) / mean`, ppm; `None` without two points of each sign.
    pub asymmetry_ppm: Option<f64>,
    /// Each linear-range point's residual, ppm of full scale: `(input deg/h, ppm)`.
    pub residuals_ppm: Vec<(f64, f64)>,
}

/// The scale factor, its non-linearity and asymmetry from the linear-range points; `None`
/// without two distinct linear-range inputs.
pub fn scale_factor(points: &[RatePoint], true_scale_factor_arcsec: f64) -> Option<ScaleFactor> {
    let linear = points
        .iter()
        .filter(|p| p.linear_range)
        .map(|p| (p.input_deg_h, p.output_deg_h));
    let line = fit_line(linear.clone())?;
    let full_scale_deg_h = linear.clone().map(|(x, _)| x.abs()).fold(0.0, f64::max);
    let full_scale_output = (line.slope * full_scale_deg_h).abs();
    let residuals_ppm: Vec<(f64, f64)> = linear
        .clone()
        .map(|(x, y)| (x, (y - line.at(x)) / full_scale_output * 1e6))
        .collect();
    let nonlinearity_ppm = residuals_ppm.iter().map(|r| r.1.abs()).fold(0.0, f64::max);
    let side = |positive: bool| {
        let pts = linear.clone().filter(move |(x, _)| (*x > 0.0) == positive);
        fit_line(pts).map(|l| true_scale_factor_arcsec / l.slope)
    };
    let asymmetry_ppm = match (side(true), side(false)) {
        (Some(plus), Some(minus)) => Some((plus - minus) / (0.5 * (plus + minus)) * 1e6),
        _ => None,
    };
    Some(ScaleFactor {
        line,
        scale_factor_arcsec: true_scale_factor_arcsec / line.slope,
        error_ppm: (1.0 / line.slope - 1.0) * 1e6,
        full_scale_deg_h,
        nonlinearity_ppm,
        asymmetry_ppm,
        residuals_ppm,
    })
}

/// The smallest resolved rate and the dead band.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Threshold {
    /// The smallest tested |input| from which every tested point is resolved, deg/h; `None`
    /// when even the largest tested point fails.
    pub threshold_deg_h: Option<f64>,
    /// Every tested point is resolved: the threshold is at most the smallest tested rate.
    pub below_smallest_tested: bool,
    /// The smallest tested |input|, deg/h.
    pub smallest_tested_deg_h: f64,
    /// The largest failing |input| of the negative inputs, deg/h (0: none fails).
    pub dead_band_negative_deg_h: f64,
    /// The largest failing |input| of the positive inputs, deg/h (0: none fails).
    pub dead_band_positive_deg_h: f64,
}

/// Whether a point's bias-corrected output is within [`THRESHOLD_TOLERANCE`] of the line's
/// slope times its input.
pub fn resolved(point: &RatePoint, slope: f64, bias_deg_h: f64) -> bool {
    let predicted = slope * point.input_deg_h;
    (point.output_deg_h - bias_deg_h - predicted).abs() <= THRESHOLD_TOLERANCE * predicted.abs()
}

/// The threshold and dead band over every point (dense and linear-range) whose input is not
/// zero, against the scale factor `slope` and the static bias.
pub fn threshold(points: &[RatePoint], slope: f64, bias_deg_h: f64) -> Threshold {
    let tested: Vec<&RatePoint> = points.iter().filter(|p| p.input_deg_h != 0.0).collect();
    let largest_failing = |positive: bool| {
        tested
            .iter()
            .filter(|p| (p.input_deg_h > 0.0) == positive && !resolved(p, slope, bias_deg_h))
            .map(|p| p.input_deg_h.abs())
            .fold(0.0, f64::max)
    };
    let (neg, pos) = (largest_failing(false), largest_failing(true));
    let worst = neg.max(pos);
    let smallest = tested
        .iter()
        .map(|p| p.input_deg_h.abs())
        .fold(f64::INFINITY, f64::min);
    let threshold_deg_h = tested
        .iter()
        .map(|p| p.input_deg_h.abs())
        .filter(|&m| m > worst)
        .fold(None, |best: Option<f64>, m| {
            Some(best.map_or(m, |b| b.min(m)))
        });
    Threshold {
        threshold_deg_h,
        below_smallest_tested: worst == 0.0 && smallest.is_finite(),
        smallest_tested_deg_h: smallest,
        dead_band_negative_deg_h: neg,
        dead_band_positive_deg_h: pos,
    }
}

/// The sample standard deviation of the means of consecutive `block` samples of `rates`
/// (blocks holding a NaN, a gap, are left out); `None` with fewer than two whole blocks.
pub fn block_std(rates: &[f64], block: usize) -> Option<f64> {
    if block == 0 {
        return None;
    }
    let means: Vec<f64> = rates
        .chunks_exact(block)
        .filter(|c| c.iter().all(|r| r.is_finite()))
        .map(|c| c.iter().sum::<f64>() / block as f64)
        .collect();
    if means.len() < 2 {
        return None;
    }
    let mean = means.iter().sum::<f64>() / means.len() as f64;
    let ss: f64 = means.iter().map(|m| (m - mean) * (m - mean)).sum();
    Some((ss / (means.len() - 1) as f64).sqrt())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: f64, b: f64, tol: f64) -> bool {
        (a - b).abs() <= tol
    }

    /// A gyro whose positive inputs read 1 + 200 ppm, negative 1 + 100 ppm, with a 0.5 deg/h
    /// bias and one point bent by a known amount: the figures come back exactly.
    #[test]
    fn an_exact_linear_scale_factor_gives_its_figures_back() {
        let rates = [30.0, 300.0, 3000.0, 30_000.0, 300_000.0];
        let mut points: Vec<RatePoint> = rates
            .iter()
            .flat_map(|&r| [r, -r])
            .map(|x: f64| RatePoint {
                input_deg_h: x,
                output_deg_h: x * if x > 0.0 { 1.0002 } else { 1.0001 } + 0.5,
                linear_range: true,
            })
            .collect();
        // Dense points are not in the scale-factor fit, however wrong.
        points.push(RatePoint {
            input_deg_h: 1.0,
            output_deg_h: 0.0,
            linear_range: false,
        });
        let sf = scale_factor(&points, 2.0).unwrap();
        // The sides: SF+ = 2 / 1.0002, SF- = 2 / 1.0001.
        let (plus, minus) = (2.0 / 1.0002, 2.0 / 1.0001);
        let want_asym = (plus - minus) / (0.5 * (plus + minus)) * 1e6;
        assert!(close(sf.asymmetry_ppm.unwrap(), want_asym, 1e-6), "{sf:?}");
        assert!(close(want_asym, -100.0, 0.1));
        // The pooled slope is between the two sides; the kink is the non-linearity.
        assert!(sf.line.slope > 1.0001 && sf.line.slope < 1.0002);
        assert!(close(sf.error_ppm, (1.0 / sf.line.slope - 1.0) * 1e6, 1e-9));
        assert!(close(sf.full_scale_deg_h, 300_000.0, 0.0));
        // The error is V-shaped: 50 ppm of |x| on a symmetric set, which a line cannot take
        // (its slope is 0 against x); the line takes its mean, so the largest residual is at
        // full scale: 50e-6 (300000 - mean |x|), in ppm of the full-scale output.
        let mean_abs = rates.iter().sum::<f64>() / rates.len() as f64;
        let want = 50e-6 * (300_000.0 - mean_abs) / (sf.line.slope * 300_000.0) * 1e6;
        assert!(close(sf.nonlinearity_ppm, want, 1e-6), "{sf:?} want {want}");
        assert!(close(sf.line.slope, 1.00015, 1e-12));
        // A perfectly linear gyro: no non-linearity, no asymmetry, its scale factor exactly.
        let linear: Vec<RatePoint> = points
            .iter()
            .filter(|p| p.linear_range)
            .map(|p| RatePoint {
                output_deg_h: p.input_deg_h * 0.999 - 2.0,
                ..*p
            })
            .collect();
        let sf = scale_factor(&linear, 1.8655).unwrap();
        assert!(sf.nonlinearity_ppm < 1e-6, "{sf:?}");
        assert!(sf.asymmetry_ppm.unwrap().abs() < 1e-6);
        assert!(close(sf.scale_factor_arcsec, 1.8655 / 0.999, 1e-12));
        assert!(close(sf.error_ppm, (1.0 / 0.999 - 1.0) * 1e6, 1e-6));
        assert!(close(sf.line.intercept, -2.0, 1e-9));
    }

    /// One point 36 deg/h off the line at 300000 deg/h full scale is 120 ppm of full scale.
    #[test]
    fn the_non_linearity_is_the_largest_residual_in_ppm_of_full_scale() {
        let xs = [-300_000.0, -1000.0, 1000.0, 100_000.0, 300_000.0];
        let pts: Vec<RatePoint> = xs
            .iter()
            .map(|&x| RatePoint {
                input_deg_h: x,
                output_deg_h: x + if x == 100_000.0 { 36.0 } else { 0.0 },
                linear_range: true,
            })
            .collect();
        let sf = scale_factor(&pts, 1.0).unwrap();
        // The LS line moves towards the bent point; the residual at it is 36 minus the line's
        // value there: compute it from the fitted line and check the figure equals it.
        let want = (36.0 + 100_000.0 - sf.line.at(100_000.0)).abs() / (sf.line.slope * 300_000.0);
        assert!(close(sf.nonlinearity_ppm, want * 1e6, 1e-6), "{sf:?}");
        assert!(sf.nonlinearity_ppm > 80.0 && sf.nonlinearity_ppm < 120.0);
    }

    /// A synthetic dead band: Chow's law `sign(x) sqrt(x^2 - b^2)` outside |x| = b, zero inside.
    /// The 50 % criterion is met from |x| = b / sqrt(0.75) = 1.1547 b: the threshold is the
    /// first tested rate above that, and the dead band ends at the last one below.
    #[test]
    fn a_synthetic_dead_band_gives_its_threshold_back() {
        let band = 3.358;
        let chow = |x: f64| {
            if x.abs() <= band {
                0.0
            } else {
                x.signum() * (x * x - band * band).sqrt()
            }
        };
        let xs: Vec<f64> = (1..=40).map(|i| 0.1 * i as f64).collect();
        let points: Vec<RatePoint> = xs
            .iter()
            .flat_map(|&x| [x, -x])
            .map(|x| RatePoint {
                input_deg_h: x,
                output_deg_h: chow(x) + 0.25,
                linear_range: false,
            })
            .collect();
        let t = threshold(&points, 1.0, 0.25);
        let edge = band / 0.75f64.sqrt();
        assert!(close(edge, 3.8775, 1e-4));
        assert!(close(t.threshold_deg_h.unwrap(), 3.9, 1e-9), "{t:?}");
        assert!(close(t.dead_band_positive_deg_h, 3.8, 1e-9), "{t:?}");
        assert!(close(t.dead_band_negative_deg_h, 3.8, 1e-9), "{t:?}");
        assert!(!t.below_smallest_tested);
        // Without the bias correction the positive side resolves sooner, the negative later.
        let t = threshold(&points, 1.0, 0.0);
        assert!(
            t.dead_band_negative_deg_h > t.dead_band_positive_deg_h,
            "{t:?}"
        );
        // A linear gyro: every point resolved, the threshold at most the smallest rate.
        let linear: Vec<RatePoint> = points
            .iter()
            .map(|p| RatePoint {
                output_deg_h: p.input_deg_h,
                ..*p
            })
            .collect();
        let t = threshold(&linear, 1.0, 0.0);
        assert!(t.below_smallest_tested, "{t:?}");
        assert!(close(t.threshold_deg_h.unwrap(), 0.1, 1e-12));
        assert!(close(t.smallest_tested_deg_h, 0.1, 1e-12));
        // A gyro blind everywhere: no threshold.
        let blind: Vec<RatePoint> = points
            .iter()
            .map(|p| RatePoint {
                output_deg_h: 0.0,
                ..*p
            })
            .collect();
        assert_eq!(threshold(&blind, 1.0, 0.0).threshold_deg_h, None);
    }

    /// Block means of a known sequence; blocks with a gap are left out.
    #[test]
    fn block_std_of_known_blocks() {
        // Blocks of 2: means 1, 3, (gap), 5 -> std of 1, 3, 5 = 2.
        let rates = [0.0, 2.0, 3.0, 3.0, f64::NAN, 1.0, 4.0, 6.0, 9.0];
        assert!(close(block_std(&rates, 2).unwrap(), 2.0, 1e-12));
        assert_eq!(block_std(&rates, 5), None);
        assert_eq!(block_std(&rates, 0), None);
    }
}
