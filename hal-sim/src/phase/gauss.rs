//! Gauss-Legendre nodes and weights, computed (not typed in): Newton on the Legendre
//! polynomial from the asymptotic guess, to the last bit. Used by the near region's
//! collocation tableau ([`super::near`]) and the far drift's end value
//! ([`super::integrator`]).

/// Legendre polynomial `P_n(x)` and its derivative.
fn legendre(n: usize, x: f64) -> (f64, f64) {
    let (mut p0, mut p1) = (1.0, x);
    for k in 2..=n {
        let kf = k as f64;
        let p2 = ((2.0 * kf - 1.0) * x * p1 - (kf - 1.0) * p0) / kf;
        p0 = p1;
        p1 = p2;
    }
    let d = n as f64 * (x * p1 - p0) / (x * x - 1.0);
    (p1, d)
}

/// The `S`-node rule on `[-1, 1]`: nodes in increasing order and their weights.
pub fn rule<const S: usize>() -> ([f64; S], [f64; S]) {
    let mut x = [0.0; S];
    let mut w = [0.0; S];
    for (i, (xi, wi)) in x.iter_mut().zip(w.iter_mut()).enumerate() {
        let mut z = -(core::f64::consts::PI * (i as f64 + 0.75) / (S as f64 + 0.5)).cos();
        for _ in 0..100 {
            let (p, d) = legendre(S, z);
            let dz = p / d;
            z -= dz;
            if dz.abs() < 1e-17 {
                break;
            }
        }
        let (_, d) = legendre(S, z);
        *xi = z;
        *wi = 2.0 / ((1.0 - z * z) * d * d);
    }
    (x, w)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rules_integrate_polynomials_to_their_degree_exactly() {
        // The 5-node rule: the classic values; exact to degree 9.
        let (x, w) = rule::<5>();
        assert!((x[2]).abs() < 1e-16 && (x[4] - 0.906_179_845_938_664).abs() < 1e-15);
        assert!((w[2] - 128.0 / 225.0).abs() < 1e-15);
        let (x, w) = rule::<10>();
        for p in 0..20 {
            let exact = if p % 2 == 0 {
                2.0 / (p as f64 + 1.0)
            } else {
                0.0
            };
            let q: f64 = x.iter().zip(&w).map(|(x, w)| w * x.powi(p)).sum();
            assert!((q - exact).abs() < 1e-14, "x^{p}: {q} vs {exact}");
        }
    }
}
