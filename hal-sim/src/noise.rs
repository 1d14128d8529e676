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
//! Reproducibility: segment `k` draws its Gaussian (Box-Muller from two `u64`) at word
//! position `4 k` of a ChaCha8 stream seeded from the gyro seed, so any segment's rate is a
//! pure function of `(seed, k)`; angles at segment starts are cumulative sums in a fixed
//! order, cached with a checkpoint every [`BLOCK`] segments.

use crate::params::{Derived, GyroParams};
use core::cell::RefCell;
use core::f64::consts::TAU;
use rand::{RngCore, SeedableRng};
use rand_chacha::ChaCha8Rng;

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

/// The angle-random-walk process of one gyro.
#[derive(Clone, Debug)]
pub struct Noise {
    sigma_rad_per_rt_s: f64,
    seed: u64,
    /// Dither frequency (segments are half cycles) or 0 (segments of `piece_s`).
    dither_hz: f64,
    piece_s: f64,
    cache: RefCell<Cache>,
}

impl Noise {
    /// The noise of `params` (off if the ARW is 0).
    pub fn new(params: &GyroParams, derived: &Derived) -> Self {
        Self {
            sigma_rad_per_rt_s: derived.arw_rad_per_rt_s,
            seed: params.seed ^ 0x3c6e_f372_fe94_f82b,
            dither_hz: if params.has_dither() {
                params.dither_hz
            } else {
                0.0
            },
            piece_s: params.solver.max_piece_s,
            cache: RefCell::new(Cache::default()),
        }
    }

    /// True if the noise is on.
    pub fn is_on(&self) -> bool {
        self.sigma_rad_per_rt_s > 0.0
    }

    /// End time of segment `k` (= start of segment `k + 1`).
    pub fn segment_end_s(&self, k: u64) -> f64 {
        if self.dither_hz > 0.0 {
            (k as f64 + 0.5) / (2.0 * self.dither_hz)
        } else {
            (k + 1) as f64 * self.piece_s
        }
    }

    /// Start time of segment `k`.
    pub fn segment_start_s(&self, k: u64) -> f64 {
        if k == 0 {
            0.0
        } else {
            self.segment_end_s(k - 1)
        }
    }

    /// Index of the segment containing `t_s` (segments are half-open).
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

    fn gaussian_block(&self, b: u64, rates: &mut Vec<f64>) {
        let mut rng = ChaCha8Rng::seed_from_u64(self.seed);
        rng.set_word_pos(u128::from(b * BLOCK) * 4);
        rates.clear();
        for j in 0..BLOCK {
            let k = b * BLOCK + j;
            let u1 = ((rng.next_u64() >> 11) + 1) as f64 * (1.0 / (1u64 << 53) as f64);
            let u2 = (rng.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64);
            let z = (-2.0 * u1.ln()).sqrt() * (TAU * u2).cos();
            let dt = self.segment_end_s(k) - self.segment_start_s(k);
            rates.push(self.sigma_rad_per_rt_s / dt.sqrt() * z);
        }
    }

    fn load_block(&self, c: &mut Cache, b: u64) {
        if c.block == Some(b) {
            return;
        }
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

    /// Rate of segment `k` and the noise angle at its start (rad/s, rad).
    pub fn segment(&self, k: u64) -> (f64, f64) {
        if !self.is_on() {
            return (0.0, 0.0);
        }
        let mut c = self.cache.borrow_mut();
        self.load_block(&mut c, k / BLOCK);
        let j = (k % BLOCK) as usize;
        (c.rates[j], c.angles[j])
    }

    /// Noise angle and derivatives at `t_s` with the formula of segment `k` (rate constant).
    pub fn angle_jet(&self, t_s: f64, k: u64, out: &mut [f64]) {
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
    pub fn angle_rad(&self, t_s: f64) -> f64 {
        let mut d = [0.0; 1];
        self.angle_jet(t_s, self.segment_index(t_s), &mut d);
        d[0]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn random_walk_variance_matches_arw() {
        let p = GyroParams {
            arw_deg_per_rt_h: 0.1,
            ..Default::default()
        };
        let d = p.derive().unwrap();
        let n = Noise::new(&p, &d);
        // Increments over 1 s windows: variance ARW^2 * 1 s. 2000 windows: 3 % rel. std.
        let mut s2 = 0.0;
        let windows = 2000;
        let mut prev = n.angle_rad(0.0);
        for i in 1..=windows {
            let a = n.angle_rad(i as f64);
            s2 += (a - prev).powi(2);
            prev = a;
        }
        let var = s2 / windows as f64;
        let expect = d.arw_rad_per_rt_s.powi(2);
        assert!((var / expect - 1.0).abs() < 0.1, "{var} vs {expect}");
    }

    #[test]
    fn angle_is_continuous_and_reproducible() {
        let p = GyroParams {
            arw_deg_per_rt_h: 0.1,
            ..Default::default()
        };
        let d = p.derive().unwrap();
        let n1 = Noise::new(&p, &d);
        let n2 = Noise::new(&p, &d);
        for k in [1u64, 5, 1023, 1024, 5000] {
            let t = n1.segment_start_s(k);
            let mut a = [0.0; 1];
            let mut b = [0.0; 1];
            n1.angle_jet(t, k - 1, &mut a);
            n1.angle_jet(t, k, &mut b);
            assert!((a[0] - b[0]).abs() < 1e-12);
            assert_eq!(
                n1.angle_rad(t + 1e-4).to_bits(),
                n2.angle_rad(t + 1e-4).to_bits()
            );
            assert_eq!(n1.segment_index(t), k);
        }
    }
}
