//! The Lissajous fit in use: one window after another, the coefficients of the last accepted
//! one kept (a rejected window changes nothing but the rejection count).

use super::ellipse::{fit_window, Ellipse, FitRejection, LissajousConfig};
use super::levels::{LissajousCoefficients, NormalisedLevels};
use super::moments::{LissajousAccumulator, MAX_WINDOW_SAMPLES};
use crate::sample::AdcCode;

/// Per-window fitting with the coefficients in use: the previous ones are kept when a window
/// is rejected.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LissajousTracker {
    coefficients: LissajousCoefficients,
    ellipse: Option<Ellipse>,
    accumulator: LissajousAccumulator,
    last_rejection: Option<FitRejection>,
    rejections: u32,
}

impl LissajousTracker {
    /// Starts with `initial` coefficients (e.g. [`LissajousCoefficients::NOMINAL`] or stored
    /// ones) and no fit yet.
    pub const fn new(initial: LissajousCoefficients) -> Self {
        Self {
            coefficients: initial,
            ellipse: None,
            accumulator: LissajousAccumulator::new(),
            last_rejection: None,
            rejections: 0,
        }
    }

    /// Adds a sample; at the window's end fits, and returns the outcome (`Some`), starting a
    /// new window. On success the new coefficients take effect for the next [`normalise`].
    ///
    /// [`normalise`]: Self::normalise
    pub fn add(
        &mut self,
        config: &LissajousConfig,
        a_code: AdcCode,
        b_code: AdcCode,
    ) -> Option<Result<Ellipse, FitRejection>> {
        self.accumulator.add(a_code, b_code);
        let window = config.window_samples.clamp(1, MAX_WINDOW_SAMPLES);
        if self.accumulator.len() >= window {
            Some(self.finish_window(config))
        } else {
            None
        }
    }

    /// Closes the current window now (fits it if it has enough samples) and starts a new one.
    pub fn finish_window(&mut self, config: &LissajousConfig) -> Result<Ellipse, FitRejection> {
        let outcome = fit_window(&self.accumulator, config);
        self.accumulator = LissajousAccumulator::new();
        match outcome {
            Ok((coefficients, ellipse)) => {
                self.coefficients = coefficients;
                self.ellipse = Some(ellipse);
                self.last_rejection = None;
                Ok(ellipse)
            }
            Err(reason) => {
                self.last_rejection = Some(reason);
                self.rejections = self.rejections.saturating_add(1);
                Err(reason)
            }
        }
    }

    /// Coefficients in use.
    #[inline]
    pub const fn coefficients(&self) -> LissajousCoefficients {
        self.coefficients
    }

    /// The last accepted fit (`None` before the first).
    #[inline]
    pub const fn ellipse(&self) -> Option<Ellipse> {
        self.ellipse
    }

    /// Why the last window was rejected (`None` if it was accepted or none closed yet).
    #[inline]
    pub const fn last_rejection(&self) -> Option<FitRejection> {
        self.last_rejection
    }

    /// Rejected windows since start (saturating).
    #[inline]
    pub const fn rejections(&self) -> u32 {
        self.rejections
    }

    /// Normalises with the coefficients in use.
    #[inline]
    pub fn normalise(&self, a_code: AdcCode, b_code: AdcCode) -> NormalisedLevels {
        self.coefficients.normalise(a_code, b_code)
    }
}

#[cfg(test)]
mod tests {
    use super::super::synthetic::{dither_psi, Truth};
    use super::*;
    use crate::test_rng::XorShift;

    #[test]
    fn tracker_keeps_coefficients_on_rejection() {
        let cfg = LissajousConfig {
            window_samples: 2048,
            ..LissajousConfig::DEFAULT
        };
        let good = Truth {
            offset_a: 2000.0,
            offset_b: 2100.0,
            radius_a: 1400.0,
            radius_b: 1600.0,
            alpha: 0.05,
            noise: 1.5,
        };
        let mut rng = XorShift(77);
        let mut tracker = LissajousTracker::new(LissajousCoefficients::NOMINAL);
        let mut outcomes = Vec::new();
        for _ in 0..2048 {
            let (a, b) = good.codes(dither_psi(&mut rng), &mut rng);
            if let Some(o) = tracker.add(&cfg, a, b) {
                outcomes.push(o);
            }
        }
        assert_eq!(outcomes.len(), 1);
        assert!(outcomes[0].is_ok());
        let fitted = tracker.coefficients();
        assert_ne!(fitted, LissajousCoefficients::NOMINAL);
        // Signal lost for a window: rejected, coefficients kept.
        for _ in 0..2048 {
            let code = |c| AdcCode::new(c).unwrap();
            tracker.add(&cfg, code(2000), code(2100));
        }
        assert_eq!(tracker.last_rejection(), Some(FitRejection::SignalLost));
        assert_eq!(tracker.coefficients(), fitted);
        assert_eq!(tracker.rejections(), 1);
    }
}
