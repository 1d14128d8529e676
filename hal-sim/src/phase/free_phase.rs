//! The free (lock-in-free) phase `theta(t)`: input angle + dither angle + noise angle, in rad
//! of beat phase, with its rate `omega = theta'` and higher derivatives.
//!
//! `theta` is continuous everywhere; `omega` is smooth inside *pieces* and may jump (input
//! steps, noise segments) or kink (ramps) at breakpoints. Every derivative is evaluated
//! "with the formula of a piece" ([`PieceId`]), so one-sided values at a breakpoint are
//! unambiguous and the integrator never differentiates across a jump. Pieces are bounded:
//! with dither they are at most a half cycle (between peaks of the dither rate), without
//! dither at most `solver.max_piece_s`.
//!
//! With the driven dither ([`crate::dither::driven`]) every drive segment start is a
//! breakpoint too, a piece lasts at most one nominal dither period (the noise segments still
//! split it when the noise is on; they snap to the drive's segment starts, so that a noise
//! step and a drive start near it make one breakpoint, see [`crate::noise`]), and no piece
//! reaches beyond [`FreePhase::known_until_s`]: the time up to which the drive is known, or
//! with the noise on the noise horizon if that is earlier (the start of the first noise
//! segment whose end the drive does not decide yet). [`FreePhase::piece_end`] says whether a
//! piece is complete or cut at that horizon; with the noise on a piece always ends at or
//! before its noise segment's decided end, so it is never cut.

use crate::dither::{Dither, MAX_JET};
use crate::input::InputProfile;
use crate::noise::Noise;
use crate::params::{Derived, GyroParams};
use core::f64::consts::TAU;

/// Which formula of each component applies: the smooth piece of the input, the noise
/// segment and the drive segment.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PieceId {
    /// Piece index of the input profile.
    pub input: usize,
    /// Noise segment index (also the half-cycle / fixed-length structural segment).
    pub noise: u64,
    /// Drive segment index of the driven dither (0 for the prescribed sine).
    pub drive: u64,
}

/// The lock-in-free phase of one gyro (immutable apart from the noise cache).
#[derive(Clone, Debug)]
pub struct FreePhase {
    input: InputProfile,
    /// rad of beat phase per arcsec of body angle (= rad/s per deg/h): 2 pi / SF.
    input_scale: f64,
    dither: Dither,
    noise: Noise,
}

impl FreePhase {
    /// Builds the free phase of `params` driven by `input`.
    pub fn new(params: &GyroParams, derived: &Derived, input: InputProfile) -> Self {
        Self {
            input,
            input_scale: TAU / derived.scale_factor_arcsec,
            dither: Dither::new(&params.dither_spec(derived)),
            noise: Noise::new(params, derived),
        }
    }

    /// The dither model.
    pub fn dither(&self) -> &Dither {
        &self.dither
    }

    /// The dither model, to push drive into.
    pub fn dither_mut(&mut self) -> &mut Dither {
        &mut self.dither
    }

    /// The input profile.
    pub fn input(&self) -> &InputProfile {
        &self.input
    }

    /// The noise model.
    pub fn noise(&self) -> &Noise {
        &self.noise
    }

    /// The piece containing `t_s`.
    pub fn piece_at(&self, t_s: f64) -> PieceId {
        PieceId {
            input: self.input.piece_index(t_s),
            // Without noise the segments share one formula: one id, so the planner joins the
            // far segments on both sides of a piece boundary (one far expansion per half
            // cycle instead of two at every other dither peak).
            noise: if self.noise.is_on() {
                self.noise.segment_at(t_s, &self.dither)
            } else {
                0
            },
            drive: self.dither.drive_index_at(t_s),
        }
    }

    /// The time up to which the free phase is known, s: the driven dither's drive horizon, or
    /// the noise horizon if the noise is on and that is earlier ([`Noise::known_until_s`]:
    /// less than 3/4 of a nominal period earlier); infinite for the prescribed sine.
    pub fn known_until_s(&self) -> f64 {
        self.dither
            .known_until_s()
            .min(self.noise.known_until_s(&self.dither))
    }

