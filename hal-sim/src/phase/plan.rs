//! The timeline: turnarounds (exact zeros of the lock-in-free rate) and the split of time
//! into near segments (stepped) and far segments (expanded), planned ahead piece by piece
//! from `omega(t)` alone, so it never depends on the integration state or on output requests.
//!
//! A time is *far* when `q = |omega| - max(omega_c, sqrt(|omega'| / delta_max)) > 0`: the
//! rate is large (`u = Omega_L/omega` small) and the adiabatic parameter `|omega'|/omega^2`
//! is below `delta_max`, the two small parameters of the far-field series. Each smooth piece
//! (see [`super::free_phase`]) is probed on a grid (32 probes per dither cycle: the near
//! region around a turnaround is ~220 us wide, wider than the probe spacing of 80 us),
//! sign changes of `omega` are refined by safeguarded Newton to the last bit (turnarounds),
//! sign changes of `q` by bisection (boundaries). A far segment is accepted only if `q > 0`
//! at interior check points as well; anything doubtful is near (always correct, only slower).
//! Limitation: a rate that jumps across zero at a breakpoint (an input step larger than the
//! dither rate there) has no smooth zero and is not reported as a turnaround.
//!
//! With the driven dither the future is known only up to the drive supplied so far: a piece
//! is planned only when it is complete ([`Planner::try_plan_next_piece`]), or, when a caller
//! must reach a time inside an incomplete piece, cut at the drive's horizon. Nothing is ever
//! planned, probed or refined beyond that horizon: a turnaround near a segment end is
//! bracketed inside its own piece (the probes include both ends), and the next piece is
//! planned only once its drive is known.

use super::free_phase::{FreePhase, PieceId};
use crate::params::SolverParams;
use firmware::sample::TurnaroundKind;
use std::collections::VecDeque;

/// A stretch of time integrated one way.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Segment {
    /// Start, s.
    pub t_a: f64,
    /// End, s.
    pub t_b: f64,
    /// True: far-field expansion; false: RK steps.
    pub far: bool,
    /// The smooth piece of the free phase it lies in (whose formulas it uses).
    pub piece: PieceId,
}

/// A zero of the lock-in-free rate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TurnaroundTime {
    /// The zero, s (Newton to the last bit).
    pub time_s: f64,
    /// Which way the rate crosses zero (`Plus`: beat phase at a minimum).
    pub kind: TurnaroundKind,
    /// `omega'` at the zero (= psi_ddot up to the lock-in term), rad/s^2.
    pub psi_ddot_rad_per_s2: f64,
}

/// Plans segments and turnarounds ahead of the integration.
#[derive(Clone, Debug)]
pub struct Planner {
    cursor: f64,
    omega_c: f64,
    delta_max: f64,
    probe_dt: f64,
    /// Planned segments, in time order.
    pub segments: VecDeque<Segment>,
    /// Planned turnarounds, in time order.
    pub turnarounds: VecDeque<TurnaroundTime>,
}

impl Planner {
    /// Starts planning at `t0`.
    pub fn new(fp: &FreePhase, solver: &SolverParams, t0: f64) -> Self {
        let f = fp.dither().freq_hz();
        Self {
            cursor: t0,
            omega_c: solver.far_threshold_rad_per_s,
            delta_max: solver.far_max_adiabatic,
            probe_dt: if f > 0.0 {
                1.0 / (32.0 * f)
            } else {
                solver.max_piece_s / 4.0
            },
            segments: VecDeque::new(),
            turnarounds: VecDeque::new(),
        }
    }

    /// End of what is planned so far.
    pub fn planned_until(&self) -> f64 {
        self.cursor
    }

    /// `(omega, q)`: the rate and the far margin `q` (far where `q > 0`).
    fn probe(&self, fp: &FreePhase, piece: PieceId, t: f64) -> (f64, f64) {
        let (w, s) = fp.omega_and_slope(t, piece);
        (
            w,
            w.abs() - self.omega_c.max((s.abs() / self.delta_max).sqrt()),
        )
    }

    fn margin(&self, fp: &FreePhase, piece: PieceId, t: f64) -> f64 {
        self.probe(fp, piece, t).1
    }

    /// Plans the next smooth piece (cut at the driven dither's horizon if need be); panics if
    /// nothing can be planned (the drive is known only up to the cursor).
    pub fn plan_next_piece(&mut self, fp: &FreePhase) {
        assert!(
            self.try_plan_next_piece(fp, true),
            "nothing to plan beyond {} s: the drive is not known further",
            self.cursor
        );
    }

