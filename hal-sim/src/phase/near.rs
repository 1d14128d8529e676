//! The near region around a turnaround: 5-stage Gauss-Legendre collocation (order 10) on
//! the lock-in phase `phi' = Omega_L cos(theta(t) + phi)`, with `theta` from a local
//! Taylor polynomial.
//!
//! Why Gauss-Legendre: the error is almost entirely the quadrature of the fringe-rate
//! oscillation (the coupling through `phi` is weak, `Omega_L h << 1`), and an s-node Gauss
//! rule is exact to degree 2s - 1. Why 5 stages: for an oscillation the rule's error falls
//! like `(phase span per step)^(2s)` with a constant that shrinks fast with s, so more nodes
//! on longer steps cost fewer `(cos, sin)` evaluations per radian of beat phase. Measured
//! at the docs/physics.md set (`examples/speed_study.rs`): 3 stages at `dtheta` 0.5 gave
//! 3.6e-8 rad per traversal; 5 stages at `dtheta` 2 give 1.3e-8 (the far series' floor)
//! with half the near region's cost. Its implicit stages converge by plain fixed-point
//! iteration (contraction `~Omega_L h / 2`, < 1e-2 here), and each iteration only rotates
//! the stage phases by a tiny angle, so a step costs five `(cos, sin)` pairs and five
//! polynomial evaluations. The tableau is computed once from the Legendre nodes
//! (`Tableau::new`), not typed in.
//!
//! Step size: the beat phase may advance at most `dtheta` per step,
//! `h = dtheta / (sqrt(omega^2 + |omega'| TURN_PHASE_RAD) + Omega_L)`: far from the
//! turnaround this is `dtheta/|omega|`, at the turnaround `dtheta / sqrt(|psi_ddot| 1 rad)`
//! (with a quadratic phase a step of the same `dtheta` spans more phase there, hence the
//! curvature term: 0.25 rad, as the 3-stage rule had, gave 4e-6 rad at `dtheta` 1.5). The
//! two terms add in quadrature: added linearly (as before) they halved the steps where both
//! matter for no measurable gain (1.3e-8 rad per traversal either way, 7 % fewer
//! instructions in all).
//! Every step is proportional to `dtheta`, so the error falls with a clean power of it.
//! The step sequence depends only on the segment (never on output requests), so results do
//! not depend on how often a caller looks.
//!
//! `theta(t_c + tau) - theta(t_c)` is a degree-[`DEGREE`] Taylor polynomial about the
//! segment's centre, accepted only if it matches the exact `theta` to [`POLY_TOL_RAD`] at
//! the ends and quarter points (otherwise the segment is split). With the docs/physics.md set a
//! near region spans +-55 us (omega_c = 5e5 rad/s), `w_d tau <= 0.14`, and the truncation
//! error is ~1e-12 rad. Working relative to `theta(t_c)` keeps the cos argument small.

use super::free_phase::{FreePhase, PieceId};
use crate::trig::fast_cos_sin;
use core::f64::consts::TAU;

/// Degree of the Taylor polynomial of `theta`.
pub const DEGREE: usize = 9;
/// Largest accepted mismatch between the polynomial and the exact `theta`, rad.
pub const POLY_TOL_RAD: f64 = 1e-10;

/// `theta` near `t_c` as a polynomial in `tau = t - t_c`.
#[derive(Clone, Debug, PartialEq)]
pub struct NearPoly {
    /// Centre of the expansion, s.
    pub t_c: f64,
    /// Start of the validity interval, s.
    pub t_a: f64,
    /// End of the validity interval, s.
    pub t_b: f64,
    /// `theta(t_c)`, rad, exact, and reduced mod 2 pi.
    pub theta_c: f64,
    base: f64,
    p: [f64; DEGREE + 1],
}

#[inline(always)]
fn horner(c: &[f64; DEGREE + 1], x: f64) -> f64 {
    // Plain multiply-add: `mul_add` is a libm call unless the target has FMA enabled.
    let mut acc = c[DEGREE];
    for k in (0..DEGREE).rev() {
        acc = acc * x + c[k];
    }
    acc
}