    /// End of the piece that starts at `t_s`, and whether it is complete: `false` when the
    /// piece is cut at the horizon ([`Self::known_until_s`]; the end returned is the horizon,
    /// which may equal `t_s`: nothing can be planned until more drive comes).
    pub fn piece_end(&self, t_s: f64) -> (f64, bool) {
        let Some(d) = self.dither.driven() else {
            return (self.piece_end_after(t_s), true);
        };
        let mut end = t_s + 1.0 / d.nominal_hz();
        let mut horizon = d.known_until_s();
        if self.noise.is_on() {
            // The noise is known before its horizon only, where the segment containing `t_s`
            // has a decided end (at or before the horizon: the piece is complete if the drive
            // reaches it).
            let noise_until = self.noise.known_until_s(&self.dither);
            horizon = horizon.min(noise_until);
            if t_s < noise_until {
                let k = self.noise.segment_at(t_s, &self.dither);
                if let Some(e) = self.noise.segment_end_known(k, &self.dither) {
                    end = end.min(e);
                }
            }
        }
        if let Some(b) = self.input.breakpoint_after(t_s) {
            end = end.min(b);
        }
        if let Some(s) = d.segment_start_after(t_s) {
            end = end.min(s);
        }
        if end <= horizon {
            (end, true)
        } else {
            (horizon, false)
        }
    }

    /// Drops the driven dither's drive segments and the noise segments that ended at or before
    /// `t_s` (the noise first decides what the drive decides: it needs the drive's segment
    /// starts). Asking for earlier times then panics.
    pub fn forget_before(&mut self, t_s: f64) {
        self.noise.forget_before(t_s, &self.dither);
        if let Some(d) = self.dither.driven_mut() {
            d.forget_before(t_s);
        }
    }

    /// End of the piece containing `t_s` (the next breakpoint strictly after it).
    ///
    /// Pieces follow the noise segments (half dither cycles between rate peaks). Without
    /// noise nothing jumps at a peak, so pairs of half cycles are merged into one piece:
    /// one far segment then spans the peak (fewer boundaries to expand, same result). With the
    /// driven dither this is [`Self::piece_end`]'s end.
    pub fn piece_end_after(&self, t_s: f64) -> f64 {
        if self.dither.driven().is_some() {
            return self.piece_end(t_s).0;
        }
        let mut k = self.noise.segment_index(t_s);
        if !self.noise.is_on() && self.dither.is_on() && k % 2 == 1 {
            k += 1;
        }
        let mut end = self.noise.segment_end_s(k);
        if let Some(b) = self.input.breakpoint_after(t_s) {
            end = end.min(b);
        }
        end
    }

    /// `theta` and its derivatives at `t_s` with the formulas of `piece`:
    /// `out[0] = theta` (rad), `out[1] = omega` (rad/s), `out[k] = d^k theta / dt^k`.
    pub fn angle_jet(&self, t_s: f64, piece: PieceId, out: &mut [f64]) {
        debug_assert!(out.len() <= MAX_JET);
        // Scratch sized to the request: the planner and the drift ask for 3 or 4 terms at
        // ~60 instants per half cycle, and zeroing MAX_JET-long buffers there was a tenth of
        // the simulator's time.
        if out.len() <= 4 {
            self.jet_into::<4>(t_s, piece, out);
        } else {
            self.jet_into::<MAX_JET>(t_s, piece, out);
        }
    }

    #[inline(always)]
    fn jet_into<const M: usize>(&self, t_s: f64, piece: PieceId, out: &mut [f64]) {
        let n = out.len();
        let mut b = [0.0; M];
        self.input.angle_jet(t_s, piece.input, out);
        self.dither.angle_jet(t_s, piece.drive, &mut b[..n]);
        for (o, bk) in out.iter_mut().zip(&b) {
            *o = *o * self.input_scale + bk;
        }
        if self.noise.is_on() {
            let m = n.min(2);
            self.noise
                .angle_jet(t_s, piece.noise, &self.dither, &mut b[..m]);
            for (o, bk) in out.iter_mut().zip(&b[..m]) {
                *o += bk;
            }
        }
    }

    /// `theta(t)`, rad (continuous; the piece is looked up).
    pub fn theta_rad(&self, t_s: f64) -> f64 {
        let mut d = [0.0; 1];
        self.angle_jet(t_s, self.piece_at(t_s), &mut d);
        d[0]
    }

    /// `omega(t)` and `omega'(t)` with the formula of `piece`.
    pub fn omega_and_slope(&self, t_s: f64, piece: PieceId) -> (f64, f64) {
        let mut d = [0.0; 3];
        self.angle_jet(t_s, piece, &mut d);
        (d[1], d[2])
    }

    /// True input rate at `t_s`, rad/s of beat phase.
    pub fn input_rate_rad_per_s(&self, t_s: f64) -> f64 {
        self.input.rate_deg_per_h(t_s) * self.input_scale
    }
}
