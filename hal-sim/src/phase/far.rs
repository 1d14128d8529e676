//! The far region: crossing many fringes at once with a near-identity (averaging)
//! transformation, instead of stepping them.
//!
//! Where the lock-in-free rate is large (`|omega| >= omega_c`), write the lock-in phase
//! `phi = psi - theta` as a slow part plus an oscillating part,
//!
//! ```text
//! phi = chi + W(t, psi),   W = sum_{n=1..N} w_n(t, psi),   chi' = g(t),
//! ```
//!
//! with `w_n` 2 pi-periodic, zero-mean in `psi`. Inserting into `phi' = Omega_L cos psi`,
//! `psi' = omega + Omega_L cos psi` and collecting orders in `u = Omega_L / omega` and the
//! adiabatic parameter `omega' / omega^2` gives the recursion
//!
//! ```text
//! S_1 = Omega_L cos psi,
//! g_n = mean_psi S_n,       omega dw_n/dpsi = S_n - g_n,
//! S_{n+1} = -dw_n/dt - Omega_L cos psi dw_n/dpsi,
//! ```
//!
//! so `w_1 = u sin psi`, `w_2 = (u'/omega) cos psi - (u^2/4) sin 2psi`, ..., and
//! `g = g_2 + g_4 = -Omega_L^2/(2 omega) + (u/2)(u'/omega)' - u^3 Omega_L / 8`
//! (`g_odd = 0`; `-Omega_L^2/(2 omega) - Omega_L^4/(8 omega^3)` is the expansion of Eq. 5's
//! `sqrt(omega^2 - Omega_L^2) - omega`). The size of `w_n` is about `(2n-3)!! u delta^(n-1)`
//! (`delta = |omega'|/omega^2`), an asymptotic series: at the default `omega_c = 5e5` rad/s
//! with the docs/physics.md set (`u = 1.3e-3`, `delta = 0.036`) the terms fall to ~1e-8 rad by
//! order 8 and stall there (the measured far error, ~1e-8 per boundary); at 6e5 they reach
//! 7e-10, at 8e5 1e-11. The recursion stops early where the terms vanish (at a dither peak
//! `omega' = 0`). The drift's next term `g_6` (not included) integrates to a few 1e-9 rad per
//! boundary at 5e5 (below the measured total error of 1.3e-8 rad per traversal).
//!
//! [`oscillation`] evaluates `W`'s Fourier coefficients at one instant by running the
//! recursion on truncated Taylor series in `t` (jets of `omega`), so no derivative is
//! written out by hand; [`drift_rate`] is the closed form of `g`; [`GaussIntegral`] integrates
//! `g` over a far segment (and at any time inside it, for dense output).

/// Order of the oscillating series (terms `w_1 .. w_N`); needs `omega` and N-1 derivatives.
pub const ORDER: usize = 8;
const H: usize = ORDER + 2;

type Jet = [f64; ORDER];

#[inline(always)]
fn jrecip(a: &Jet) -> Jet {
    let mut r = [0.0; ORDER];
    r[0] = 1.0 / a[0];
    for j in 1..ORDER {
        let mut s = 0.0;
        for i in 1..=j {
            s += a[i] * r[j - i];
        }
        r[j] = -s * r[0];
    }
    r
}

/// A Fourier series in `psi`: `sum_k c[k] cos(k psi) + s[k] sin(k psi)`, `k >= 1`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Oscillation {
    /// `c[k]`: amplitude of `cos(k psi)`, rad (`c[0]` unused).
    pub c: [f64; H],
    /// `s[k]`: amplitude of `sin(k psi)`, rad (`s[0]` unused).
    pub s: [f64; H],
}

impl Oscillation {
    /// `W(psi)`.
    pub fn eval(&self, psi: f64) -> f64 {
        self.derivatives(psi)[0]
    }

