//! The near region around a turnaround: 3-stage Gauss-Legendre collocation (order 6) on
//! the lock-in phase `phi' = Omega_L cos(theta(t) + phi)`, with `theta` from a local
//! Taylor polynomial.
//!
//! Why Gauss-Legendre: the error is almost entirely the quadrature of the fringe-rate
//! oscillation (the coupling through `phi` is weak, `Omega_L h << 1`), and a 3-node Gauss
//! rule is exact to degree 5, so it takes ~3x longer steps than classic RK4 at equal
//! accuracy. Its implicit stages converge by plain fixed-point iteration (contraction
//! `~Omega_L h / 2`), and each iteration only rotates the three stage phases by a tiny
//! angle, so a step costs three `(cos, sin)` pairs and three polynomial evaluations.
//!
//! Step size: the beat phase may advance at most `dtheta` per step,
//! `h = dtheta / (|omega| + Omega_L + sqrt(|omega'| TURN_PHASE_RAD))`: far from the
//! turnaround this is `dtheta/|omega|`, at the turnaround `dtheta / sqrt(|psi_ddot| 0.25)`.
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
use super::trig::fast_cos_sin;
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
pub const TURN_PHASE_RAD: f64 = 0.25;

/// Step size: `h = dtheta / (|omega| + Omega_L + sqrt(|omega'| TURN_PHASE_RAD))`.
///
/// Far from the turnaround the beat phase advances `dtheta` per step; at the turnaround the
/// step is `dtheta / sqrt(|psi_ddot| 0.25 rad)` (~10 us for the docs/physics.md set at the
/// default `dtheta = 0.5`, k/2.5). Every step is proportional to `dtheta`.
#[inline(always)]
pub fn step_size(omega: f64, slope: f64, omega_l: f64, dtheta: f64) -> f64 {
    dtheta / (omega.abs() + omega_l + (slope.abs() * TURN_PHASE_RAD).sqrt())
}

/// The committed point: rate and slope of `theta` there, and the last stage derivative
/// (the predictor of the next step).
#[derive(Clone, Copy, Debug, PartialEq)]
struct PolyPoint {
    omega: f64,
    slope: f64,
    f_last: f64,
}

const SQRT15: f64 = 3.872_983_346_207_417;
/// Gauss-Legendre 3-stage collocation (order 6): nodes, weights, matrix.
const GL_C: [f64; 3] = [0.5 - SQRT15 / 10.0, 0.5, 0.5 + SQRT15 / 10.0];
const GL_B: [f64; 3] = [5.0 / 18.0, 4.0 / 9.0, 5.0 / 18.0];
const GL_A: [[f64; 3]; 3] = [
    [
        5.0 / 36.0,
        2.0 / 9.0 - SQRT15 / 15.0,
        5.0 / 36.0 - SQRT15 / 30.0,
    ],
    [
        5.0 / 36.0 + SQRT15 / 24.0,
        2.0 / 9.0,
        5.0 / 36.0 - SQRT15 / 24.0,
    ],
    [
        5.0 / 36.0 + SQRT15 / 30.0,
        2.0 / 9.0 + SQRT15 / 15.0,
        5.0 / 36.0,
    ],
];

/// One Gauss-Legendre step (3 stages, order 6) of `phi' = Omega_L cos(base + P(tau) + phi)`
/// from `tau` to `tau + h`; returns `phi(tau + h)` and the last stage derivative.
///
/// The implicit stage equations are solved by fixed-point iteration, which contracts by
/// ~`Omega_L h / 2` (< 2e-3 in a dither near region): the stage phases are computed once
/// with a full `(cos, sin)` each (three independent evaluations, in parallel in the
/// pipeline) and every iteration only rotates them by the small change of the stage `phi`.
/// Iterates to rounding level (a deterministic function of the state, so results stay
/// bit-reproducible).
#[inline(always)]
fn gl3_step(poly: &NearPoly, omega_l: f64, tau: f64, phi: f64, h: f64, f_pred: f64) -> (f64, f64) {
    // Written out for the three stages (no loops: stays unrolled at any opt-level).
    let b = poly.base + phi;
    let (d01, d02, d03) = (
        GL_C[0] * h * f_pred,
        GL_C[1] * h * f_pred,
        GL_C[2] * h * f_pred,
    );
    let (c1, s1) = fast_cos_sin(b + d01 + poly.dtheta(tau + GL_C[0] * h));
    let (c2, s2) = fast_cos_sin(b + d02 + poly.dtheta(tau + GL_C[1] * h));
    let (c3, s3) = fast_cos_sin(b + d03 + poly.dtheta(tau + GL_C[2] * h));
    let (mut f1, mut f2, mut f3) = (omega_l * c1, omega_l * c2, omega_l * c3);
    for _ in 0..60 {
        let d1 = h * (GL_A[0][0] * f1 + GL_A[0][1] * f2 + GL_A[0][2] * f3);
        let d2 = h * (GL_A[1][0] * f1 + GL_A[1][1] * f2 + GL_A[1][2] * f3);
        let d3 = h * (GL_A[2][0] * f1 + GL_A[2][1] * f2 + GL_A[2][2] * f3);
        let g1 = omega_l * cos_shifted(c1, s1, d1 - d01);
        let g2 = omega_l * cos_shifted(c2, s2, d2 - d02);
        let g3 = omega_l * cos_shifted(c3, s3, d3 - d03);
        let change = (g1 - f1).abs().max((g2 - f2).abs()).max((g3 - f3).abs());
        (f1, f2, f3) = (g1, g2, g3);
        if change * h <= 1e-16 {
            break;
        }
    }
    (phi + h * (GL_B[0] * f1 + GL_B[1] * f2 + GL_B[2] * f3), f3)
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
            let (phi, f_last) = gl3_step(
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
        gl3_step(&self.poly, omega_l, self.tau, self.phi, h, self.at.f_last).0
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
