//! Angle random walk: white rate noise, seeded, bit-for-bit reproducible.
//!
//! Choice: the noise rate is piecewise constant over *noise segments*, each an independent
//! Gaussian of standard deviation `ARW / sqrt(duration)`, so the noise angle is a random walk
//! whose variance grows exactly as `ARW^2 t` at every segment boundary, and is linear in
//! between. With dither the segments are the half cycles between the peaks of the dither
//! rate (`(n + 1/2) / (2 f_d)`): the rate jumps only where |omega| is largest, never near a
//! turnaround, so a turnaround is always a smooth zero and the far-field expansion sees the
//! jump only as a boundary between two smooth pieces. The noise is then white up to the
//! Nyquist frequency of the half cycle (f_d), which is all the firmware can resolve: it
//! samples once per turnaround. Without dither the segments are `solver.max_piece_s` long.
//!
//! Reproducibility: segment `k` draws its Gaussian `z_k` (Box-Muller from two `u64`) at word
//! position `4 k` of a ChaCha8 stream seeded from the gyro seed, so any segment's rate is a
//! pure function of `(seed, k)` (and, with the driven dither, of the drive's segment starts);
//! angles at segment starts are cumulative sums in a fixed order, cached with a checkpoint
//! every [`BLOCK`] segments.
//!
//! # With the driven dither: the noise steps on the drive's segment starts
//!
//! The driven dither ([`crate::dither::driven`]) has breakpoints of its own: a drive segment
//! starts wherever the firmware updates its DDS, about twice per cycle near the rate peaks (it
//! updates at the pick-off's zero crossings), a few drive ticks (25 us) off the nominal grid
//! above. A noise step a few ticks from a segment start is one more piece boundary per half
//! cycle, one more far-field expansion: measured, the driven dither with noise took 31 % more
//! CPU time than the prescribed sine with the same noise, against 15 % without noise. So with
//! a driven dither and the noise on, the grid snaps to the drive:
//!
//! - boundary `k`, nominally `e_k = (k + 1/2) / (2 f_nom)`, is the **first** segment start `s`
//!   of the driven dither (a pushed drive segment or a temperature split) with
//!   `e_k - W <= s < e_k + W`, `W = 1/8` of a nominal period ([`Noise::snap_window_s`]), and
//!   `e_k` if there is none;
//! - segment `k`'s rate is `ARW / sqrt(d_k) z_k`, with `d_k` its actual (snapped) length and
//!   `z_k` the nominal grid's Gaussian: the variance is still exactly `ARW^2 t` at every
//!   boundary, however the drive is segmented.
//!
//! Measured (bench `phase`, per 0.1 gyro-second): the driven dither with noise 2.00 ms against
//! 1.74 ms for the prescribed sine with the same noise (+15 %, a speed drop of 13 %), was
//! 2.33 against 1.78 ms.
//!
//! The window: boundaries are half a period `T/2` apart and windows `T/4` wide, so a start
//! belongs to one window at most, boundaries stay in order and a segment lasts between `T/4`
//! and `3T/4`. A start within `T/8` of a rate peak keeps the step far from the turnarounds
//! (`T/4` from the peaks) whenever the dither's phase is near the nominal grid's. Starts a few
//! ticks off the grid (the open-loop drive, a firmware locked near the nominal frequency) all
//! snap; a drive at another frequency slides its starts through the windows, and about half of
//! the boundaries snap (a window of `T/4` in every `T/2`); the others stay nominal, an extra
//! piece boundary as before.
//!
//! ## Causality: decided boundaries, and the noise horizon
//!
//! The drive is known up to its horizon `K` ([`DrivenDither::known_until_s`]) and every
//! segment start before `K` is known: later drive starts at `K` or after. So boundary `k` is
//! *decided*, final, as soon as the first start in its window is known (a later start cannot
//! come before it: that is why the rule takes the first), or, with none, once `K >= e_k + W`.
//! The rate of segment `k` needs its length, so it is known once its end is decided: the
//! noise is known up to the start of the first segment whose end is not decided
//! ([`Noise::known_until_s`], the *noise horizon*), which lags `K` by less than `3T/4` (that
//! segment started at `e_{k-1} - W` or later, and `K >= e_k + W` decides its end). The phase
//! integrator never plans or goes beyond the lesser horizon
//! ([`crate::phase::free_phase::FreePhase::known_until_s`], `Gyro::known_until_s`), so the
//! membership of a time in a noise segment, and the segment's rate, never change after they
//! were used. Every piece ends at or before its noise segment's end, which is decided and at
//! or before both horizons: with the noise on, no piece is ever cut at a horizon, and the
//! results do not depend on the caller's lead or on how pushing drive and advancing interleave
//! (bit for bit, `tests/driven_gyro.rs`). With the lead the gyro asks for (two nominal periods,
//! `Gyro::drive_lead_s`) the noise horizon is never in the way (see [`crate::dither`]).
//!
//! ## Trade-offs
//!
//! - A caller that keeps the drive known only up to where it advances (no lead) cannot
//!   advance as far with the noise on: the gyro refuses beyond the noise horizon. The
//!   alternative, the nominal length in the rate (`ARW / sqrt(T/2) z_k`), needs only the
//!   segment's start and would keep the horizon at `K`, but its variance is
//!   `ARW^2 sum d_k^2 / (T/2)` instead of `ARW^2 sum d_k`: a relative bias of
//!   `E[(d_k - T/2)^2] / (T/2)^2`, with `d_k - T/2` the change of the snap offset between two
//!   boundaries. That is 1e-4 for the open-loop drive (lengths of 51 and 52 ticks around
//!   51.4), 0.3 % for a firmware updating once per cycle 3 ticks after the peak (one boundary
//!   in two snapped: lengths `T/2 -+ 75 us`), 6 % if that update were `W` off the peak, and
//!   up to 25 % (offsets `-W` and `+W` in turn: lengths `T/2 -+ 2W`). Exactness won: a caller
//!   needs the lead anyway for the turnarounds, and with it the horizon costs nothing.
//! - The noise's realisation depends on the drive's segmentation (the same `z_k`, steps at
//!   other instants): two runs with different drives see different, equally valid, walks.
//! - A drive whose segments start at the turnarounds puts them outside the windows while the
//!   dither's phase is near nominal; if it drifts by `T/8`, noise steps land at turnarounds,
//!   inside near regions (exact, as any breakpoint; a step that carries the rate across zero
//!   there hides that turnaround, [`crate::phase::plan`]'s limitation: a chance of order
//!   `|step| / (psi_ddot tick)`, 4e-4 per step at ARW 0.01 deg/sqrt(h) and 25 us ticks).
//!
//! Memory: the snapped grid keeps its segments (32 bytes each, ~780 per second) as long as
//! the drive keeps its history ([`crate::dither::driven::HISTORY_S`],
//! [`Noise::forget_before`]).