    /// `W(psi)` and its first four derivatives in `psi`, from one `(cos, sin)` pair.
    pub fn derivatives(&self, psi: f64) -> [f64; 5] {
        // The fast pair is exact enough below 1e5 rad (its reduction's range); beyond, libm.
        let (c1, s1) = if psi.abs() < 1e5 {
            crate::trig::fast_cos_sin(psi)
        } else {
            let (s, c) = psi.sin_cos();
            (c, s)
        };
        // cos/sin of k psi by the angle-addition recurrence; d/dpsi of c cos + s sin is
        // k (s cos - c sin).
        let (mut ck, mut sk) = (c1, s1);
        let mut d = [0.0; 5];
        for k in 1..H {
            let kf = k as f64;
            let even = self.c[k] * ck + self.s[k] * sk;
            let odd = self.s[k] * ck - self.c[k] * sk;
            d[0] += even;
            d[1] += kf * odd;
            d[2] -= kf * kf * even;
            d[3] -= kf * kf * kf * odd;
            d[4] += kf * kf * kf * kf * even;
            let (cn, sn) = (ck * c1 - sk * s1, sk * c1 + ck * s1);
            ck = cn;
            sk = sn;
        }
        d
    }
}

/// `1/k` for the harmonics `k < H` (`INV_K[0]` unused).
const INV_K: [f64; H] = {
    let mut t = [0.0; H];
    let mut k = 1;
    while k < H {
        t[k] = 1.0 / k as f64;
        k += 1;
    }
    t
};

/// Fourier coefficients of `W = w_1 + .. + w_ORDER` at one instant, from the Taylor
/// coefficients `omega_taylor[j] = omega^(j) / j!` there. Also returns the means `g_n`
/// (index n-1) of the recursion (for checks; the integrator uses [`drift_rate`]).
///
/// The recursion runs order by order (one monomorphised copy per order so every loop bound is
/// a constant: unrolled, no bounds checks; this runs at both ends of every far segment and at
/// every dense query inside one, and the loop version with run-time bounds took four times
/// the arithmetic's instructions), and stops early once the remainder is negligible (far from
/// the near region the series collapses fast: at a dither peak `omega' = 0`).
///
/// It first tries a *short run*: the Taylor lengths that a series stopping where the previous
/// instant's did (plus one order) needs, the full run only if that does not stop. The work
/// grows as the square of the Taylor length and most dense instants stop after 3 of the 8
/// orders, so this takes the simulated board from 209 M to 183 M instructions per
/// gyro-second (the bare gyro, whose queries are mostly boundaries, from 57 M to 54 M), with
/// the same result bit for bit (`oscillation_at_any_order_guess_is_the_full_run`; `rlg-sim
/// record` writes the same CSV, and a 10 h record the same Allan deviation).
pub fn oscillation_with_means(omega_taylor: &Jet, omega_l: f64) -> (Oscillation, [f64; ORDER]) {
    const _: () = assert!(ORDER == 8, "the order lists below name each order");
    // The recursion's 2.5 KB of tables are reused (zeroing them at every call was a tenth
    // of the simulator's instructions): every entry an order reads was written earlier in
    // the same call, except row 1 of `S_0` and the mean `S_0[0][0]`, which `reset` sets.
    thread_local! {
        static SCRATCH: std::cell::RefCell<Recursion> =
            std::cell::RefCell::new(Recursion::new(&[1.0; ORDER], 0.0));
        /// The order the previous call stopped at (the next instant is usually alike).
        static LAST_STOP: std::cell::Cell<usize> = const { std::cell::Cell::new(ORDER - 1) };
    }
    SCRATCH.with_borrow_mut(|r| {
        let (out, means, stop) = r.run(omega_taylor, omega_l, LAST_STOP.get() + 2);
        LAST_STOP.set(stop);
        (out, means)
    })
}

/// The recursion's state: `S_n` as cosine and sine coefficients `[harmonic][Taylor term]`,
/// the last `w_n` likewise, and the Taylor series of `1/omega`.
struct Recursion {
    sc: [[f64; ORDER]; H],
    ss: [[f64; ORDER]; H],
    wc: [[f64; ORDER]; H],
    ws: [[f64; ORDER]; H],
    inv: Jet,
    half: f64,
}

