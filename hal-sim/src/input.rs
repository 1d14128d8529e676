//! Input-rate profiles: the body rate the gyro should measure, in deg/h, with its angle
//! (the time integral, arcsec) known analytically and its breakpoints listed.
//!
//! The integrator needs three things from an input: the angle at any time (exact, no
//! quadrature: the free phase is built from it), derivatives of the rate inside a smooth
//! piece (for turnaround search and the far-field expansion), and the breakpoints where the
//! rate or a derivative jumps (the integrator never steps or expands across one).
//!
//! 1 deg/h = 1 arcsec/s, so integrating a rate in deg/h over seconds gives arcsec.
//!
//! # Rotary table (the paper's input)
//!
//! The gyro's sensitive axis is horizontal on a table that turns about the local vertical.
//! With the table (azimuth) angle `alpha` measured from north to the sensitive axis, the
//! Earth rate `Omega_E` projects onto the axis as
//!
//! ```text
//! Omega_in = Omega_E cos(L) cos(alpha)        (L = latitude)
//! ```
//!
//! since the Earth-rate vector has the horizontal (north) component `Omega_E cos L` and the
//! vertical component `Omega_E sin L`, and a horizontal axis at azimuth `alpha` sees only the
//! north component, scaled by `cos alpha`. With `Omega_E = 15 deg/h` (solar day) and
//! `L = 22.2 deg` this gives the paper's `+-13.888 deg/h`; the sidereal rate 15.041 deg/h is
//! offered too ([`crate::units::EARTH_RATE_SIDEREAL_DEG_PER_H`]).
//!
//! A table turning at a constant rate `rho` about the vertical adds nothing to a horizontal
//! sensitive axis directly (the table's rotation vector is perpendicular to the axis); it
//! only sweeps `alpha(t) = alpha0 + rho t`, so the input becomes a sinusoid of period
//! `2 pi / rho`. Its angle integral is `Omega_E cos L (sin alpha(t) - sin alpha0) / rho`.

use core::f64::consts::TAU;

/// One piece of a piecewise-polynomial rate: `rate(t) = sum_k c_k (t - start)^k` (k = 0..3,
/// deg/h per s^k) from `start_s` to the next piece's start. The input profiles are linear
/// (c2 = c3 = 0); a gyro's thermal errors make the rate it measures cubic
/// ([`crate::thermal`]).
#[derive(Clone, Copy, Debug, PartialEq)]
struct RatePiece {
    start_s: f64,
    rate_deg_per_h: [f64; 4],
    /// Angle accumulated from t = 0 to `start_s`, arcsec.
    angle0_arcsec: f64,
}

impl RatePiece {
    /// The angle over `dt` from the piece's start, arcsec.
    fn angle_over(&self, dt: f64) -> f64 {
        let c = &self.rate_deg_per_h;
        dt * (c[0] + dt * (c[1] / 2.0 + dt * (c[2] / 3.0 + dt * c[3] / 4.0)))
    }
}

/// An input-rate profile (rates in deg/h, time in s from the gyro's start).
#[derive(Clone, Debug, PartialEq)]
pub enum InputProfile {
    /// Piecewise-linear rate (constant, steps, ramps), possibly discontinuous at the joints.
    Piecewise(PiecewiseRate),
    /// `offset + amplitude sin(2 pi f t + phase)`.
    Sinusoid {
        /// Constant part, deg/h.
        offset_deg_per_h: f64,
        /// Peak of the sinusoidal part, deg/h.
        amplitude_deg_per_h: f64,
        /// Frequency of the sinusoidal part, Hz (0: a constant `amplitude sin(phase)`).
        freq_hz: f64,
        /// Phase of the sinusoidal part at t = 0, rad.
        phase_rad: f64,
    },
    /// Earth rate on a horizontal sensitive axis on a table turning about the vertical:
    /// `Omega_E cos(L) cos(alpha0 + rho t)` (see the module docs).
    RotaryTable {
        /// Earth rate `Omega_E`, deg/h (15 solar, 15.041 sidereal).
        earth_rate_deg_per_h: f64,
        /// Latitude `L`, rad.
        latitude_rad: f64,
        /// Azimuth `alpha0` of the sensitive axis at t = 0, rad from north.
        azimuth0_rad: f64,
        /// Table rate `rho` about the vertical, rad/s (0: a fixed table).
        table_rate_rad_per_s: f64,
    },
}

