//! Brute-force reference: classic RK4 on the full Eq. 6 written for `phi = psi - theta`,
//! `phi' = Omega_L cos(theta(t) + phi)`, with `theta` evaluated exactly at every stage (no
//! Taylor polynomial, no far-field expansion) and a step that limits the beat-phase advance
//! per step to `dtheta` (the same rule as the near region, but everywhere and with a much
//! smaller `dtheta`; a fixed step `h_max` caps it). It never steps across a piece
//! boundary. Slow by design: only for tests and convergence studies.

use super::free_phase::FreePhase;
use super::near::step_size;

/// A reference integration in progress.
#[derive(Clone, Debug)]
pub struct Reference<'a> {
    fp: &'a FreePhase,
    omega_l: f64,
    /// Largest beat-phase advance per step, rad.
    pub dtheta: f64,
    /// Largest step, s.
    pub h_max: f64,
    t: f64,
    phi: f64,
    /// Kahan compensation of the running sum `phi` (millions of tiny increments onto
    /// |phi| ~ 1e3 would otherwise lose ~1e-10 rad to rounding).
    phi_carry: f64,
    /// Steps taken so far.
    pub steps: u64,
}

impl<'a> Reference<'a> {
    /// Starts at `t0` with beat phase `psi0`.
    pub fn new(
        fp: &'a FreePhase,
        omega_l: f64,
        t0: f64,
        psi0: f64,
        dtheta: f64,
        h_max: f64,
    ) -> Self {
        let phi = psi0 - fp.theta_rad(t0);
        Self {
            fp,
            omega_l,
            dtheta,
            h_max,
            t: t0,
            phi,
            phi_carry: 0.0,
            steps: 0,
        }
    }

    /// Current time, s.
    pub fn t(&self) -> f64 {
        self.t
    }

    /// Lock-in phase `phi = psi - theta` now, rad.
    pub fn phi(&self) -> f64 {
        self.phi
    }

    /// Beat phase now, rad.
    pub fn psi(&self) -> f64 {
        self.fp.theta_rad(self.t) + self.phi
    }

    /// Integrates to `t_end` and returns `psi(t_end)`.
    pub fn advance_to(&mut self, t_end: f64) -> f64 {
        while self.t < t_end {
            let piece = self.fp.piece_at(self.t);
            let stop = self.fp.piece_end_after(self.t).min(t_end);
            let mut jet = [0.0; 3];
            self.fp.angle_jet(self.t, piece, &mut jet);
            while self.t < stop {
                let h = step_size(jet[1], jet[2], self.omega_l, self.dtheta).min(self.h_max);
                let t1 = if self.t + h >= stop { stop } else { self.t + h };
                let h = t1 - self.t;
                let mut mid = [0.0; 1];
                self.fp.angle_jet(self.t + 0.5 * h, piece, &mut mid);
                let mut end = [0.0; 3];
                self.fp.angle_jet(t1, piece, &mut end);
                let (l, phi) = (self.omega_l, self.phi);
                let k1 = l * (jet[0] + phi).cos();
                let k2 = l * (mid[0] + phi + 0.5 * h * k1).cos();
                let k3 = l * (mid[0] + phi + 0.5 * h * k2).cos();
                let k4 = l * (end[0] + phi + h * k3).cos();
                let inc = h / 6.0 * (k1 + 2.0 * (k2 + k3) + k4) - self.phi_carry;
                let sum = self.phi + inc;
                self.phi_carry = (sum - self.phi) - inc;
                self.phi = sum;
                self.t = t1;
                jet = end;
                self.steps += 1;
            }
        }
        self.psi()
    }
}
