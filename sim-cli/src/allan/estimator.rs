//! The overlapping Allan deviation of a rate series with gaps, and its equivalent degrees of
//! freedom.
//!
//! Per run of valid samples (a segment, [`RateRecord::segments`]) the rate is integrated to
//! angle, `x[0] = 0, x[k + 1] = x[k] + (y[k] - mean) * tau0` (the segment's mean rate is taken out
//! first: it cancels in the second differences and keeps `x` small, so rounding
//! stays at 1e-15 relative over 15 M samples). At `tau = m * tau0` each segment gives the
//! `N - 2m` overlapping second differences `x[i + 2m] - 2 x[i + m] + x[i]` (`N` its angle
//! points); the variance is their pooled mean square over `2 tau^2`. With one segment this is
//! exactly the textbook (and allantools') `oadev` of frequency data; across a gap no difference
//! is formed, so no angle is spliced. The angle of one segment at a time is held (the longest
//! one at most), and each tau is one pass: time `O(n log n)` for octave taus (22 passes for
//! 15 M samples), memory `O(n)`.
//!
//! Tau runs in octaves `m = 1, 2, 4, ...` up to a third of the longest segment.
//!
//! The EDF of an overlapping Allan variance depends on the noise type at that tau; the
//! Howe-Allan-Barnes approximations (NIST SP 1065, Table 12) are used, summed over the
//! segments (they are independent), with the type from the fitted noise model
//! ([`super::fit`]): whichever term dominates at that tau.

use super::input::RateRecord;

/// The noise type that dominates at a tau, in the rate's terms (IEEE 952).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NoiseType {
    /// Quantisation (white angle noise): slope -1.
    Quantisation,
    /// Angle random walk (white rate noise): slope -1/2.
    AngleRandomWalk,
    /// Bias instability (flicker rate noise): slope 0.
    BiasInstability,
    /// Rate random walk: slope +1/2.
    RateRandomWalk,
}

/// The deviation at one tau.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AllanPoint {
    /// Averaging time, s.
    pub tau_s: f64,
    /// Averaging factor: tau / sample period.
    pub m: usize,
    /// Second differences averaged (over all segments).
    pub terms: u64,
    /// Allan variance, (deg/h)^2.
    pub avar: f64,
}

impl AllanPoint {
    /// Allan deviation, deg/h.
    pub fn adev_deg_h(&self) -> f64 {
        self.avar.sqrt()
    }
}

/// The Allan variance of a record at octave taus.
#[derive(Clone, Debug, PartialEq)]
pub struct AllanVariance {
    /// Sample period, s.
    pub period_s: f64,
    /// One per octave tau, ascending.
    pub points: Vec<AllanPoint>,
    /// Angle points (valid samples + 1) of each segment.
    pub segment_points: Vec<usize>,
}

impl AllanVariance {
    /// Equivalent degrees of freedom of the point at averaging factor `m`, for `noise`.
    pub fn edf(&self, m: usize, noise: NoiseType) -> f64 {
        self.segment_points
            .iter()
            .filter(|&&n| n > 2 * m)
            .map(|&n| segment_edf(n as f64, m as f64, noise))
            .sum()
    }
}

/// NIST SP 1065 Table 12 (overlapping ADEV), `n` angle points, factor `m`.
fn segment_edf(n: f64, m: f64, noise: NoiseType) -> f64 {
    let edf = match noise {
        NoiseType::Quantisation => (n + 1.0) * (n - 2.0 * m) / (2.0 * (n - m)),
        NoiseType::AngleRandomWalk => {
            (3.0 * (n - 1.0) / (2.0 * m) - 2.0 * (n - 2.0) / n) * 4.0 * m * m / (4.0 * m * m + 5.0)
        }
        NoiseType::BiasInstability if m == 1.0 => 2.0 * (n - 2.0).powi(2) / (2.3 * n - 4.9),
        NoiseType::BiasInstability => 5.0 * n * n / (4.0 * m * (n + 3.0 * m)),
        NoiseType::RateRandomWalk => {
            (n - 2.0) / m * ((n - 1.0).powi(2) - 3.0 * m * (n - 1.0) + 4.0 * m * m)
                / (n - 3.0).powi(2)
        }
    };
    // The approximations go below 1 (or negative) for the shortest segments: one difference
    // is at least one degree of freedom's worth of information, never less.
    edf.max(1.0)
}

/// Sum of squared second differences of `x` at `m`, and their number.
fn second_differences(x: &[f64], m: usize) -> (f64, u64) {
    if x.len() <= 2 * m {
        return (0.0, 0);
    }
    let sum = x
        .windows(2 * m + 1)
        .map(|w| {
            let d = w[2 * m] - 2.0 * w[m] + w[0];
            d * d
        })
        .sum();
    (sum, (x.len() - 2 * m) as u64)
}

/// The octave averaging factors of a record whose longest segment has `points` angle points.
pub fn octave_factors(points: usize) -> Vec<usize> {
    std::iter::successors(Some(1usize), |m| m.checked_mul(2))
        .take_while(|&m| 3 * m <= points)
        .collect()
}