/// `P(x)`, `P'(x)`, `P''(x)` in one Horner pass.
#[inline(always)]
fn horner2(c: &[f64; DEGREE + 1], x: f64) -> (f64, f64, f64) {
    let mut p = c[DEGREE];
    let mut d = 0.0;
    let mut dd = 0.0;
    for &a in c[..DEGREE].iter().rev() {
        dd = dd * x + d;
        d = d * x + p;
        p = p * x + a;
    }
    (p, d, 2.0 * dd)
}

impl NearPoly {
    /// Expands `theta` about the midpoint of `[t_a, t_b]` (formulas of `piece`); `None` if
    /// the polynomial misses the exact `theta` by more than [`POLY_TOL_RAD`].
    pub fn build(fp: &FreePhase, piece: PieceId, t_a: f64, t_b: f64) -> Option<Self> {
        let t_c = 0.5 * (t_a + t_b);
        let mut jet = [0.0; DEGREE + 1];
        fp.angle_jet(t_c, piece, &mut jet);
        let mut p = [0.0; DEGREE + 1];
        let mut fact = 1.0;
        for j in 1..=DEGREE {
            fact *= j as f64;
            p[j] = jet[j] / fact;
        }
        let poly = Self {
            t_c,
            t_a,
            t_b,
            theta_c: jet[0],
            base: jet[0].rem_euclid(TAU),
            p,
        };
        let half = 0.5 * (t_b - t_a);
        for f in [-1.0, -0.5, 0.5, 1.0] {
            // The offset that the sampled time really has (t is f64: at t ~ 2 s its ulp,
            // 4e-16 s, is already 4e-10 rad at 1e6 rad/s).
            let t = t_c + f * half;
            let tau = t - t_c;
            let mut th = [0.0; 1];
            fp.angle_jet(t, piece, &mut th);
            // The exact difference itself is only known to a few ulp of |theta|, which grows
            // without bound (1e6 rad after 1 s at 100 deg/s of input).
            let tol = POLY_TOL_RAD + 32.0 * f64::EPSILON * jet[0].abs().max(th[0].abs());
            if (poly.dtheta(tau) - (th[0] - jet[0])).abs() > tol {
                return None;
            }
        }
        Some(poly)
    }

    /// `theta(t_c + tau) - theta(t_c)`.
    #[inline(always)]
    pub fn dtheta(&self, tau: f64) -> f64 {
        horner(&self.p, tau)
    }

    /// `omega(t_c + tau)` and `omega'(t_c + tau)`.
    #[inline(always)]
    pub fn omega_and_slope(&self, tau: f64) -> (f64, f64) {
        let (_, w, s) = horner2(&self.p, tau);
        (w, s)
    }

    /// `theta(t_c) mod 2 pi`.
    #[inline(always)]
    pub fn base(&self) -> f64 {
        self.base
    }
}

/// `cos x`, see [`fast_cos_sin`].
#[inline(always)]
pub fn fast_cos(x: f64) -> f64 {
    fast_cos_sin(x).0
}

/// `cos(a + e)` from `cos a`, `sin a` for a small `e` (|e| <= 0.05: series error < 1e-19).
#[inline(always)]
fn cos_shifted(c: f64, s: f64, e: f64) -> f64 {
    if e.abs() < 1e-3 {
        // Series error < e^6/720 ~ 1.4e-21.
        let e2 = e * e;
        return c * (1.0 - e2 * (0.5 - e2 * (1.0 / 24.0)))
            - s * (e * (1.0 - e2 * (1.0 / 6.0 - e2 * (1.0 / 120.0))));
    }
    if e.abs() > 0.05 {
        return c * e.cos() - s * e.sin();
    }
    let e2 = e * e;
    let ce = 1.0 + e2 * (-0.5 + e2 * (1.0 / 24.0 + e2 * (-1.0 / 720.0 + e2 * (1.0 / 40320.0))));
    let se = e
        * (1.0
            + e2 * (-1.0 / 6.0
                + e2 * (1.0 / 120.0 + e2 * (-1.0 / 5040.0 + e2 * (1.0 / 362880.0)))));
    c * ce - s * se
}