/// A piecewise-linear rate with its analytic angle.
#[derive(Clone, Debug, PartialEq)]
pub struct PiecewiseRate {
    pieces: Vec<RatePiece>,
}

impl PiecewiseRate {
    /// Builds from `(start_s, rate0, slope)` triples; the first must start at 0.
    fn new(raw: &[(f64, f64, f64)]) -> Self {
        let poly: Vec<(f64, [f64; 4])> = raw
            .iter()
            .map(|&(start, r0, slope)| (start, [r0, slope, 0.0, 0.0]))
            .collect();
        Self::polynomial(&poly)
    }

    /// Builds from `(start_s, [c0, c1, c2, c3])` pieces (rate in deg/h, polynomial in the time
    /// since the piece's start); the first must start at 0.
    pub(crate) fn polynomial(raw: &[(f64, [f64; 4])]) -> Self {
        let mut pieces: Vec<RatePiece> = Vec::with_capacity(raw.len());
        let mut angle = 0.0;
        for (i, &(start, rate_deg_per_h)) in raw.iter().enumerate() {
            if i > 0 {
                let p = pieces[i - 1];
                angle += p.angle_over(start - p.start_s);
            }
            pieces.push(RatePiece {
                start_s: start,
                rate_deg_per_h,
                angle0_arcsec: angle,
            });
        }
        Self { pieces }
    }

    /// The pieces: `(start_s, [c0, c1, c2, c3])`.
    pub(crate) fn pieces(&self) -> impl Iterator<Item = (f64, [f64; 4])> + '_ {
        self.pieces.iter().map(|p| (p.start_s, p.rate_deg_per_h))
    }

    fn index(&self, t_s: f64) -> usize {
        self.pieces
            .partition_point(|p| p.start_s <= t_s)
            .saturating_sub(1)
    }
}

/// Earth rate projected on a horizontal sensitive axis at latitude `latitude_rad` and
/// azimuth `azimuth_rad` (from north): `Omega_E cos(L) cos(alpha)`, deg/h.
pub fn earth_rate_on_horizontal_axis_deg_per_h(
    earth_rate_deg_per_h: f64,
    latitude_rad: f64,
    azimuth_rad: f64,
) -> f64 {
    earth_rate_deg_per_h * latitude_rad.cos() * azimuth_rad.cos()
}

impl InputProfile {
    /// A constant rate.
    pub fn constant(rate_deg_per_h: f64) -> Self {
        Self::Piecewise(PiecewiseRate::new(&[(0.0, rate_deg_per_h, 0.0)]))
    }

    /// Rate steps: `initial` from 0, then each `(time_s, rate)` from its time on.
    /// Times must increase and be > 0.
    pub fn steps(initial_deg_per_h: f64, steps: &[(f64, f64)]) -> Self {
        let mut raw = vec![(0.0, initial_deg_per_h, 0.0)];
        raw.extend(steps.iter().map(|&(t, r)| (t, r, 0.0)));
        Self::Piecewise(PiecewiseRate::new(&raw))
    }

    /// A continuous piecewise-linear rate through `knots` `(time_s, rate)`, constant before the
    /// first and after the last knot (ramps). Times must increase and be >= 0.
    pub fn piecewise_linear(knots: &[(f64, f64)]) -> Self {
        let mut raw = vec![(0.0, knots[0].1, 0.0)];
        for w in knots.windows(2) {
            let slope = (w[1].1 - w[0].1) / (w[1].0 - w[0].0);
            raw.push((w[0].0, w[0].1, slope));
        }
        let last = knots[knots.len() - 1];
        raw.push((last.0, last.1, 0.0));
        raw.retain(|&(t, _, _)| t >= 0.0);
        raw.dedup_by(|b, a| {
            a.0 == b.0 && {
                *a = *b;
                true
            }
        });
        Self::Piecewise(PiecewiseRate::new(&raw))
    }

    /// A ramp from `rate0` at `t0` to `rate1` at `t1`, constant outside.
    pub fn ramp(t0_s: f64, rate0: f64, t1_s: f64, rate1: f64) -> Self {
        Self::piecewise_linear(&[(t0_s, rate0), (t1_s, rate1)])
    }

