//! Chi-squared quantiles for the confidence intervals of Allan variances.
//!
//! An Allan variance estimate with `edf` equivalent degrees of freedom is distributed as
//! `avar * chi2(edf) / edf`, so the interval at confidence `c` is
//! `[avar * edf / q(1 - (1 - c) / 2), avar * edf / q((1 - c) / 2)]` with `q` the chi-squared
//! quantile. `edf` is not an integer, so the quantile comes from the regularised lower
//! incomplete gamma function `P(edf / 2, x / 2)` (series below `a + 1`, Lentz's continued
//! fraction above, Numerical Recipes 6.2), inverted by bisection on `ln x`: 200 halvings are
//! far more than the 1e-12 relative the intervals need, and they cost microseconds. No
//! statistics crate for one function.

/// `ln Gamma(x)` for `x > 0` (Lanczos, g = 7, n = 9: 1e-15 relative).
fn ln_gamma(x: f64) -> f64 {
    const G: [f64; 9] = [
        0.999_999_999_999_809_9,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_1,
        -176.615_029_162_140_6,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_572e-6,
        1.505_632_735_149_311_6e-7,
    ];
    if x < 0.5 {
        let pi = std::f64::consts::PI;
        return (pi / (pi * x).sin()).ln() - ln_gamma(1.0 - x);
    }
    let x = x - 1.0;
    let t = x + 7.5;
    let sum = G[1..]
        .iter()
        .enumerate()
        .fold(G[0], |s, (i, g)| s + g / (x + i as f64 + 1.0));
    0.5 * (2.0 * std::f64::consts::PI).ln() + (x + 0.5) * t.ln() - t + sum.ln()
}

/// Regularised lower incomplete gamma `P(a, x)`.
fn gamma_p(a: f64, x: f64) -> f64 {
    if x <= 0.0 {
        return 0.0;
    }
    let front = (a * x.ln() - x - ln_gamma(a)).exp();
    if x < a + 1.0 {
        let (mut term, mut sum, mut n) = (1.0 / a, 1.0 / a, a);
        for _ in 0..10_000 {
            n += 1.0;
            term *= x / n;
            sum += term;
            if term.abs() < sum.abs() * 1e-16 {
                break;
            }
        }
        front * sum
    } else {
        const TINY: f64 = 1e-300;
        let mut b = x + 1.0 - a;
        let (mut c, mut d) = (1.0 / TINY, 1.0 / b);
        let mut h = d;
        for i in 1..10_000 {
            let an = -(i as f64) * (i as f64 - a);
            b += 2.0;
            d = an * d + b;
            d = if d.abs() < TINY { TINY } else { d };
            c = b + an / c;
            c = if c.abs() < TINY { TINY } else { c };
            d = 1.0 / d;
            let step = d * c;
            h *= step;
            if (step - 1.0).abs() < 1e-16 {
                break;
            }
        }
        1.0 - front * h
    }
}

/// Chi-squared cumulative distribution with `dof` (> 0, real) degrees of freedom.
pub fn cdf(x: f64, dof: f64) -> f64 {
    gamma_p(0.5 * dof, 0.5 * x)
}

/// The `p`-quantile (0 < p < 1) of chi-squared with `dof` (> 0) degrees of freedom.
pub fn quantile(p: f64, dof: f64) -> f64 {
    let (mut lo, mut hi) = (1e-300f64.ln(), (dof + 100.0 * dof.sqrt() + 1000.0).ln());
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if cdf(mid.exp(), dof) < p {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    (0.5 * (lo + hi)).exp()
}

/// The interval `[low, high]` of a variance estimated as `variance` with `dof` degrees of
/// freedom, at two-sided confidence `confidence` (0 < c < 1).
pub fn variance_interval(variance: f64, dof: f64, confidence: f64) -> (f64, f64) {
    let tail = 0.5 * (1.0 - confidence);
    (
        variance * dof / quantile(1.0 - tail, dof),
        variance * dof / quantile(tail, dof),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Table values (Abramowitz & Stegun 26.8, NIST): chi2 quantiles to 4 significant digits.
    #[test]
    fn quantiles_match_the_tables() {
        for (p, dof, want) in [
            (0.975, 1.0, 5.0239),
            (0.025, 1.0, 0.000_982_07),
            (0.95, 10.0, 18.307),
            (0.05, 10.0, 3.9403),
            (0.5, 2.0, 1.386_29),
            (0.975, 100.0, 129.561),
            (0.025, 100.0, 74.222),
        ] {
            let got = quantile(p, dof);
            assert!(
                (got / want - 1.0).abs() < 2e-4,
                "q({p}, {dof}) = {got}, want {want}"
            );
        }
    }

    /// With many degrees of freedom the interval narrows as sqrt(2 / dof) around the estimate.
    #[test]
    fn interval_narrows_with_dof() {
        let (lo, hi) = variance_interval(1.0, 20_000.0, 0.6827);
        let half = 0.5 * (hi - lo);
        assert!(
            (half / (2.0f64 / 20_000.0).sqrt() - 1.0).abs() < 0.01,
            "{lo} {hi}"
        );
    }
}