/// Curvature scale of the step rule at a turnaround, rad (see [`step_size`]).
pub const TURN_PHASE_RAD: f64 = 1.0;

/// Step size: `h = dtheta / (sqrt(omega^2 + |omega'| TURN_PHASE_RAD) + Omega_L)`.
///
/// Far from the turnaround the beat phase advances `dtheta` per step; at the turnaround the
/// step is `dtheta / sqrt(|psi_ddot| 1 rad)` (~21 us for the docs/physics.md set at the
/// default `dtheta = 2`). Every step is proportional to `dtheta`.
#[inline(always)]
pub fn step_size(omega: f64, slope: f64, omega_l: f64, dtheta: f64) -> f64 {
    dtheta / ((omega * omega + slope.abs() * TURN_PHASE_RAD).sqrt() + omega_l)
}

/// The committed point: rate and slope of `theta` there, and the last stage derivative
/// (the predictor of the next step).
#[derive(Clone, Copy, Debug, PartialEq)]
struct PolyPoint {
    omega: f64,
    slope: f64,
    f_last: f64,
}

/// Stages of the Gauss-Legendre collocation (order `2 STAGES`).
pub const STAGES: usize = 5;

/// A Gauss-Legendre Butcher tableau on `[0, 1]`: nodes `c`, weights `b`, matrix `a`.
#[derive(Clone, Copy, Debug)]
struct Tableau<const S: usize> {
    c: [f64; S],
    b: [f64; S],
    a: [[f64; S]; S],
}

impl<const S: usize> Tableau<S> {
    /// Nodes and weights of the S-node rule ([`super::gauss::rule`]) moved to `[0, 1]`,
    /// and `a_ij = integral_0^{c_i} l_j` (the Lagrange basis on the nodes) by the S-node Gauss
    /// rule on `[0, c_i]` (exact: `l_j` has degree S - 1).
    fn new() -> Self {
        let (x, w) = super::gauss::rule::<S>();
        let c = x.map(|v| 0.5 * (1.0 + v));
        let b = w.map(|v| 0.5 * v);
        let lagrange = |j: usize, t: f64| {
            (0..S)
                .filter(|&m| m != j)
                .fold(1.0, |acc, m| acc * (t - c[m]) / (c[j] - c[m]))
        };
        let mut a = [[0.0; S]; S];
        for (i, row) in a.iter_mut().enumerate() {
            for (j, aij) in row.iter_mut().enumerate() {
                *aij = c[i] * (0..S).map(|k| b[k] * lagrange(j, c[i] * c[k])).sum::<f64>();
            }
        }
        Self { c, b, a }
    }
}

fn tableau() -> &'static Tableau<STAGES> {
    static T: std::sync::OnceLock<Tableau<STAGES>> = std::sync::OnceLock::new();
    T.get_or_init(Tableau::new)
}

/// One Gauss-Legendre step ([`STAGES`] stages, order `2 STAGES`) of
/// `phi' = Omega_L cos(base + P(tau) + phi)` from `tau` to `tau + h`; returns `phi(tau + h)`
/// and the last stage derivative.
///
/// The implicit stage equations are solved by fixed-point iteration, which contracts by
/// ~`Omega_L h / 2` (< 1e-2 in a dither near region): the stage phases are computed once
/// with a full `(cos, sin)` each (independent evaluations, in parallel in the pipeline) and
/// every iteration only rotates them by the small change of the stage `phi`. Iterates until
/// the stage derivatives move the step's result by less than 1e-14 rad (~2e-13 rad per
/// traversal at most, five orders below the method's error; 1e-16 cost 4 % more), a
/// deterministic function of the state, so results stay bit-reproducible.
#[inline(always)]
fn gl_step(poly: &NearPoly, omega_l: f64, tau: f64, phi: f64, h: f64, f_pred: f64) -> (f64, f64) {
    let t = tableau();
    let b = poly.base + phi;
    let d0 = t.c.map(|c| c * h * f_pred);
    let mut cs = [(0.0, 0.0); STAGES];
    for i in 0..STAGES {
        cs[i] = fast_cos_sin(b + d0[i] + poly.dtheta(tau + t.c[i] * h));
    }
    let mut f = cs.map(|(c, _)| omega_l * c);
    for _ in 0..60 {
        let mut g = [0.0; STAGES];
        let mut change: f64 = 0.0;
        for i in 0..STAGES {
            let d: f64 = t.a[i].iter().zip(&f).map(|(a, fj)| a * fj).sum();
            g[i] = omega_l * cos_shifted(cs[i].0, cs[i].1, h * d - d0[i]);
            change = change.max((g[i] - f[i]).abs());
        }
        f = g;
        if change * h <= 1e-14 {
            break;
        }
    }
    let sum: f64 = t.b.iter().zip(&f).map(|(b, fj)| b * fj).sum();
    (phi + h * sum, f[STAGES - 1])
}