impl Recursion {
    /// `W`'s coefficients, the means and the order the series stopped at. First the short
    /// run that suffices if the series stops within `guess` orders (the order the previous
    /// instant stopped at plus two: consecutive instants are alike), else the full run. A
    /// short run that stops gives exactly the full run's terms (see [`Self::truncated`]), so
    /// the guess changes the cost, never the result.
    fn run(
        &mut self,
        omega_taylor: &Jet,
        omega_l: f64,
        guess: usize,
    ) -> (Oscillation, [f64; ORDER], usize) {
        let negligible = 1e-12 * omega_taylor[0].abs();
        let mut out = Oscillation::default();
        let mut means = [0.0; ORDER];
        self.reset(omega_taylor, omega_l);
        let short = match guess {
            2 => self.truncated::<2>(&mut out, &mut means, negligible),
            3 => self.truncated::<3>(&mut out, &mut means, negligible),
            4 => self.truncated::<4>(&mut out, &mut means, negligible),
            5 => self.truncated::<5>(&mut out, &mut means, negligible),
            6 => self.truncated::<6>(&mut out, &mut means, negligible),
            7 => self.truncated::<7>(&mut out, &mut means, negligible),
            _ => None,
        };
        if let Some(stop) = short {
            return (out, means, stop);
        }
        if (2..ORDER).contains(&guess) {
            self.reset(omega_taylor, omega_l);
            out = Oscillation::default();
            means = [0.0; ORDER];
        }
        let stop = self
            .truncated::<ORDER>(&mut out, &mut means, negligible)
            .unwrap_or_else(|| {
                means[ORDER - 1] = self.sc[0][0];
                self.order::<{ ORDER - 1 }, ORDER>(&mut out);
                ORDER - 1
            });
        (out, means, stop)
    }

    fn new(omega_taylor: &Jet, omega_l: f64) -> Self {
        let mut sc = [[0.0; ORDER]; H];
        sc[1][0] = omega_l;
        Self {
            sc,
            ss: [[0.0; ORDER]; H],
            wc: [[0.0; ORDER]; H],
            ws: [[0.0; ORDER]; H],
            inv: jrecip(omega_taylor),
            half: 0.5 * omega_l,
        }
    }

    /// Starts the recursion at `S_1 = Omega_L cos psi` for the rate `omega_taylor`: sets what
    /// order 0 reads and nothing else (see [`oscillation_with_means`]).
    fn reset(&mut self, omega_taylor: &Jet, omega_l: f64) {
        self.sc[0][0] = 0.0;
        self.sc[1] = [0.0; ORDER];
        self.sc[1][0] = omega_l;
        self.ss[1] = [0.0; ORDER];
        self.inv = jrecip(omega_taylor);
        self.half = 0.5 * omega_l;
    }

    /// The orders `0 ..= M - 2` of a run truncated at `M` orders, each checked: `Some(n)`
    /// once the remainder after order `n` is below `negligible` (`W` is then `w_0 .. w_n`),
    /// `None` if it never is.
    ///
    /// Order `n` carries the `M - n` Taylor terms that `w_{M-1}` would need (`w_n`'s term
    /// `j` reads `S_n`'s terms `0..=j`, and `S_{n+1}`'s term `j` reads `w_n`'s `j` and
    /// `j + 1`). Every entry it computes is computed by the same operations as in the full
    /// run (`M = ORDER`), so a run that stops gives the full run's `W` and means bit for bit,
    /// at a fraction of the cost: the recursion's work grows as the square of the Taylor
    /// length, and at a dense instant deep in a far segment the series stops after 3-5 of
    /// its 8 orders (`oscillation_at_any_order_guess_is_the_full_run` checks the identity).
    #[inline(always)]
    fn truncated<const M: usize>(
        &mut self,
        out: &mut Oscillation,
        means: &mut [f64; ORDER],
        negligible: f64,
    ) -> Option<usize> {
        macro_rules! checked {
            ($($n:literal)*) => {$(
                if $n + 1 < M {
                    means[$n] = self.sc[0][0];
                    if self.order::<$n, M>(out) < negligible {
                        return Some($n);
                    }
                }
            )*};
        }
        checked!(0 1 2 3 4 5 6);
        None
    }

