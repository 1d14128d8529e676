//! The integrator: walks the planned timeline, stepping near segments with Gauss-Legendre collocation and jumping
//! over far segments with the near-identity expansion, and reports turnarounds (with the
//! exact beat phase there) and, per near run, the change of the slow variable `chi`.
//!
//! State across a boundary is the lock-in phase `phi = psi - theta` (continuous). Entering a
//! far segment, `chi = phi - W(t, psi)`; leaving it, `phi` solves `phi = chi + W(t, theta +
//! phi)` with `chi` advanced by the drift integral. A *near run* is a maximal chain of near
//! segments between two far segments; its `chi_out - chi_in` is the lock-in phase error of
//! that traversal with the far-field oscillation `W` removed at both ends.
//!
//! Dense output never changes the committed state: in a near segment it is one partial
//! Gauss-Legendre step from the last committed step, in a far segment the expansion evaluated at that
//! instant. So the result at any time does not depend on which other times were asked for.

use super::far::{self, GaussIntegral, Oscillation, ORDER};
use super::free_phase::{FreePhase, PieceId};
use super::near::{NearPoly, NearStepper};
use super::plan::{Planner, Segment, TurnaroundTime};
use crate::params::SolverParams;
use std::collections::VecDeque;

/// A turnaround as the integration passed it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TurnaroundState {
    /// Its time, kind and `psi_ddot`, from the plan.
    pub at: TurnaroundTime,
    /// Beat phase at the instant, rad (unwrapped).
    pub psi_rad: f64,
    /// Lock-in phase `phi = psi - theta` at the instant, rad.
    pub phi_rad: f64,
}

/// A near run that ended in a far segment.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NearRun {
    /// Start of the run's first near segment, s.
    pub t_in: f64,
    /// End of its last near segment (start of the next far segment), s.
    pub t_out: f64,
    /// `chi` entering the run (None if the run began at the start of the simulation).
    pub chi_in: Option<f64>,
    /// `chi` leaving the run (entering the next far segment), rad.
    pub chi_out: f64,
}

/// What the integration reports while it advances.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Event {
    /// A turnaround was passed.
    Turnaround(TurnaroundState),
    /// A near run ended: one traversal's change of `chi`.
    NearRunEnd(NearRun),
}

/// How a part of the drift integral is parametrised.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Map {
    /// In `t`.
    Linear,
    /// In `u = ln|t - t_star|`, with `t_star` the zero of `omega` extrapolated from the end
    /// nearest a turnaround: the drift `~ -Omega_L^2 / (2 omega)` has a pole there, which the
    /// logarithm moves to `u = -infinity`, so one 10-node rule holds the whole part.
    Log { t_star: f64 },
}

impl Map {
    /// The part's variable at `t`.
    fn variable(&self, t: f64) -> f64 {
        match *self {
            Map::Linear => t,
            Map::Log { t_star } => (t - t_star).abs().ln(),
        }
    }
}

/// One part of a far segment's drift integral.
#[derive(Clone, Debug)]
struct DriftPart {
    map: Map,
    t_end: f64,
    integral: GaussIntegral,
    /// The integral over the parts before this one, rad.
    offset: f64,
}

/// The slow drift `chi' = g(t)` over one far segment, integrated in one or two parts
/// (a logarithmic variable towards each end that borders a turnaround) by a 10-node
/// Gauss-Legendre rule each ([`GaussIntegral`]): 20 evaluations of the rate per segment.
/// The rule's sum is what the integration commits; dense output integrates the polynomial
/// through the same nodes (no further evaluation). Measured against brute force
/// (`far_drift_matches_brute_force`): 4e-21 rad at the end and 7e-13 rad inside, of a drift
/// of 6e-5 rad, for the docs/physics.md set. (Before: a 24-node Chebyshev interpolant per
/// part, split where its tail exceeded 2e-11 rad, 48 evaluations per segment.)
#[derive(Clone, Debug)]
struct FarDrift {
    parts: [Option<DriftPart>; 2],
    total: f64,
}

impl FarDrift {
    /// No segment (before the first far segment).
    fn empty() -> Self {
        Self {
            parts: [None, None],
            total: 0.0,
        }
    }