/// Committed RK state inside one polynomial piece.
#[derive(Clone, Debug, PartialEq)]
pub struct NearStepper {
    /// The polynomial of `theta` stepped on; the stepper ends at its `t_b`.
    pub poly: NearPoly,
    /// Committed time, as an offset from `poly.t_c`, s.
    pub tau: f64,
    /// Lock-in phase `phi` at the committed time, rad.
    pub phi: f64,
    at: PolyPoint,
    /// Steps committed (for statistics).
    pub steps: u64,
}

impl NearStepper {
    /// Starts at `poly.t_a` with `phi`.
    pub fn new(poly: NearPoly, phi: f64) -> Self {
        let tau = poly.t_a - poly.t_c;
        let (omega, slope) = poly.omega_and_slope(tau);
        let f_last = 0.0;
        Self {
            poly,
            tau,
            phi,
            at: PolyPoint {
                omega,
                slope,
                f_last,
            },
            steps: 0,
        }
    }

    /// Absolute committed time.
    pub fn t(&self) -> f64 {
        self.poly.t_c + self.tau
    }

    /// Commits steps while they end at or before `t`; stops at the piece end.
    pub fn advance_until(&mut self, t: f64, omega_l: f64, dtheta: f64) {
        let tau_t = t - self.poly.t_c;
        let tau_end = self.poly.t_b - self.poly.t_c;
        while self.tau < tau_end {
            let h = step_size(self.at.omega, self.at.slope, omega_l, dtheta);
            let rest = tau_end - self.tau;
            let tau_new = if h >= rest * (1.0 - 1e-12) {
                tau_end
            } else {
                self.tau + h
            };
            if tau_new > tau_t {
                break;
            }
            let (phi, f_last) = gl_step(
                &self.poly,
                omega_l,
                self.tau,
                self.phi,
                tau_new - self.tau,
                self.at.f_last,
            );
            let (omega, slope) = self.poly.omega_and_slope(tau_new);
            self.phi = phi;
            self.at = PolyPoint {
                omega,
                slope,
                f_last,
            };
            self.tau = tau_new;
            self.steps += 1;
        }
    }

    /// `phi` at `t` (committed time <= t <= next committed step end): one uncommitted
    /// partial Gauss-Legendre step from the committed state.
    pub fn phi_at(&self, t: f64, omega_l: f64) -> f64 {
        let h = (t - self.poly.t_c) - self.tau;
        if h <= 0.0 {
            return self.phi;
        }
        gl_step(&self.poly, omega_l, self.tau, self.phi, h, self.at.f_last).0
    }

    /// True once the piece end is committed.
    pub fn done(&self) -> bool {
        self.tau >= self.poly.t_b - self.poly.t_c
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fast_cos_matches_libm() {
        let mut worst: f64 = 0.0;
        let mut x = -200.0;
        while x < 200.0 {
            worst = worst.max((fast_cos(x) - x.cos()).abs());
            x += 0.000_731_3;
        }
        // Reduction error ~ |k| ulp(pi/2 tail) plus polynomial rounding: a few 1e-16.
        assert!(worst < 1e-15, "{worst}");
        for e in [1e-3, 0.01, 0.049, 0.5] {
            let a = 1.234f64;
            let c = cos_shifted(a.cos(), a.sin(), e);
            assert!((c - (a + e).cos()).abs() < 1e-15);
        }
    }
}