use crate::dither::driven::DrivenDither;
use crate::dither::Dither;
use crate::params::{Derived, GyroParams};
use core::cell::RefCell;
use core::f64::consts::TAU;
use rand::{RngCore, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::collections::VecDeque;

/// Segments per cached block.
pub const BLOCK: u64 = 1024;

#[derive(Clone, Debug, Default)]
struct Cache {
    /// Noise angle at the start of block `b` (segment `b * BLOCK`), for every block so far.
    checkpoints: Vec<f64>,
    block: Option<u64>,
    rates: Vec<f64>,
    /// Angle at the start of each segment of the cached block.
    angles: Vec<f64>,
}

/// A noise segment of the snapped grid (driven dither) whose end is decided.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Snapped {
    start_s: f64,
    end_s: f64,
    rate: f64,
    /// Noise angle at `start_s`.
    angle: f64,
}

/// The snapped grid decided so far (see the module docs).
#[derive(Clone, Debug, Default)]
struct Grid {
    /// Index of `decided[0]`.
    first: u64,
    /// The segments whose ends are decided, in order.
    decided: VecDeque<Snapped>,
    /// Start of the first segment whose end is not decided (index `first + decided.len()`):
    /// the noise horizon.
    open_start_s: f64,
    /// Noise angle at `open_start_s`.
    open_angle: f64,
    /// The block of Gaussians drawn last, and its draws.
    z_block: Option<u64>,
    z: Vec<f64>,
}