    /// `f` is the drift rate, `w` gives `(omega, omega')`.
    fn new(t_a: f64, t_b: f64, f: &impl Fn(f64) -> f64, w: &impl Fn(f64) -> (f64, f64)) -> Self {
        let len = t_b - t_a;
        let (wa, sa) = w(t_a);
        let (wb, sb) = w(t_b);
        // Zeros of omega extrapolated (one Newton step) behind t_a and beyond t_b.
        let za = t_a - wa / sa;
        let zb = t_b - wb / sb;
        // (Only for segments long enough that the logarithms differ.)
        let long = len > 1e-7;
        let before = long && za < t_a && t_a - za < len;
        let after = long && zb > t_b && zb - t_b < len;
        let mut total = 0.0;
        let mut part = |t_a: f64, t_b: f64, map: Map| {
            let integral = match map {
                Map::Linear => GaussIntegral::new(t_a, t_b, f),
                Map::Log { t_star } => {
                    // dt = sgn e^u du
                    let sgn = if t_star < t_a { 1.0 } else { -1.0 };
                    GaussIntegral::new(map.variable(t_a), map.variable(t_b), |u: f64| {
                        let d = u.exp();
                        f(t_star + sgn * d) * sgn * d
                    })
                }
            };
            let offset = total;
            total += integral.total();
            Some(DriftPart {
                map,
                t_end: t_b,
                integral,
                offset,
            })
        };
        let parts = match (before, after) {
            (true, true) => {
                let m = 0.5 * (t_a + t_b);
                let first = part(t_a, m, Map::Log { t_star: za });
                [first, part(m, t_b, Map::Log { t_star: zb })]
            }
            (true, false) => [part(t_a, t_b, Map::Log { t_star: za }), None],
            (false, true) => [part(t_a, t_b, Map::Log { t_star: zb }), None],
            (false, false) => [part(t_a, t_b, Map::Linear), None],
        };
        Self { parts, total }
    }

    /// The integral over the whole segment, rad (what the integration commits).
    fn total(&self) -> f64 {
        self.total
    }

    /// The integral from the segment's start to `t`, rad (dense output).
    fn eval(&self, t: f64) -> f64 {
        let mut parts = self.parts.iter().flatten();
        let Some(mut p) = parts.next() else {
            return 0.0;
        };
        if t > p.t_end {
            if let Some(q) = parts.next() {
                p = q;
            }
        }
        p.offset + p.integral.eval(p.map.variable(t))
    }
}

#[derive(Clone, Debug)]
enum State {
    Near {
        stepper: NearStepper,
        trial_len: f64,
    },
    Far {
        chi_a: f64,
        drift: FarDrift,
    },
}

/// Omega_L(t) = Omega_L0 (1 + rate min(t, until)): a slow linear drift of the lock-in
/// threshold. With a zero rate the factor is exactly 1, so results do not change.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LockInDrift {
    /// Lock-in threshold at t = 0, rad/s of beat phase.
    pub omega_l0: f64,
    /// Relative drift `r`, 1/s (0 = none).
    pub rate_per_s: f64,
    /// End of the drift, s; the threshold stays constant after it.
    pub until_s: f64,
    /// The block's temperature, when it moves Omega_L (`crate::thermal`).
    pub thermal: Option<crate::thermal::GyroThermal>,
}

impl LockInDrift {
    /// No drift: the threshold stays `omega_l0`, rad/s of beat phase.
    pub fn none(omega_l0: f64) -> Self {
        Self {
            omega_l0,
            rate_per_s: 0.0,
            until_s: 0.0,
            thermal: None,
        }
    }

    /// The threshold at `t_s`, rad/s of beat phase.
    pub fn at(&self, t_s: f64) -> f64 {
        let drift = self.omega_l0 * (1.0 + self.rate_per_s * t_s.min(self.until_s));
        match &self.thermal {
            Some(th) => drift * th.lock_in_factor(t_s),
            None => drift,
        }
    }
}

/// Plans one more piece: a complete one if its drive is known, else one cut at the driven
/// dither's horizon. False if nothing can be planned.
fn plan_one(planner: &mut Planner, fp: &FreePhase) -> bool {
    planner.try_plan_next_piece(fp, false) || planner.try_plan_next_piece(fp, true)
}