    /// `offset + amplitude sin(2 pi f t + phase)`.
    pub fn sinusoid(
        offset_deg_per_h: f64,
        amplitude_deg_per_h: f64,
        freq_hz: f64,
        phase_rad: f64,
    ) -> Self {
        Self::Sinusoid {
            offset_deg_per_h,
            amplitude_deg_per_h,
            freq_hz,
            phase_rad,
        }
    }

    /// The paper's rotary table at a fixed azimuth, solar Earth rate 15 deg/h.
    pub fn rotary_table(latitude_deg: f64, azimuth_deg: f64) -> Self {
        Self::RotaryTable {
            earth_rate_deg_per_h: crate::units::EARTH_RATE_SOLAR_DEG_PER_H,
            latitude_rad: latitude_deg.to_radians(),
            azimuth0_rad: azimuth_deg.to_radians(),
            table_rate_rad_per_s: 0.0,
        }
    }

    /// A rotary table turning at `table_rate_deg_per_s` about the vertical from `azimuth0_deg`.
    pub fn rotary_table_turning(
        latitude_deg: f64,
        azimuth0_deg: f64,
        table_rate_deg_per_s: f64,
    ) -> Self {
        Self::RotaryTable {
            earth_rate_deg_per_h: crate::units::EARTH_RATE_SOLAR_DEG_PER_H,
            latitude_rad: latitude_deg.to_radians(),
            azimuth0_rad: azimuth0_deg.to_radians(),
            table_rate_rad_per_s: table_rate_deg_per_s.to_radians(),
        }
    }

    /// Index of the smooth piece containing `t_s` (pieces are half-open `[start, next)`).
    pub fn piece_index(&self, t_s: f64) -> usize {
        match self {
            Self::Piecewise(p) => p.index(t_s),
            _ => 0,
        }
    }

    /// The first breakpoint strictly after `t_s`, if any.
    pub fn breakpoint_after(&self, t_s: f64) -> Option<f64> {
        match self {
            Self::Piecewise(p) => p.pieces.iter().map(|q| q.start_s).find(|&s| s > t_s),
            _ => None,
        }
    }

    /// The true input rate at `t_s`, deg/h.
    pub fn rate_deg_per_h(&self, t_s: f64) -> f64 {
        let mut d = [0.0; 2];
        self.angle_jet(t_s, self.piece_index(t_s), &mut d);
        d[1]
    }

    /// The input angle (integral of the rate from 0), arcsec.
    pub fn angle_arcsec(&self, t_s: f64) -> f64 {
        let mut d = [0.0; 1];
        self.angle_jet(t_s, self.piece_index(t_s), &mut d);
        d[0]
    }

    /// Angle and its time derivatives at `t_s`, evaluated with the formula of smooth piece
    /// `piece`: `out[0]` = angle (arcsec), `out[1]` = rate (deg/h), `out[k]` = d^k angle/dt^k.
    pub fn angle_jet(&self, t_s: f64, piece: usize, out: &mut [f64]) {
        out.fill(0.0);
        match self {
            Self::Piecewise(p) => {
                let q = &p.pieces[piece];
                let dt = t_s - q.start_s;
                out[0] = q.angle0_arcsec + q.angle_over(dt);
                // d^k angle / dt^k = d^(k-1) rate / dt^(k-1) of the cubic rate.
                let c = &q.rate_deg_per_h;
                let derivs = [
                    c[0] + dt * (c[1] + dt * (c[2] + dt * c[3])),
                    c[1] + dt * (2.0 * c[2] + dt * 3.0 * c[3]),
                    2.0 * c[2] + dt * 6.0 * c[3],
                    6.0 * c[3],
                ];
                for (o, d) in out.iter_mut().skip(1).zip(derivs) {
                    *o = d;
                }
            }
            &Self::Sinusoid {
                offset_deg_per_h,
                amplitude_deg_per_h,
                freq_hz,
                phase_rad,
            } => {
                let w = TAU * freq_hz;
                out[0] = offset_deg_per_h * t_s;
                if out.len() > 1 {
                    out[1] = offset_deg_per_h;
                }
                // angle of the sine part: -(a/w) cos(w t + p) + (a/w) cos(p)
                let x = w * t_s + phase_rad;
                if w != 0.0 {
                    let a = amplitude_deg_per_h / w;
                    out[0] += a * phase_rad.cos();
                    add_sinusoid_derivs(-a, w, x + core::f64::consts::FRAC_PI_2, out);
                } else {
                    out[0] += amplitude_deg_per_h * phase_rad.sin() * t_s;
                    if out.len() > 1 {
                        out[1] += amplitude_deg_per_h * phase_rad.sin();
                    }
                }
            }
            &Self::RotaryTable {
                earth_rate_deg_per_h,
                latitude_rad,
                azimuth0_rad,
                table_rate_rad_per_s,
            } => {
                let r = earth_rate_deg_per_h * latitude_rad.cos();
                let rho = table_rate_rad_per_s;
                if rho == 0.0 {
                    out[0] = r * azimuth0_rad.cos() * t_s;
                    if out.len() > 1 {
                        out[1] = r * azimuth0_rad.cos();
                    }
                } else {
                    // angle = (r/rho) (sin(alpha) - sin(alpha0)); rate = r cos(alpha)
                    let a = r / rho;
                    out[0] -= a * azimuth0_rad.sin();
                    add_sinusoid_derivs(a, rho, rho * t_s + azimuth0_rad, out);
                }
            }
        }
    }
}

