//! The temperature's rate: the least-squares slope of the last [`RATE_WINDOW`] results.
//!
//! A slope over N results spaced dt apart with white noise sigma has the standard deviation
//! `sigma sqrt(12 / N) / (N dt)` (N >> 1): with the TMP117's ~1 LSB (7.8 m°C) at 8 results a
//! second, 16 results (2 s) give 3.4 m°C/s = 0.2 °C/min, and the rate lags the temperature by
//! half the window (1 s). The window trades the two: a longer one is quieter but follows a change
//! of the ramp later. The rate is valid only over a full window of results without a gap (no
//! more than [`MAX_GAP_MS`] between two): after a sensor fault it is rebuilt from scratch.

use super::sensor::Reading;

/// Results in the slope's window.
pub const RATE_WINDOW: usize = 16;
/// The largest gap between two results inside one window, ms (two conversion times).
pub const MAX_GAP_MS: u64 = 250;

/// The last results and their slope.
#[derive(Clone, Copy, Debug, Default)]
pub struct RateEstimator {
    /// (ms since the first result of the window, °C), oldest first.
    window: [(u64, f32); RATE_WINDOW],
    len: usize,
    last_ms: Option<u64>,
}

impl RateEstimator {
    /// Empty.
    pub fn new() -> Self {
        Self::default()
    }

    /// Forgets every result (a sensor fault).
    pub fn clear(&mut self) {
        *self = Self::default();
    }

    /// Adds a result (in time order).
    pub fn push(&mut self, reading: &Reading) {
        if self
            .last_ms
            .is_some_and(|last| reading.at_ms.saturating_sub(last) > MAX_GAP_MS)
        {
            self.clear();
        }
        self.last_ms = Some(reading.at_ms);
        let entry = (reading.at_ms, reading.temp_c());
        if self.len < RATE_WINDOW {
            if let Some(slot) = self.window.get_mut(self.len) {
                *slot = entry;
            }
            self.len = self.len.saturating_add(1);
        } else {
            self.window.rotate_left(1);
            if let Some(slot) = self.window.last_mut() {
                *slot = entry;
            }
        }
    }

    /// The slope of the window, °C/s; `None` until the window is full.
    pub fn rate_c_per_s(&self) -> Option<f32> {
        if self.len < RATE_WINDOW {
            return None;
        }
        let t0 = self.window.first()?.0;
        let n = RATE_WINDOW as f32;
        let (mut st, mut sy) = (0.0f32, 0.0f32);
        for &(t, y) in &self.window {
            st += t.saturating_sub(t0) as f32 * 1e-3;
            sy += y;
        }
        let (mt, my) = (st / n, sy / n);
        let (mut stt, mut sty) = (0.0f32, 0.0f32);
        for &(t, y) in &self.window {
            let dt = t.saturating_sub(t0) as f32 * 1e-3 - mt;
            stt += dt * dt;
            sty += dt * (y - my);
        }
        (stt > 0.0).then(|| sty / stt)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn reading(at_ms: u64, temp_c: f32) -> Reading {
        Reading {
            raw: (temp_c * 128.0).round() as i16,
            at_ms,
        }
    }

    /// A ramp of 0.5 °C/s read at 8 Hz: the slope within the results' quantisation (1/128 °C
    /// over a 1.9 s window: < 0.004 °C/s); a gap restarts the window.
    #[test]
    fn the_slope_of_a_ramp_and_a_gap_restarts_it() {
        let mut r = RateEstimator::new();
        for i in 0..RATE_WINDOW as u64 - 1 {
            r.push(&reading(i * 125, 20.0 + 0.5 * i as f32 * 0.125));
            assert_eq!(r.rate_c_per_s(), None);
        }
        r.push(&reading(15 * 125, 20.0 + 0.5 * 15.0 * 0.125));
        let rate = r.rate_c_per_s().unwrap();
        assert!((rate - 0.5).abs() < 0.004, "{rate}");
        r.push(&reading(15 * 125 + 400, 30.0));
        assert_eq!(r.rate_c_per_s(), None);
    }
}
