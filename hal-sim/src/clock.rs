//! Simulated time: a continuous clock in seconds, the free-running capture timer in ticks, and an
//! event queue that fires events in time order at their exact times.
//!
//! # Model
//!
//! Simulation time is an `f64` in seconds ([`SimClock::now_s`]). The board's capture timer (a
//! 32-bit general-purpose timer such as TIM2/TIM5 on the STM32F405, clocked at 84 MHz) counts
//! whole ticks: at time `t_s` it reads `start_ticks + floor(t_s * tick_hz)` modulo 2^32
//! ([`CaptureTimer::ticks_at`]). At 84 MHz it wraps every 51.1 s; conversion back from ticks to
//! seconds therefore needs a reference time within half a wrap period
//! ([`CaptureTimer::time_of_ticks_s`]).
//!
//! [`EventQueue`] is a priority queue of `(time, event)` pairs, generic over the event type. Events
//! fire in time order; events scheduled for the same time fire in the order they were scheduled
//! (a sequence number breaks ties, so the order never depends on the heap's internals). The queue
//! refuses to schedule an event before the last one it fired: that would be a causality bug in
//! the caller.
//!
//! # Limits
//!
//! - `f64` seconds resolve 84 MHz ticks exactly up to about 1e8 s of simulated time (2^53 ticks);
//!   an event at exactly a tick boundary `k / tick_hz` may land on tick `k - 1` because `k /
//!   tick_hz * tick_hz` need not round back to `k`. Keep event times off tick boundaries when the
//!   tick matters, or compare with a one-tick tolerance.
//! - A real input capture latches the counter one to three timer clocks after the input edge
//!   (resynchronisation and the digital filter); the model latches at the exact instant. Firmware
//!   that needs the latency can subtract a constant.
//! - No clock drift or jitter: the crystal is perfect.

use std::cmp::Ordering;
use std::collections::BinaryHeap;

/// Tick frequency of the STM32F405's 32-bit capture timers (APB1 timer clock, 84 MHz).
pub const CAPTURE_TIMER_HZ: f64 = 84.0e6;

/// A free-running 32-bit up-counting timer: converts between seconds and wrapping ticks.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CaptureTimer {
    /// Counting frequency (Hz).
    pub tick_hz: f64,
    /// Register value at `t_s = 0` (lets tests put a wrap early).
    pub start_ticks: u32,
}

impl Default for CaptureTimer {
    fn default() -> Self {
        Self {
            tick_hz: CAPTURE_TIMER_HZ,
            start_ticks: 0,
        }
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
        4_294_967_296.0 / self.tick_hz
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

/// Simulation time plus the capture timer that the firmware reads.
#[derive(Clone, Debug, PartialEq)]
pub struct SimClock {
    now_s: f64,
    timer: CaptureTimer,
}

impl SimClock {
    /// A clock at `t_s = 0` with the given capture timer.
    pub fn new(timer: CaptureTimer) -> Self {
        Self { now_s: 0.0, timer }
    }

    /// Current simulation time (s).
    pub fn now_s(&self) -> f64 {
        self.now_s
    }

    /// The capture timer.
    pub fn timer(&self) -> &CaptureTimer {
        &self.timer
    }

    /// Capture timer register now.
    pub fn now_ticks(&self) -> u32 {
        self.timer.ticks_at(self.now_s)
    }

    /// Move time forward to `t_s`. Panics if `t_s` is before now or not finite.
    pub fn advance_to(&mut self, t_s: f64) {
        assert!(t_s.is_finite(), "time must be finite");
        assert!(
            t_s >= self.now_s,
            "clock cannot go backwards: {t_s} < {}",
            self.now_s
        );
        self.now_s = t_s;
    }

    /// Move time forward by `dt_s` (>= 0).
    pub fn advance_by(&mut self, dt_s: f64) {
        self.advance_to(self.now_s + dt_s);
    }
}

impl Default for SimClock {
    fn default() -> Self {
        Self::new(CaptureTimer::default())
    }
}

/// One scheduled event.
struct Entry<E> {
    at_s: f64,
    seq: u64,
    event: E,
}

impl<E> PartialEq for Entry<E> {
    fn eq(&self, other: &Self) -> bool {
        self.cmp(other) == Ordering::Equal
    }
}

impl<E> Eq for Entry<E> {}

impl<E> PartialOrd for Entry<E> {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

impl<E> Ord for Entry<E> {
    /// Reversed, so that `BinaryHeap` (a max-heap) pops the earliest, then first-scheduled, entry.
    fn cmp(&self, other: &Self) -> Ordering {
        other
            .at_s
            .total_cmp(&self.at_s)
            .then_with(|| other.seq.cmp(&self.seq))
    }
}

/// Events at exact times, fired in time order; ties fire in scheduling order.
pub struct EventQueue<E> {
    heap: BinaryHeap<Entry<E>>,
    next_seq: u64,
    last_fired_s: f64,
}

impl<E> Default for EventQueue<E> {
    fn default() -> Self {
        Self::new()
    }
}

impl<E> EventQueue<E> {
    /// An empty queue.
    pub fn new() -> Self {
        Self {
            heap: BinaryHeap::new(),
            next_seq: 0,
            last_fired_s: f64::NEG_INFINITY,
        }
    }

    /// Schedule `event` at `at_s`. Panics if `at_s` is not finite or earlier than the last fired
    /// event (an event in the past is a causality bug).
    pub fn schedule(&mut self, at_s: f64, event: E) {
        assert!(at_s.is_finite(), "event time must be finite");
        assert!(
            at_s >= self.last_fired_s,
            "event at {at_s} s scheduled before the last fired event at {} s",
            self.last_fired_s
        );
        self.heap.push(Entry {
            at_s,
            seq: self.next_seq,
            event,
        });
        self.next_seq += 1;
    }

    /// Time of the next event, if any.
    pub fn next_time_s(&self) -> Option<f64> {
        self.heap.peek().map(|e| e.at_s)
    }

    /// Remove and return the next event with its time.
    pub fn pop(&mut self) -> Option<(f64, E)> {
        let entry = self.heap.pop()?;
        self.last_fired_s = entry.at_s;
        Some((entry.at_s, entry.event))
    }

    /// Remove and return the next event if it is due at or before `until_s`.
    pub fn pop_until(&mut self, until_s: f64) -> Option<(f64, E)> {
        if self.next_time_s()? <= until_s {
            self.pop()
        } else {
            None
        }
    }

    /// Pop the next event due at or before `until_s` and advance `clock` to its time. Panics if
    /// the clock is already past the event (it was advanced behind the queue's back).
    pub fn fire_next(&mut self, clock: &mut SimClock, until_s: f64) -> Option<E> {
        let (at_s, event) = self.pop_until(until_s)?;
        clock.advance_to(at_s);
        Some(event)
    }

    /// Number of pending events.
    pub fn len(&self) -> usize {
        self.heap.len()
    }

    /// True when no event is pending.
    pub fn is_empty(&self) -> bool {
        self.heap.is_empty()
    }
}