    /// Plans the next smooth piece if its formulas are known to its end; with
    /// `allow_partial`, also a piece cut at the driven dither's horizon. Returns false if
    /// nothing was planned.
    pub fn try_plan_next_piece(&mut self, fp: &FreePhase, allow_partial: bool) -> bool {
        let a = self.cursor;
        let (b, complete) = fp.piece_end(a);
        if b <= a || !(complete || allow_partial) {
            return false;
        }
        self.plan_piece(fp, a, b);
        true
    }

    /// Plans the piece `[a, b]` (`a` = the cursor).
    fn plan_piece(&mut self, fp: &FreePhase, a: f64, b: f64) {
        let piece = fp.piece_at(0.5 * (a + b));
        let n = (((b - a) / self.probe_dt).ceil() as usize).max(2);
        let probe = |i: usize| {
            if i == n {
                b
            } else {
                a + (b - a) * i as f64 / n as f64
            }
        };
        let mut bounds = vec![a];
        let (mut w0, mut q0) = self.probe(fp, piece, a);
        let mut t0 = a;
        for i in 1..=n {
            let t1 = probe(i);
            let (w1, q1) = self.probe(fp, piece, t1);
            if (w0 >= 0.0) != (w1 >= 0.0) {
                self.turnarounds
                    .push_back(find_turnaround(fp, piece, t0, t1));
            }
            if (q0 > 0.0) != (q1 > 0.0) {
                bounds.push(regula_falsi(|t| self.margin(fp, piece, t), t0, q0, t1, q1));
            }
            (t0, w0, q0) = (t1, w1, q1);
        }
        bounds.push(b);
        bounds.sort_by(f64::total_cmp);
        for w in bounds.windows(2) {
            let (sa, sb) = (w[0], w[1]);
            if sb <= sa {
                continue;
            }
            let far = (1..4).all(|j| self.margin(fp, piece, sa + (sb - sa) * j as f64 / 4.0) > 0.0);
            match self.segments.back_mut() {
                Some(last) if last.far == far && last.piece == piece && last.t_b == sa => {
                    last.t_b = sb
                }
                _ => self.segments.push_back(Segment {
                    t_a: sa,
                    t_b: sb,
                    far,
                    piece,
                }),
            }
        }
        self.cursor = b;
    }
}

/// Bisection for the switch of `pred` in `[lo, hi]` (`pred(lo) == at_lo`).
/// Root of `q` bracketed by `[a, b]` (Illinois regula falsi), to ~1e-9 of the bracket: a
/// boundary needs no precision, only determinism and the right side of the sign change.
fn regula_falsi(q: impl Fn(f64) -> f64, mut a: f64, mut qa: f64, mut b: f64, mut qb: f64) -> f64 {
    let tol = 1e-6 * (b - a);
    let mut side = 0;
    for _ in 0..40 {
        let c = (a * qb - b * qa) / (qb - qa);
        let qc = q(c);
        if (qc > 0.0) == (qa > 0.0) {
            a = c;
            qa = qc;
            if side == -1 {
                qb *= 0.5;
            }
            side = -1;
        } else {
            b = c;
            qb = qc;
            if side == 1 {
                qa *= 0.5;
            }
            side = 1;
        }
        if b - a < tol || qc == 0.0 {
            break;
        }
    }
    0.5 * (a + b)
}

/// Zero of `omega` bracketed by `[lo, hi]`: Newton, falling back to bisection when a step
/// leaves the bracket; iterated until the step is below the resolution of `t`.
pub fn find_turnaround(fp: &FreePhase, piece: PieceId, lo: f64, hi: f64) -> TurnaroundTime {
    let (mut lo, mut hi) = (lo, hi);
    let lo_positive = fp.omega_and_slope(lo, piece).0 >= 0.0;
    let mut t = 0.5 * (lo + hi);
    for _ in 0..100 {
        let (w, s) = fp.omega_and_slope(t, piece);
        if (w >= 0.0) == lo_positive {
            lo = t;
        } else {
            hi = t;
        }
        let newton = t - w / s;
        // Converged: the Newton step is below the resolution of `t`. (Tested before the
        // bracket: a step that lands on `t` itself, which just became a bracket end, is
        // convergence, not a reason to bisect; bisecting there cost ~25 extra evaluations at
        // most turnarounds.)
        if (newton - t).abs() <= 2.0 * f64::EPSILON * t.abs().max(1e-3) {
            t = newton;
            break;
        }
        let tn = if newton > lo && newton < hi {
            newton
        } else {
            0.5 * (lo + hi)
        };
        if hi - lo <= f64::EPSILON * t.abs() {
            t = tn;
            break;
        }
        t = tn;
    }
    let s = fp.omega_and_slope(t, piece).1;
    let kind = if lo_positive {
        TurnaroundKind::Minus
    } else {
        TurnaroundKind::Plus
    };
    TurnaroundTime {
        time_s: t,
        kind,
        psi_ddot_rad_per_s2: s,
    }
}