    /// Order `N` (from 0) of a run truncated at `M` orders: `w_N` from `S_N` (added to
    /// `out`), then `S_{N+1}`; returns the largest coefficient of `S_{N+1}` at the instant
    /// (rad/s), the size of what is left.
    ///
    /// At order N only harmonics below `N + 2` and the first `ORDER - N` Taylor terms are
    /// live; each entry of `S_{N+1}` is gathered once from `w_N`:
    /// `-dw/dt` keeps the harmonic, `-Omega_L cos(psi) dw/dpsi` moves it by one either way.
    #[inline(always)]
    fn order<const N: usize, const M: usize>(&mut self, out: &mut Oscillation) -> f64 {
        let top = if N + 2 < H { N + 2 } else { H };
        // (Instantiated for N >= M too, never called: no overflow there.)
        let len = M.saturating_sub(N);
        // w_N = antiderivative in psi of the oscillating part of S_N, divided by omega.
        // (Index loops: the iterator adapters' version was not unrolled.)
        #[allow(clippy::needless_range_loop)]
        for k in 1..top {
            let inv_k = INV_K[k];
            for j in 0..len {
                let (mut a, mut b) = (0.0, 0.0);
                for i in 0..=j {
                    a += self.ss[k][i] * self.inv[j - i];
                    b += self.sc[k][i] * self.inv[j - i];
                }
                self.wc[k][j] = -a * inv_k;
                self.ws[k][j] = b * inv_k;
            }
            out.c[k] += self.wc[k][0];
            out.s[k] += self.ws[k][0];
        }
        // S_{N+1} = -dw/dt - Omega_L cos psi dw/dpsi, harmonics 0 ..= top (the next order
        // needs the first len - 1 Taylor terms).
        let next = len.saturating_sub(1);
        let (wc, ws, half) = (&self.wc, &self.ws, self.half);
        let ntop = if top + 1 < H { top + 1 } else { H };
        let mut rest: f64 = 0.0;
        for m in 0..ntop {
            for j in 0..next {
                let d = (j + 1) as f64;
                let (mut c, mut s) = (0.0, 0.0);
                if m >= 1 && m < top {
                    c -= d * wc[m][j + 1];
                    s -= d * ws[m][j + 1];
                }
                // From harmonic m + 1 (cos psi moves it down by one).
                if m + 1 < top {
                    let kf = (m + 1) as f64;
                    c -= half * kf * ws[m + 1][j];
                    if m >= 1 {
                        s += half * kf * wc[m + 1][j];
                    }
                }
                // From harmonic m - 1 (moved up by one).
                if m >= 2 && m - 1 < top {
                    let kf = (m - 1) as f64;
                    c -= half * kf * ws[m - 1][j];
                    s += half * kf * wc[m - 1][j];
                }
                self.sc[m][j] = c;
                self.ss[m][j] = s;
                if j == 0 && m >= 1 {
                    // (Not `f64::max`: its NaN handling costs a branch per call.)
                    let size = if c.abs() > s.abs() { c.abs() } else { s.abs() };
                    if size > rest {
                        rest = size;
                    }
                }
            }
        }
        rest
    }
}

/// Fourier coefficients of `W` (see [`oscillation_with_means`]).
pub fn oscillation(omega_taylor: &Jet, omega_l: f64) -> Oscillation {
    oscillation_with_means(omega_taylor, omega_l).0
}

/// The slow drift `chi' = g_2 + g_4` from `omega`, `omega'`, `omega''` (rad/s).
pub fn drift_rate(omega: f64, d1: f64, d2: f64, omega_l: f64) -> f64 {
    let u = omega_l / omega;
    let w2 = omega * omega;
    let dut_over_w = -omega_l * (d2 / (w2 * omega) - 3.0 * d1 * d1 / (w2 * w2));
    -0.5 * omega_l * u + 0.5 * u * dut_over_w - u * u * u * omega_l / 8.0
}