/// The angle-random-walk process of one gyro.
#[derive(Clone, Debug)]
pub struct Noise {
    sigma_rad_per_rt_s: f64,
    seed: u64,
    /// Dither frequency (segments are half cycles) or 0 (segments of `piece_s`).
    dither_hz: f64,
    piece_s: f64,
    /// Snap window `W` of the driven dither with the noise on (0: the nominal grid).
    snap_window_s: f64,
    cache: RefCell<Cache>,
    grid: RefCell<Grid>,
}

impl Noise {
    /// The noise of `params` (off if the ARW is 0).
    pub fn new(params: &GyroParams, derived: &Derived) -> Self {
        let on = derived.arw_rad_per_rt_s > 0.0;
        Self {
            sigma_rad_per_rt_s: derived.arw_rad_per_rt_s,
            seed: params.seed ^ 0x3c6e_f372_fe94_f82b,
            dither_hz: if params.has_dither() {
                params.dither_hz
            } else {
                0.0
            },
            piece_s: params.solver.max_piece_s,
            snap_window_s: if on && params.resonator().is_some() {
                1.0 / (8.0 * params.dither_hz)
            } else {
                0.0
            },
            cache: RefCell::new(Cache::default()),
            grid: RefCell::default(),
        }
    }

    /// True if the noise is on.
    pub fn is_on(&self) -> bool {
        self.sigma_rad_per_rt_s > 0.0
    }

    /// True if the segment boundaries snap to the driven dither's segment starts (a driven
    /// dither with the noise on).
    pub fn snaps(&self) -> bool {
        self.snap_window_s > 0.0
    }

    /// The snap window `W`: a boundary moves to a drive segment start within `[-W, W)` of its
    /// nominal time, s (1/8 of a nominal period; 0 if the grid does not snap).
    pub fn snap_window_s(&self) -> f64 {
        self.snap_window_s
    }

    /// End time of segment `k` (= start of segment `k + 1`) on the nominal grid.
    pub fn segment_end_s(&self, k: u64) -> f64 {
        if self.dither_hz > 0.0 {
            (k as f64 + 0.5) / (2.0 * self.dither_hz)
        } else {
            (k + 1) as f64 * self.piece_s
        }
    }

    /// Start time of segment `k` on the nominal grid.
    pub fn segment_start_s(&self, k: u64) -> f64 {
        if k == 0 {
            0.0
        } else {
            self.segment_end_s(k - 1)
        }
    }

    /// Index of the segment containing `t_s` on the nominal grid (segments are half-open).
    pub fn segment_index(&self, t_s: f64) -> u64 {
        let k = if self.dither_hz > 0.0 {
            (2.0 * self.dither_hz * t_s + 0.5).floor().max(0.0) as u64
        } else {
            (t_s / self.piece_s).floor().max(0.0) as u64
        };
        // Guard the floor against rounding at a boundary.
        if t_s >= self.segment_end_s(k) {
            k + 1
        } else if k > 0 && t_s < self.segment_end_s(k - 1) {
            k - 1
        } else {
            k
        }
    }

    /// The Gaussians `z_k` of block `b`.
    fn gaussians(&self, b: u64, z: &mut Vec<f64>) {
        let mut rng = ChaCha8Rng::seed_from_u64(self.seed);
        rng.set_word_pos(u128::from(b * BLOCK) * 4);
        z.clear();
        for _ in 0..BLOCK {
            let u1 = ((rng.next_u64() >> 11) + 1) as f64 * (1.0 / (1u64 << 53) as f64);
            let u2 = (rng.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64);
            z.push((-2.0 * u1.ln()).sqrt() * (TAU * u2).cos());
        }
    }

    /// The rates of block `b` on the nominal grid.
    fn gaussian_block(&self, b: u64, rates: &mut Vec<f64>) {
        self.gaussians(b, rates);
        for (j, r) in rates.iter_mut().enumerate() {
            let k = b * BLOCK + j as u64;
            let dt = self.segment_end_s(k) - self.segment_start_s(k);
            // (sigma / sqrt(dt)) z, as the rate always was (a product commutes exactly).
            *r *= self.sigma_rad_per_rt_s / dt.sqrt();
        }
    }