/// The overlapping Allan variance at octave taus; `None` if no segment has 3 angle points.
pub fn allan_variance(record: &RateRecord) -> Option<AllanVariance> {
    let segments = record.segments();
    let segment_points: Vec<usize> = segments.iter().map(|s| s.len() + 1).collect();
    let factors = octave_factors(segment_points.iter().copied().max().unwrap_or(0));
    if factors.is_empty() {
        return None;
    }
    let tau0 = record.period_s;
    let mut sums = vec![(0.0f64, 0u64); factors.len()];
    let mut x = Vec::new();
    for segment in segments {
        let rates = &record.rates_deg_h[segment];
        let mean = rates.iter().sum::<f64>() / rates.len() as f64;
        x.clear();
        x.push(0.0);
        let mut angle = 0.0;
        for &y in rates {
            angle += (y - mean) * tau0;
            x.push(angle);
        }
        for (sum, &m) in sums.iter_mut().zip(&factors) {
            let (s, n) = second_differences(&x, m);
            sum.0 += s;
            sum.1 += n;
        }
    }
    let points = factors
        .iter()
        .zip(sums)
        .map(|(&m, (sum, terms))| {
            let tau_s = m as f64 * tau0;
            AllanPoint {
                tau_s,
                m,
                terms,
                avar: sum / (2.0 * tau_s * tau_s * terms as f64),
            }
        })
        .collect();
    Some(AllanVariance {
        period_s: tau0,
        points,
        segment_points,
    })
}

#[cfg(test)]
mod tests {
    use super::super::synthetic::{NoiseTerms, Synthetic};
    use super::*;

    fn record(rates: Vec<f64>, period_s: f64) -> RateRecord {
        RateRecord {
            period_s,
            rates_deg_h: rates,
            rows: 0,
            invalid_rows: 0,
            missing_samples: 0,
        }
    }

    /// Hand-computed: rates 1, 3, 2, 6 at 1 s: angle 0 1 4 6 12 (mean 3 taken out changes
    /// nothing); m = 1 differences 2, -1, 4: avar = 21 / (2 * 3) = 3.5.
    #[test]
    fn a_small_case_by_hand() {
        let av = allan_variance(&record(vec![1.0, 3.0, 2.0, 6.0], 1.0)).unwrap();
        assert_eq!(av.points.len(), 1);
        assert!((av.points[0].avar - 3.5).abs() < 1e-12, "{:?}", av.points);
        assert_eq!(av.points[0].terms, 3);
    }

    /// White rate noise of sigma per sample: ADEV = sigma / sqrt(m) in expectation; the
    /// expectation inside each octave's 99.9 % chi-squared interval (EDF of white FM), and
    /// within 2 % where that EDF exceeds 20000.
    #[test]
    fn white_noise_falls_as_one_over_root_tau() {
        let sigma = 0.18;
        let rates = Synthetic::new(
            NoiseTerms {
                arw_deg_rt_h: sigma * 1.0f64.sqrt() / 60.0,
                ..NoiseTerms::default()
            },
            1.0,
            7,
        )
        .rates(1 << 18);
        let av = allan_variance(&record(rates, 1.0)).unwrap();
        assert_eq!(av.points.len(), 17);
        for p in &av.points {
            let want = sigma * sigma / p.m as f64;
            let edf = av.edf(p.m, NoiseType::AngleRandomWalk);
            let (lo, hi) = super::super::chi2::variance_interval(p.avar, edf, 0.999);
            assert!(
                lo <= want && want <= hi,
                "m {}: avar {} want {want}",
                p.m,
                p.avar
            );
            if edf > 20_000.0 {
                assert!((p.avar / want - 1.0).abs() < 0.02, "m {}: {}", p.m, p.avar);
            }
        }
    }

    /// A rate random walk rises as +1/2: ADEV(4 m) / ADEV(m) = 2 within 15 % from m = 4 (below,
    /// the sampled walk is not yet the continuous one: at m = 1 the ratio is about 1.7) over
    /// the octaves where it has many degrees of freedom.
    #[test]
    fn a_random_walk_rises_as_root_tau() {
        let rates = Synthetic::new(
            NoiseTerms {
                rrw_deg_h_rt_h: 0.5,
                ..NoiseTerms::default()
            },
            0.1,
            3,
        )
        .rates(1 << 18);
        let av = allan_variance(&record(rates, 0.1)).unwrap();
        for w in av.points.windows(3).skip(2).take(8) {
            let ratio = (w[2].avar / w[0].avar).sqrt();
            assert!(
                (ratio / 2.0 - 1.0).abs() < 0.15,
                "m {}: ratio {ratio}",
                w[0].m
            );
        }
    }

    /// A gap splits the record: differences never span it. Two halves of white noise with an
    /// enormous jump between them have the variance of the halves, not the jump's.
    #[test]
    fn no_difference_spans_a_gap() {
        let mut rates = Synthetic::new(
            NoiseTerms {
                arw_deg_rt_h: 0.003,
                ..NoiseTerms::default()
            },
            1.0,
            5,
        )
        .rates(20_001);
        for r in &mut rates[10_001..] {
            *r += 1e6;
        }
        rates[10_000] = f64::NAN;
        let av = allan_variance(&record(rates, 1.0)).unwrap();
        let white = (0.003f64 * 60.0).powi(2);
        for p in &av.points {
            assert!(p.avar < 2.0 * white / p.m as f64, "m {}: {}", p.m, p.avar);
        }
        assert_eq!(av.segment_points, vec![10_001, 10_001]);
        assert_eq!(av.points.last().unwrap().m, 2048);
    }
}