/// `phi` from `chi`: solves `phi = chi + W(theta + phi)`.
///
/// `e = phi - chi` is the oscillation itself (`|e| <= u`, 1.4e-3 rad at most), so `W` is
/// expanded about `psi_0 = theta + chi` to fourth order (truncation `u e^5 / 120 < 1e-18`
/// rad) from one `(cos, sin)` pair, and `e = W(psi_0 + e)` is iterated on that quartic
/// (contraction `~u`: rounding level in a few steps of plain arithmetic). Iterating on `W`
/// itself cost a `(cos, sin)` and the harmonic recurrence per step, five or six times.
pub fn solve_phi(chi: f64, theta: f64, w: &Oscillation) -> f64 {
    let [w0, w1, w2, w3, w4] = w.derivatives(theta + chi);
    let mut e = w0;
    for _ in 0..12 {
        let next = w0 + e * (w1 + e * (0.5 * w2 + e * (w3 / 6.0 + e * (w4 / 24.0))));
        let done = next == e;
        e = next;
        if done {
            break;
        }
    }
    chi + e
}

/// Nodes of a [`GaussIntegral`].
pub const GAUSS_NODES: usize = 10;

/// The Gauss-Legendre rule of [`GAUSS_NODES`] nodes on `[-1, 1]` and the projection onto the
/// Legendre polynomials: `proj[n][k] = (2n + 1)/2 w_k P_n(x_k)`.
struct GaussTable {
    x: [f64; GAUSS_NODES],
    proj: [[f64; GAUSS_NODES]; GAUSS_NODES],
}

fn gauss_table() -> &'static GaussTable {
    static TABLE: std::sync::OnceLock<GaussTable> = std::sync::OnceLock::new();
    TABLE.get_or_init(|| {
        let (x, w) = super::gauss::rule::<GAUSS_NODES>();
        let mut proj = [[0.0; GAUSS_NODES]; GAUSS_NODES];
        for (k, (&xk, &wk)) in x.iter().zip(&w).enumerate() {
            let p = legendre_values(xk);
            for (n, row) in proj.iter_mut().enumerate() {
                row[k] = (2 * n + 1) as f64 * 0.5 * wk * p[n];
            }
        }
        GaussTable { x, proj }
    })
}

/// `P_0(x) ..= P_GAUSS_NODES(x)` by the three-term recurrence.
fn legendre_values(x: f64) -> [f64; GAUSS_NODES + 1] {
    let mut p = [0.0; GAUSS_NODES + 1];
    p[0] = 1.0;
    p[1] = x;
    for n in 1..GAUSS_NODES {
        let nf = n as f64;
        p[n + 1] = ((2.0 * nf + 1.0) * x * p[n] - nf * p[n - 1]) / (nf + 1.0);
    }
    p
}

/// `F(x) = integral_{x_a}^{x} f` from `f` at the [`GAUSS_NODES`] Gauss-Legendre nodes of
/// `[x_a, x_b]`.
///
/// The whole integral ([`Self::total`]) is the Gauss rule, exact for polynomials of degree
/// 19; values inside ([`Self::eval`]) integrate the degree-9 polynomial through the nodes,
/// as a Legendre series (`integral_{-1}^{s} P_n = (P_{n+1}(s) - P_{n-1}(s)) / (2n + 1)`),
/// so dense output costs no evaluation of `f` beyond the rule's. At `x_b` the two agree to
/// rounding (`c_0` is the rule).
#[derive(Clone, Debug, PartialEq)]
pub struct GaussIntegral {
    x_a: f64,
    x_b: f64,
    /// Legendre coefficients of the interpolant on `[-1, 1]`, times the half width.
    coef: [f64; GAUSS_NODES],
}