/// The fast integrator of Eq. 6.
#[derive(Clone, Debug)]
pub struct Integrator {
    fp: FreePhase,
    /// Omega_L of the current segment (see [`LockInDrift`]).
    omega_l: f64,
    drift: LockInDrift,
    dtheta: f64,
    planner: Planner,
    seg: Segment,
    state: State,
    /// Start time and entering `chi` of the near run in progress.
    run: Option<(f64, Option<f64>)>,
    events: VecDeque<Event>,
    /// Latest time asked for (forward-only).
    t_now: f64,
}

impl Integrator {
    /// Starts at t = 0 with beat phase `psi0`.
    pub fn new(fp: FreePhase, omega_l: f64, solver: &SolverParams, psi0: f64) -> Self {
        let mut planner = Planner::new(&fp, solver, 0.0);
        while planner.segments.is_empty() && plan_one(&mut planner, &fp) {}
        // A driven dither without drive yet: an empty near segment at t = 0 holds the start.
        let seg = planner.segments.pop_front().unwrap_or(Segment {
            t_a: 0.0,
            t_b: 0.0,
            far: false,
            piece: fp.piece_at(0.0),
        });
        let phi0 = psi0 - fp.theta_rad(0.0);
        let placeholder = State::Far {
            chi_a: 0.0,
            drift: FarDrift::empty(),
        };
        let mut me = Self {
            fp,
            omega_l,
            drift: LockInDrift::none(omega_l),
            dtheta: solver.step_phase_rad,
            planner,
            seg,
            state: placeholder,
            run: None,
            events: VecDeque::new(),
            t_now: 0.0,
        };
        me.enter(seg, phi0, None);
        me
    }

    /// The free phase.
    pub fn free_phase(&self) -> &FreePhase {
        &self.fp
    }

    /// The free phase, to push drive into its driven dither (appending only: what is planned
    /// stays valid).
    pub(crate) fn free_phase_mut(&mut self) -> &mut FreePhase {
        &mut self.fp
    }

    /// Lock-in threshold, rad/s.
    pub fn omega_l(&self) -> f64 {
        self.omega_l
    }

    /// Latest time integrated to, s.
    pub fn t_now(&self) -> f64 {
        self.t_now
    }

