//! The board's capture timer: converts between simulated seconds and the wrapping ticks the
//! firmware's timestamps are in.
//!
//! # Model
//!
//! Simulation time is an `f64` in seconds, kept by the gyro and the board (each moves forward
//! to the instant it is asked for; there is no event queue: the harness steps from turnaround
//! to turnaround, and everything in between is computed in closed form or by the integrator).
//! The board's capture timer (TIM2 on the STM32F405, clocked at the board profile's
//! `firmware::profile::BoardProfile::timer_hz`, 84 MHz) counts whole ticks: at time `t_s` it
//! reads `start_ticks + floor(t_s * tick_hz)` modulo 2^32 ([`CaptureTimer::ticks_at`]). At
//! 84 MHz it wraps every 51.1 s; conversion back from ticks to seconds therefore needs a
//! reference time within half a wrap period ([`CaptureTimer::time_of_ticks_s`]).
//!
//! # Limits
//!
//! - `f64` seconds resolve 84 MHz ticks exactly up to about 1e8 s of simulated time (2^53 ticks);
//!   an instant at exactly a tick boundary `k / tick_hz` may land on tick `k - 1` because `k /
//!   tick_hz * tick_hz` need not round back to `k`. Keep instants off tick boundaries when the
//!   tick matters, or compare with a one-tick tolerance.
//! - The timer latches at the exact instant it is given; the pick-off path's latency is added by
//!   the board ([`crate::board`]) from the profile's delays.
//! - No clock drift or jitter: the crystal is perfect.

use firmware::profile::BoardProfile;

/// A free-running 32-bit up-counting timer: converts between seconds and wrapping ticks.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CaptureTimer {
    /// Counting frequency (Hz).
    pub tick_hz: f64,
    /// Register value at `t_s = 0` (lets tests put a wrap early).
    pub start_ticks: u32,
}

impl Default for CaptureTimer {
    /// The board profile's timer ([`BoardProfile::F405`]), reading 0 at `t_s = 0`.
    fn default() -> Self {
        Self::new(f64::from(BoardProfile::F405.timer_hz))
    }
}

impl CaptureTimer {
    /// A timer at `tick_hz` that reads 0 at `t_s = 0`.
    pub fn new(tick_hz: f64) -> Self {
        assert!(
            tick_hz > 0.0 && tick_hz.is_finite(),
            "tick_hz must be positive"
        );
        Self {
            tick_hz,
            start_ticks: 0,
        }
    }

    /// Ticks elapsed since `t_s = 0`, unwrapped (`floor(t_s * tick_hz)`).
    pub fn unwrapped_ticks_at(&self, t_s: f64) -> i64 {
        (t_s * self.tick_hz).floor() as i64
    }

    /// The register value at time `t_s` (wraps modulo 2^32).
    pub fn ticks_at(&self, t_s: f64) -> u32 {
        (self.unwrapped_ticks_at(t_s) as u32).wrapping_add(self.start_ticks)
    }

    /// Duration of `ticks` timer periods (s).
    pub fn ticks_to_s(&self, ticks: i64) -> f64 {
        ticks as f64 / self.tick_hz
    }

    /// Ticks from register value `from` to `to`, assuming less than one wrap in between.
    pub fn elapsed_ticks(from: u32, to: u32) -> u32 {
        to.wrapping_sub(from)
    }

    /// Time of one full wrap of the register (s): 2^32 / tick_hz.
    pub fn wrap_period_s(&self) -> f64 {
        (f64::from(u32::MAX) + 1.0) / self.tick_hz
    }

    /// The start time (s) of the tick whose register value is `ticks`, choosing among the wraps
    /// the one nearest to `near_s`. Exact as long as `|result - near_s|` is below half a wrap
    /// period (25.6 s at 84 MHz).
    pub fn time_of_ticks_s(&self, ticks: u32, near_s: f64) -> f64 {
        let near = self.unwrapped_ticks_at(near_s);
        let near_register = (near as u32).wrapping_add(self.start_ticks);
        let offset = ticks.wrapping_sub(near_register) as i32;
        self.ticks_to_s(near + i64::from(offset))
    }
}