impl GaussIntegral {
    /// Samples `f` at the nodes of `[x_a, x_b]`.
    pub fn new(x_a: f64, x_b: f64, f: impl Fn(f64) -> f64) -> Self {
        let table = gauss_table();
        let (half, mid) = (0.5 * (x_b - x_a), 0.5 * (x_a + x_b));
        let fv = table.x.map(|x| f(mid + half * x));
        let coef = table
            .proj
            .map(|row| half * row.iter().zip(&fv).map(|(p, v)| p * v).sum::<f64>());
        Self { x_a, x_b, coef }
    }

    /// `integral_{x_a}^{x_b} f`.
    pub fn total(&self) -> f64 {
        2.0 * self.coef[0]
    }

    /// `integral_{x_a}^{x} f`, for `x` in `[x_a, x_b]` (clamped).
    pub fn eval(&self, x: f64) -> f64 {
        if self.x_b == self.x_a {
            return 0.0;
        }
        let s = ((2.0 * x - self.x_a - self.x_b) / (self.x_b - self.x_a)).clamp(-1.0, 1.0);
        let p = legendre_values(s);
        let mut acc = self.coef[0] * (s + 1.0);
        for n in 1..GAUSS_NODES {
            acc += self.coef[n] * (p[n + 1] - p[n - 1]) / (2 * n + 1) as f64;
        }
        acc
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn recursion_matches_hand_derived_terms() {
        // omega(t0 + tau) = w0 + w1 tau + w2 tau^2 + w3 tau^3 ...
        let omega_l = 673.6;
        let tay = [1.2e6, 8.7e9, -3.0e12, 1.0e15, 2.0e17, 0.0, 0.0, 0.0];
        let (osc, means) = oscillation_with_means(&tay, omega_l);
        let (w, d1, d2) = (tay[0], tay[1], 2.0 * tay[2]);
        let u = omega_l / w;
        let ut = -omega_l * d1 / (w * w);
        let utw_t = -omega_l * (d2 / w.powi(3) - 3.0 * d1 * d1 / w.powi(4));
        // w1 + w2 (+ w3's first harmonic)
        let b = -utw_t + u * u * omega_l / 4.0;
        assert!((osc.s[2] - (-u * u / 4.0 - u * ut / (2.0 * w) * 0.0)).abs() < 1e-3 * u * u);
        let c1 = ut / w;
        assert!(
            (osc.c[1] - c1).abs() < 0.05 * c1.abs(),
            "{} vs {c1}",
            osc.c[1]
        );
        let s1 = u + b / w;
        assert!(
            (osc.s[1] - s1).abs() < 1e-2 * (b / w).abs(),
            "{} vs {s1}",
            osc.s[1]
        );
        assert!((osc.s[3] - u.powi(3) / 12.0).abs() < 1e-3 * u.powi(3));
        // Means: g1 = 0, g2 = -Omega_L u / 2, g3 = 0, g2 + g4 = drift_rate.
        assert_eq!(means[0], 0.0);
        assert!((means[1] + 0.5 * omega_l * u).abs() < 1e-12 * omega_l * u);
        assert!(means[2].abs() < 1e-6 * means[1].abs());
        let g = means[1] + means[3];
        let gd = drift_rate(w, d1, d2, omega_l);
        assert!((g - gd).abs() < 1e-9 * gd.abs(), "{g} vs {gd}");
    }

    /// The short runs are the full run, bit for bit, whatever the guess: at the far boundary
    /// (all 8 orders needed), across a far segment, and at a dither peak (`omega' = 0`, the
    /// series stops after a few orders). Instants where a guess is too short fall back.
    #[test]
    fn oscillation_at_any_order_guess_is_the_full_run() {
        let mut r = Recursion::new(&[1.0; ORDER], 0.0);
        let mut stops = [0usize; ORDER];
        for i in 0..400 {
            let x = i as f64 / 400.0;
            // omega from the near/far boundary (4.8e5 rad/s) to a dither peak (3.7e6).
            let w = 4.8e5 + x * 3.2e6;
            let slope = 9.0e9 * (1.0 - x) * (1.0 - 2.0 * (i % 2) as f64);
            let tay = [
                w,
                slope,
                -4.5e12 * x,
                -1.5e15 * (1.0 - x),
                2.0e17,
                -1e20,
                3e22,
                0.0,
            ];
            let full = r.run(&tay, 673.6, ORDER);
            stops[full.2] += 1;
            for guess in 2..ORDER {
                let short = r.run(&tay, 673.6, guess);
                assert_eq!(short.0, full.0, "W at guess {guess}, instant {i}");
                assert_eq!(short.1, full.1, "means at guess {guess}, instant {i}");
                assert_eq!(short.2, full.2, "stop at guess {guess}, instant {i}");
            }
        }
        // Both kinds of instant occur: early stops and the full 8 orders.
        assert!(stops[..5].iter().sum::<usize>() > 50, "{stops:?}");
        assert!(stops[ORDER - 1] > 10, "{stops:?}");
    }

    /// The quartic expansion of `W` in `solve_phi` against fixed-point iteration on `W` itself,
    /// at the far boundary's size of `W` (u = 1.4e-3) and all phases.
    #[test]
    fn solve_phi_matches_iteration_on_w() {
        let tay = [4.8e5, 9.0e9, -3.0e12, 1.0e15, 2.0e17, 0.0, 0.0, 0.0];
        let osc = oscillation(&tay, 673.6);
        let mut worst: f64 = 0.0;
        for i in 0..1000 {
            let (chi, theta) = (0.3, i as f64 * 0.0123);
            let mut phi = chi;
            for _ in 0..40 {
                phi = chi + osc.eval(theta + phi);
            }
            worst = worst.max((solve_phi(chi, theta, &osc) - phi).abs());
        }
        // Within two ulps of phi (~0.3 rad: an ulp is 5.6e-17; measured one). The quartic's
        // truncation is < 1e-18 rad (the cubic's, 2e-16, fails here); theta stays below 13
        // rad so that its rounding, times W', is negligible.
        assert!(worst <= 2.0 * 5.6e-17, "{worst}");
    }

    #[test]
    fn constant_rate_drift_is_eq5() {
        let (w, l) = (1.0e6f64, 673.6f64);
        let exact = -l * l / (w + (w * w - l * l).sqrt());
        assert!((drift_rate(w, 0.0, 0.0, l) - exact).abs() < 1e-12 * exact.abs());
    }

    #[test]
    fn gauss_integral_is_exact_to_its_degrees() {
        // Degree 9: the interpolant is the function, so values inside are exact too.
        let p9 = |t: f64| (0..10).fold(0.0, |acc, k| acc * t + (k as f64 - 4.5));
        let int9 = |t: f64| -> f64 {
            (0..10i32)
                .map(|k| (k as f64 - 4.5) * t.powi(10 - k) / (10 - k) as f64)
                .sum()
        };
        let g = GaussIntegral::new(-0.5, 1.5, p9);
        for t in [-0.5, 0.1, 0.7, 1.5] {
            let exact = int9(t) - int9(-0.5);
            assert!(
                (g.eval(t) - exact).abs() < 1e-13,
                "{t}: {} vs {exact}",
                g.eval(t)
            );
        }
        // Degree 19: only the whole integral (the Gauss rule) is exact.
        let g = GaussIntegral::new(0.0, 1.0, |t: f64| t.powi(19));
        assert!((g.total() - 0.05).abs() < 1e-15);
        assert!((g.eval(1.0) - 0.05).abs() < 1e-15);
        // A pole at -0.3 (Bernstein ellipse rho = 2.85): the rule's error ~rho^-20 ~ 1e-9.
        let g = GaussIntegral::new(0.0, 1.0, |t: f64| 1.0 / (0.3 + t));
        let exact = (1.3f64 / 0.3).ln();
        assert!((g.total() - exact).abs() < 2e-9, "{}", g.total() - exact);
    }
}
