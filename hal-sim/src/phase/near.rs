//! The near region around a turnaround: explicit RK4 on the lock-in phase
//! `phi' = Omega_L cos(theta(t) + phi)`, with `theta` from a local Taylor polynomial.
//!
//! Step size: the beat phase may advance at most `dtheta` per step,
//! `h = dtheta / (|omega| + Omega_L + sqrt(|omega'| dtheta))`: far from the turnaround this
//! is `dtheta/|omega|` (a fixed phase advance, so the error per step of the oscillating
//! integrand is the same everywhere), at the turnaround `sqrt(dtheta/|psi_ddot|)` (the
//! parabola `psi_ddot h^2 / 2` then advances < dtheta). The global error is O(dtheta^4).
//! The step sequence depends only on the segment (never on output requests), so results do
//! not depend on how often a caller looks.
//!
//! `theta(t_c + tau) - theta(t_c)` is a degree-[`DEGREE`] Taylor polynomial about the
//! segment's centre, accepted only if it matches the exact `theta` to [`POLY_TOL_RAD`] at
//! the ends and quarter points (otherwise the segment is split). With the PHYSICS.md set a
//! near region spans +-110 us, `w_d tau <= 0.27`, and the truncation error is ~1e-14 rad.
//! Working relative to `theta(t_c)` keeps the cos argument small (no large-argument
//! reduction) and each RHS evaluation is one Horner pass and one cosine.

use super::free_phase::{FreePhase, PieceId};
use core::f64::consts::TAU;

/// Degree of the Taylor polynomial of `theta`.
pub const DEGREE: usize = 12;
/// Largest accepted mismatch between the polynomial and the exact `theta`, rad.
pub const POLY_TOL_RAD: f64 = 1e-10;

/// `theta` near `t_c` as a polynomial in `tau = t - t_c`.
#[derive(Clone, Debug, PartialEq)]
pub struct NearPoly {
    /// Centre of the expansion, s.
    pub t_c: f64,
    /// Start and end of the validity interval, s.
    pub t_a: f64,
    pub t_b: f64,
    /// `theta(t_c)`, rad, exact, and reduced mod 2 pi.
    pub theta_c: f64,
    base: f64,
    p: [f64; DEGREE + 1],
    dp: [f64; DEGREE],
    ddp: [f64; DEGREE - 1],
}

fn horner(c: &[f64], x: f64) -> f64 {
    c.iter().rev().fold(0.0, |acc, &a| acc.mul_add(x, a))
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
        let mut dp = [0.0; DEGREE];
        for j in 0..DEGREE {
            dp[j] = (j + 1) as f64 * p[j + 1];
        }
        let mut ddp = [0.0; DEGREE - 1];
        for j in 0..DEGREE - 1 {
            ddp[j] = (j + 1) as f64 * dp[j + 1];
        }
        let poly = Self { t_c, t_a, t_b, theta_c: jet[0], base: jet[0].rem_euclid(TAU), p, dp, ddp };
        let half = 0.5 * (t_b - t_a);
        for f in [-1.0, -0.5, 0.5, 1.0] {
            let tau = f * half;
            let mut th = [0.0; 1];
            fp.angle_jet(t_c + tau, piece, &mut th);
            if (poly.dtheta(tau) - (th[0] - jet[0])).abs() > POLY_TOL_RAD {
                return None;
            }
        }
        Some(poly)
    }

    /// `theta(t_c + tau) - theta(t_c)`.
    #[inline]
    pub fn dtheta(&self, tau: f64) -> f64 {
        horner(&self.p, tau)
    }

    /// `omega(t_c + tau)` and `omega'(t_c + tau)`.
    #[inline]
    pub fn omega_and_slope(&self, tau: f64) -> (f64, f64) {
        (horner(&self.dp, tau), horner(&self.ddp, tau))
    }

    /// `theta(t_c) mod 2 pi`.
    #[inline]
    pub fn base(&self) -> f64 {
        self.base
    }
}

/// Step size for a beat-phase advance of at most `dtheta` (see the module docs).
#[inline]
pub fn step_size(omega: f64, slope: f64, omega_l: f64, dtheta: f64) -> f64 {
    dtheta / (omega.abs() + omega_l + (slope.abs() * dtheta).sqrt())
}

/// One classic RK4 step of `phi' = Omega_L cos(base + P(tau) + phi)` from `tau` to `tau + h`,
/// given `P(tau)`; returns `(phi(tau + h), P(tau + h))`.
#[inline]
pub fn rk4_step(poly: &NearPoly, omega_l: f64, tau: f64, phi: f64, h: f64, p0: f64) -> (f64, f64) {
    let b = poly.base + phi;
    let pm = poly.dtheta(tau + 0.5 * h);
    let p1 = poly.dtheta(tau + h);
    let k1 = omega_l * (b + p0).cos();
    let k2 = omega_l * (b + 0.5 * h * k1 + pm).cos();
    let k3 = omega_l * (b + 0.5 * h * k2 + pm).cos();
    let k4 = omega_l * (b + h * k3 + p1).cos();
    (phi + h / 6.0 * (k1 + 2.0 * (k2 + k3) + k4), p1)
}

/// Committed RK state inside one polynomial piece.
#[derive(Clone, Debug, PartialEq)]
pub struct NearStepper {
    pub poly: NearPoly,
    /// Committed time offset from `t_c` and `phi` there.
    pub tau: f64,
    pub phi: f64,
    p_tau: f64,
}

impl NearStepper {
    /// Starts at `poly.t_a` with `phi`.
    pub fn new(poly: NearPoly, phi: f64) -> Self {
        let tau = poly.t_a - poly.t_c;
        let p_tau = poly.dtheta(tau);
        Self { poly, tau, phi, p_tau }
    }

    /// Absolute committed time.
    pub fn t(&self) -> f64 {
        self.poly.t_c + self.tau
    }

    /// The next step from the committed state (clipped at the piece end).
    #[inline]
    pub fn next_h(&self, omega_l: f64, dtheta: f64) -> f64 {
        let (w, s) = self.poly.omega_and_slope(self.tau);
        let h = step_size(w, s, omega_l, dtheta);
        let rest = (self.poly.t_b - self.poly.t_c) - self.tau;
        if h >= rest * (1.0 - 1e-12) {
            rest
        } else {
            h
        }
    }

    /// Commits steps while they end at or before `t`; stops at the piece end.
    pub fn advance_until(&mut self, t: f64, omega_l: f64, dtheta: f64) {
        let tau_t = t - self.poly.t_c;
        let tau_end = self.poly.t_b - self.poly.t_c;
        while self.tau < tau_end {
            let h = self.next_h(omega_l, dtheta);
            let at_end = h == tau_end - self.tau;
            let tau_new = if at_end { tau_end } else { self.tau + h };
            if tau_new > tau_t {
                break;
            }
            let (phi, p1) = rk4_step(&self.poly, omega_l, self.tau, self.phi, tau_new - self.tau, self.p_tau);
            self.phi = phi;
            self.p_tau = p1;
            self.tau = tau_new;
        }
    }

    /// `phi` at `t` (committed time <= t <= next committed step end): one uncommitted
    /// partial RK4 step from the committed state.
    pub fn phi_at(&self, t: f64, omega_l: f64) -> f64 {
        let h = (t - self.poly.t_c) - self.tau;
        if h <= 0.0 {
            return self.phi;
        }
        rk4_step(&self.poly, omega_l, self.tau, self.phi, h, self.p_tau).0
    }

    /// True once the piece end is committed.
    pub fn done(&self) -> bool {
        self.tau >= self.poly.t_b - self.poly.t_c
    }
}