    /// Drains the events reported so far.
    pub fn drain_events(&mut self) -> impl Iterator<Item = Event> + '_ {
        self.events.drain(..)
    }

    fn theta_jet<const N: usize>(&self, t: f64, piece: PieceId) -> [f64; N] {
        let mut j = [0.0; N];
        self.fp.angle_jet(t, piece, &mut j);
        j
    }

    /// `W`'s Fourier coefficients at `t` (formulas of `piece`) and `theta(t)`.
    fn oscillation(&self, t: f64, piece: PieceId) -> (Oscillation, f64) {
        let j: [f64; ORDER + 1] = self.theta_jet(t, piece);
        let mut tay = [0.0; ORDER];
        let mut fact = 1.0;
        for k in 0..ORDER {
            if k > 0 {
                fact *= k as f64;
            }
            tay[k] = j[k + 1] / fact;
        }
        (far::oscillation(&tay, self.omega_l), j[0])
    }

    /// The far drift's rate `g(t)` with the formulas of `piece` (see [`far::drift_rate`]).
    fn drift_rate(&self, piece: PieceId) -> impl Fn(f64) -> f64 + '_ {
        let l = self.omega_l;
        move |t: f64| {
            let mut j = [0.0; 4];
            self.fp.angle_jet(t, piece, &mut j);
            far::drift_rate(j[1], j[2], j[3], l)
        }
    }

    /// A slowly drifting lock-in threshold, taken constant over each segment.
    pub fn set_lock_in_drift(&mut self, drift: LockInDrift) {
        self.drift = drift;
        self.omega_l = drift.at(self.seg.t_a);
    }

    fn enter(&mut self, seg: Segment, phi: f64, chi_prev: Option<f64>) {
        self.seg = seg;
        // phi is continuous across segments; only the far-field transform uses the new value.
        self.omega_l = self.drift.at(0.5 * (seg.t_a + seg.t_b));
        if seg.far {
            let (osc, theta) = self.oscillation(seg.t_a, seg.piece);
            let chi_a = phi - osc.eval(theta + phi);
            if let Some((t_in, chi_in)) = self.run.take() {
                self.events.push_back(Event::NearRunEnd(NearRun {
                    t_in,
                    t_out: seg.t_a,
                    chi_in,
                    chi_out: chi_a,
                }));
            }
            let (fp, piece) = (&self.fp, seg.piece);
            let w = |t: f64| fp.omega_and_slope(t, piece);
            let drift = FarDrift::new(seg.t_a, seg.t_b, &self.drift_rate(piece), &w);
            self.state = State::Far { chi_a, drift };
        } else {
            if self.run.is_none() {
                self.run = Some((seg.t_a, chi_prev));
            }
            let (stepper, len) = self.near_piece(seg.t_a, seg.t_b - seg.t_a, phi);
            self.state = State::Near {
                stepper,
                trial_len: 2.0 * len,
            };
        }
    }

    /// The longest polynomial piece from `t_a` (at most `len`) that passes its check.
    fn near_piece(&self, t_a: f64, len: f64, phi: f64) -> (NearStepper, f64) {
        let mut len = len.min(self.seg.t_b - t_a);
        loop {
            let t_b = if len >= self.seg.t_b - t_a {
                self.seg.t_b
            } else {
                t_a + len
            };
            if let Some(poly) = NearPoly::build(&self.fp, self.seg.piece, t_a, t_b) {
                return (NearStepper::new(poly, phi), len);
            }
            assert!(
                len > 1e-9,
                "theta has no accurate local polynomial at t = {t_a}"
            );
            len *= 0.5;
        }
    }

    /// The next planned segment (planning as needed); `None` at the driven dither's horizon.
    fn next_segment(&mut self) -> Option<Segment> {
        while self.planner.segments.is_empty() {
            if !plan_one(&mut self.planner, &self.fp) {
                return None;
            }
        }
        self.planner.segments.pop_front()
    }

    /// Leaves the current segment at its end: `(phi, chi)` there.
    fn finish(&self) -> (f64, Option<f64>) {
        match &self.state {
            State::Near { stepper, .. } => (stepper.phi, None),
            State::Far { chi_a, drift } => {
                let chi_b = chi_a + drift.total();
                let (osc, theta) = self.oscillation(self.seg.t_b, self.seg.piece);
                (far::solve_phi(chi_b, theta, &osc), Some(chi_b))
            }
        }
    }

    /// Commits everything up to `t` (segments, whole RK steps).
    fn commit_until(&mut self, t: f64) {
        loop {
            let (l, dth) = (self.omega_l, self.dtheta);
            let seg_end = self.seg.t_b;
            match &mut self.state {
                State::Near { stepper, trial_len } => {
                    stepper.advance_until(t, l, dth);
                    if !stepper.done() {
                        return;
                    }
                    if stepper.poly.t_b < seg_end {
                        let (start, phi, trial) = (stepper.poly.t_b, stepper.phi, *trial_len);
                        let (s, len) = self.near_piece(start, trial, phi);
                        self.state = State::Near {
                            stepper: s,
                            trial_len: 2.0 * len,
                        };
                        continue;
                    }
                }
                State::Far { .. } => {
                    if seg_end > t {
                        return;
                    }
                }
            }
            // At the driven dither's horizon the segment ends exactly at `t`: stay in it.
            let Some(next) = self.next_segment() else {
                return;
            };
            let (phi, chi) = self.finish();
            self.enter(next, phi, chi);
        }
    }

    /// `psi(t)` from the committed state (t within reach of the current segment).
    fn psi_from_state(&self, t: f64) -> f64 {
        match &self.state {
            State::Near { stepper, .. } => {
                let p = &stepper.poly;
                p.theta_c + p.dtheta(t - p.t_c) + stepper.phi_at(t, self.omega_l)
            }
            State::Far { chi_a, drift } => {
                let chi = chi_a + drift.eval(t);
                let (osc, theta) = self.oscillation(t, self.seg.piece);
                theta + far::solve_phi(chi, theta, &osc)
            }
        }
    }

    /// Plans at least past `t` (with the driven dither: up to its horizon at most).
    pub fn plan_past(&mut self, t: f64) {
        while self.planner.planned_until() <= t && plan_one(&mut self.planner, &self.fp) {}
    }

    /// The first planned turnaround not yet passed (plans ahead as needed). Loops for ever if
    /// there is none (no dither, constant input); panics at the driven dither's horizon.
    pub fn upcoming_turnaround(&mut self) -> TurnaroundTime {
        self.try_upcoming_turnaround()
            .expect("no turnaround within the known drive: push drive segments further ahead")
    }

    /// As [`Self::upcoming_turnaround`], but `None` if the driven dither's drive is not known
    /// far enough: only complete pieces are planned here, so a turnaround is reported once
    /// its whole piece is known (the same plan whatever the caller's lead).
    pub fn try_upcoming_turnaround(&mut self) -> Option<TurnaroundTime> {
        loop {
            if let Some(tt) = self.planner.turnarounds.front() {
                return Some(*tt);
            }
            if !self.planner.try_plan_next_piece(&self.fp, false) {
                return None;
            }
        }
    }

    /// Integrates to `t` (forward only) and returns `psi(t)`, rad.
    pub fn advance_to(&mut self, t: f64) -> f64 {
        assert!(
            t >= self.t_now,
            "time is forward-only: asked {t} after {}",
            self.t_now
        );
        assert!(
            t <= self.fp.known_until_s(),
            "asked {t} s beyond the drive (and noise) known until {} s",
            self.fp.known_until_s()
        );
        self.plan_past(t);
        while let Some(&tt) = self.planner.turnarounds.front() {
            if tt.time_s > t {
                break;
            }
            self.planner.turnarounds.pop_front();
            self.commit_until(tt.time_s);
            let psi = self.psi_from_state(tt.time_s);
            let phi = psi - self.fp.theta_rad(tt.time_s);
            self.events.push_back(Event::Turnaround(TurnaroundState {
                at: tt,
                psi_rad: psi,
                phi_rad: phi,
            }));
        }
        self.commit_until(t);
        self.t_now = t;
        self.psi_from_state(t)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The drift over a far segment after a turnaround of the docs/physics.md set
    /// (`omega = psi_ddot (t - t_zero)`, its pole just behind the start): the committed total
    /// and dense values inside against a brute-force Simpson rule in `ln t`.
    #[test]
    fn far_drift_matches_brute_force() {
        let (a, l) = (9.06e9, 673.6);
        let w = |t: f64| (a * t, a);
        let f = |t: f64| far::drift_rate(a * t, a, 0.0, l);
        let (t_a, t_b) = (52e-6, 640e-6);
        let d = FarDrift::new(t_a, t_b, &f, &w);
        let simpson = |t_end: f64| {
            let n = 200_000;
            let (ua, ub) = (t_a.ln(), t_end.ln());
            let h = (ub - ua) / n as f64;
            let g = |u: f64| f(u.exp()) * u.exp();
            let mut acc = g(ua) + g(ub);
            for i in 1..n {
                acc += g(ua + i as f64 * h) * if i % 2 == 1 { 4.0 } else { 2.0 };
            }
            acc * h / 3.0
        };
        let total = simpson(t_b);
        // The leading term alone: -Omega_L^2 / (2 a) ln(t_b / t_a) = -6.3e-5 rad.
        assert!((total / (-l * l / (2.0 * a) * (t_b / t_a).ln()) - 1.0).abs() < 1e-3);
        // Simpson is exact to ~1e-20 rad here (h^4, h = 1.2e-5); measured difference 4e-21.
        assert!(
            (d.total() - total).abs() < 1e-18,
            "{} vs {total}",
            d.total()
        );
        assert!((d.eval(t_b) - d.total()).abs() < 1e-18);
        assert!(d.eval(t_a).abs() < 1e-18);
        // Inside: the degree-9 interpolant's integral; measured worst 6.8e-13 rad (1e-8 of
        // the drift), five orders below the dense-output budget of 2.4e-7 rad.
        let mut worst: f64 = 0.0;
        for k in 1..20 {
            let t = t_a * (t_b / t_a).powf(k as f64 / 20.0);
            worst = worst.max((d.eval(t) - simpson(t)).abs());
        }
        assert!(worst < 2e-12, "{worst}");
    }
}