    /// Loads block `b` into the cache (once per [`BLOCK`] segments: out of line).
    #[inline(never)]
    fn load_block(&self, c: &mut Cache, b: u64) {
        if c.checkpoints.is_empty() {
            c.checkpoints.push(0.0);
        }
        let mut rates = Vec::with_capacity(BLOCK as usize);
        while (c.checkpoints.len() as u64) <= b {
            let bb = c.checkpoints.len() as u64 - 1;
            self.gaussian_block(bb, &mut rates);
            let mut a = c.checkpoints[bb as usize];
            for (j, r) in rates.iter().enumerate() {
                let k = bb * BLOCK + j as u64;
                a += r * (self.segment_end_s(k) - self.segment_start_s(k));
            }
            c.checkpoints.push(a);
        }
        self.gaussian_block(b, &mut rates);
        let mut a = c.checkpoints[b as usize];
        c.angles.clear();
        for (j, r) in rates.iter().enumerate() {
            c.angles.push(a);
            let k = b * BLOCK + j as u64;
            a += r * (self.segment_end_s(k) - self.segment_start_s(k));
        }
        c.rates = rates;
        c.block = Some(b);
    }

    /// Rate of segment `k` of the nominal grid and the noise angle at its start (rad/s, rad).
    #[inline]
    pub fn segment(&self, k: u64) -> (f64, f64) {
        if !self.is_on() {
            return (0.0, 0.0);
        }
        let mut c = self.cache.borrow_mut();
        let b = k / BLOCK;
        if c.block != Some(b) {
            self.load_block(&mut c, b);
        }
        let j = (k % BLOCK) as usize;
        (c.rates[j], c.angles[j])
    }