/// Adds `d^k/dt^k [amp sin(w t + p)]` at the phase `x = w t + p` to `out[k]` for all k:
/// `amp w^k sin(x + k pi/2)`.
pub(crate) fn add_sinusoid_derivs(amp: f64, w: f64, x: f64, out: &mut [f64]) {
    let (s, c) = x.sin_cos();
    add_sinusoid_derivs_sc(amp, w, s, c, out);
}

/// As [`add_sinusoid_derivs`] from `sin x`, `cos x`.
pub(crate) fn add_sinusoid_derivs_sc(amp: f64, w: f64, s: f64, c: f64, out: &mut [f64]) {
    let cycle = [s, c, -s, -c];
    let mut scale = amp;
    for (k, o) in out.iter_mut().enumerate() {
        *o += scale * cycle[k % 4];
        scale *= w;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn check_angle_is_integral(p: &InputProfile, t_end: f64, tol: f64) {
        // Trapezoid on a fine grid against the analytic angle.
        let n = 20_000;
        let h = t_end / n as f64;
        let mut acc = 0.0;
        for i in 0..n {
            let a = i as f64 * h;
            acc += 0.5 * h * (p.rate_deg_per_h(a) + p.rate_deg_per_h(a + h));
        }
        let exact = p.angle_arcsec(t_end);
        assert!(
            (acc - exact).abs() < tol * (1.0 + exact.abs()),
            "{acc} vs {exact}"
        );
    }

    #[test]
    fn angles_are_integrals_of_rates() {
        // Trapezoid error: O(h^2) on smooth pieces, O(h * jump) at a step (h = 1e-4 s).
        check_angle_is_integral(&InputProfile::constant(3.0), 2.0, 1e-9);
        check_angle_is_integral(
            &InputProfile::steps(1.0, &[(0.5, -2.0), (1.25, 4.0)]),
            2.0,
            5e-4,
        );
        check_angle_is_integral(&InputProfile::ramp(0.2, -1.0, 1.2, 5.0), 2.0, 1e-7);
        check_angle_is_integral(&InputProfile::sinusoid(0.5, 2.0, 1.3, 0.4), 2.0, 1e-7);
        check_angle_is_integral(
            &InputProfile::rotary_table_turning(22.2, 10.0, 30.0),
            2.0,
            1e-7,
        );
    }

    #[test]
    fn rotary_table_reproduces_paper_range() {
        let p = InputProfile::rotary_table(22.2, 0.0);
        assert!((p.rate_deg_per_h(1.0) - 13.888).abs() < 1e-3);
        let p = InputProfile::rotary_table(22.2, 180.0);
        assert!((p.rate_deg_per_h(1.0) + 13.888).abs() < 1e-3);
        let p = InputProfile::rotary_table_turning(22.2, 0.0, 90.0);
        assert!(p.rate_deg_per_h(1.0).abs() < 1e-9);
    }

    #[test]
    fn breakpoints_listed() {
        let p = InputProfile::steps(1.0, &[(0.5, -2.0), (1.25, 4.0)]);
        assert_eq!(p.breakpoint_after(0.0), Some(0.5));
        assert_eq!(p.breakpoint_after(0.5), Some(1.25));
        assert_eq!(p.breakpoint_after(1.25), None);
        assert_eq!(p.piece_index(0.7), 1);
    }
}
