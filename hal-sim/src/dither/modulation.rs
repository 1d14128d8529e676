//! The prescribed dither's amplitude modulations: a resonator's slow jitter and the industry's
//! random-noise dither (`super::sine` draws their tones).

/// A smooth, seeded, band-limited modulation of the dither amplitude:
/// `A(t) = A0 (1 + m(t))`, `m(t) = sum_j a_j sin(2 pi f_j t + phi_j)` with `tones` random
/// frequencies uniform in `[min_hz, max_hz]`, random phases, and equal `a_j` such that the rms
/// of `m` is `relative_rms`. A high-Q dither resonator changes its amplitude slowly, so keep
/// `max_hz` well below the dither frequency.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AmplitudeModulation {
    /// Rms of the relative amplitude deviation `m(t)` (0 = off).
    pub relative_rms: f64,
    /// Lowest modulation frequency, Hz.
    pub min_hz: f64,
    /// Highest modulation frequency, Hz.
    pub max_hz: f64,
    /// Number of sinusoids summed.
    pub tones: usize,
}

impl AmplitudeModulation {
    /// No modulation.
    pub const OFF: Self = Self {
        relative_rms: 0.0,
        min_hz: 0.1,
        max_hz: 2.0,
        tones: 6,
    };

    /// A slow amplitude jitter of a high-Q resonator (0.1 % rms, 0.1..2 Hz).
    pub fn jitter(relative_rms: f64) -> Self {
        Self {
            relative_rms,
            ..Self::OFF
        }
    }

    /// The industry's random-noise dither: a deliberately large random amplitude modulation
    /// (e.g. 10..20 % rms) up to a few tens of Hz, which spreads the lock-in error over the
    /// turnaround phase instead of compensating it.
    pub fn random_noise_dither(relative_rms: f64) -> Self {
        Self {
            relative_rms,
            min_hz: 1.0,
            max_hz: 30.0,
            tones: 12,
        }
    }

    pub(crate) fn is_on(&self) -> bool {
        self.relative_rms > 0.0
    }
}