    /// The driven dither whose starts the grid snaps to, if it snaps.
    fn snapping<'a>(&self, dither: &'a Dither) -> Option<&'a DrivenDither> {
        if !self.snaps() {
            return None;
        }
        Some(
            dither
                .driven()
                .expect("the noise of a driven gyro snaps to its drive"),
        )
    }

    /// Decides the boundaries of the snapped grid that the drive known so far decides.
    fn decide(&self, g: &mut Grid, d: &DrivenDither) {
        let known = d.known_until_s();
        loop {
            let k = g.first + g.decided.len() as u64;
            let e = self.segment_end_s(k);
            let (lo, hi) = (e - self.snap_window_s, e + self.snap_window_s);
            let end = match d.segment_start_at_or_after(lo) {
                Some(s) if s < hi => s,
                _ if known >= hi => e,
                _ => return,
            };
            let block = k / BLOCK;
            if g.z_block != Some(block) {
                self.gaussians(block, &mut g.z);
                g.z_block = Some(block);
            }
            let z = g.z[(k % BLOCK) as usize];
            let dt = end - g.open_start_s;
            let rate = self.sigma_rad_per_rt_s / dt.sqrt() * z;
            g.decided.push_back(Snapped {
                start_s: g.open_start_s,
                end_s: end,
                rate,
                angle: g.open_angle,
            });
            g.open_angle += rate * dt;
            g.open_start_s = end;
        }
    }

    /// The grid, with every boundary decided that the drive decides.
    fn decided_grid(&self, d: &DrivenDither) -> core::cell::RefMut<'_, Grid> {
        let mut g = self.grid.borrow_mut();
        self.decide(&mut g, d);
        g
    }

    /// Index of the snapped segment containing `t_s` (the open one at or after its start).
    fn grid_index(&self, g: &Grid, t_s: f64) -> u64 {
        let n = g.decided.len() as u64;
        if t_s >= g.open_start_s || n == 0 {
            assert!(
                t_s >= g.open_start_s || g.first == 0,
                "noise: t = {t_s} s lies before the kept history"
            );
            return g.first + n;
        }
        // |boundary - nominal| < W < T/4: the nominal index is off by one at most.
        let mut i = self.segment_index(t_s).clamp(g.first, g.first + n - 1) - g.first;
        while t_s < g.decided[i as usize].start_s {
            if i == 0 {
                assert!(
                    g.first == 0,
                    "noise: t = {t_s} s lies before the kept history"
                );
                return 0;
            }
            i -= 1;
        }
        while t_s >= g.decided[i as usize].end_s {
            i += 1;
        }
        g.first + i
    }

    /// Index of the segment containing `t_s`: on the nominal grid, or with a driven dither
    /// (the noise on) on the grid snapped to its drive. Beyond [`Self::known_until_s`], the
    /// first segment whose end is not decided (which may not contain `t_s` in the end).
    pub fn segment_at(&self, t_s: f64, dither: &Dither) -> u64 {
        match self.snapping(dither) {
            None => self.segment_index(t_s),
            Some(d) => {
                let mut g = self.grid.borrow_mut();
                if t_s >= g.open_start_s {
                    self.decide(&mut g, d);
                }
                self.grid_index(&g, t_s)
            }
        }
    }

    /// End of segment `k` if it is decided (always on the nominal grid), s.
    pub fn segment_end_known(&self, k: u64, dither: &Dither) -> Option<f64> {
        match self.snapping(dither) {
            None => Some(self.segment_end_s(k)),
            Some(d) => {
                let g = self.decided_grid(d);
                let i = k
                    .checked_sub(g.first)
                    .expect("noise: segment dropped from history");
                g.decided.get(i as usize).map(|s| s.end_s)
            }
        }
    }

    /// The noise horizon: the time up to which the noise is known, s (the start of the first
    /// segment whose end the drive known so far does not decide; infinite unless the grid
    /// snaps).
    pub fn known_until_s(&self, dither: &Dither) -> f64 {
        match self.snapping(dither) {
            None => f64::INFINITY,
            Some(d) => self.decided_grid(d).open_start_s,
        }
    }

    /// Decides what the drive decides (before the drive's history is dropped), then drops the
    /// snapped segments that ended at or before `t_s` (keeps the one containing it).
    pub fn forget_before(&self, t_s: f64, dither: &Dither) {
        let Some(d) = self.snapping(dither) else {
            return;
        };
        let mut g = self.decided_grid(d);
        while g.decided.front().is_some_and(|s| s.end_s <= t_s) {
            g.decided.pop_front();
            g.first += 1;
        }
    }

    /// [`Self::angle_jet`] on the snapped grid. Out of line: the nominal path stays small
    /// enough to inline into the integrator's jets.
    #[inline(never)]
    fn snapped_jet(&self, t_s: f64, k: u64, dither: &Dither, out: &mut [f64]) {
        let d = dither
            .driven()
            .expect("the noise of a driven gyro snaps to its drive");
        let mut g = self.grid.borrow_mut();
        let i = k
            .checked_sub(g.first)
            .expect("noise: segment dropped from history") as usize;
        if i >= g.decided.len() {
            self.decide(&mut g, d);
        }
        out.fill(0.0);
        let Some(s) = g.decided.get(i) else {
            // Only the angle is known at the start of the open segment; its rate is not. The
            // one exception: the integrator's zero-length stretch at t = 0 before any drive,
            // which uses the angle alone (the jet's rate stays 0 there).
            assert!(
                i == g.decided.len() && t_s == g.open_start_s && (out.len() == 1 || k == 0),
                "noise: segment {k} at t = {t_s} s is not decided (known until {} s): push \
                 drive further ahead",
                g.open_start_s
            );
            out[0] = g.open_angle;
            return;
        };
        out[0] = s.angle + s.rate * (t_s - s.start_s);
        if out.len() > 1 {
            out[1] = s.rate;
        }
    }

    /// Noise angle and derivatives at `t_s` with the formula of segment `k` (rate constant),
    /// `k` as [`Self::segment_at`] gives it. With a snapped grid, segment `k`'s end must be
    /// decided (else this panics), except for the angle alone at its start (the angle is
    /// continuous), and at t = 0 before any drive (the angle, 0, and a rate left at 0).
    #[inline]
    pub fn angle_jet(&self, t_s: f64, k: u64, dither: &Dither, out: &mut [f64]) {
        if self.snaps() {
            self.snapped_jet(t_s, k, dither, out);
            return;
        }
        out.fill(0.0);
        if !self.is_on() {
            return;
        }
        let (r, a) = self.segment(k);
        out[0] = a + r * (t_s - self.segment_start_s(k));
        if out.len() > 1 {
            out[1] = r;
        }
    }

    /// Noise angle at `t_s`, rad of beat phase.
    pub fn angle_rad(&self, t_s: f64, dither: &Dither) -> f64 {
        let mut d = [0.0; 1];
        self.angle_jet(t_s, self.segment_at(t_s, dither), dither, &mut d);
        d[0]
    }
}

#[cfg(test)]
mod tests;
