//! The simulated clock: tick conversion with wraps, and the event queue's ordering.
//!
//! Tolerances: the models are deterministic and discrete, so counts, codes, bytes and ticks are
//! compared exactly, marked "(exact)"; statistical and floating checks state bound and reason.

use hal_sim::clock::{CaptureTimer, EventQueue, SimClock, CAPTURE_TIMER_HZ};

/// Ticks are `floor(t * f)`; exact for times off tick boundaries (tolerance: none).
#[test]
fn ticks_at_84_mhz() {
    let timer = CaptureTimer::default();
    assert_eq!(timer.tick_hz, CAPTURE_TIMER_HZ);
    assert_eq!(timer.ticks_at(0.0), 0);
    assert_eq!(timer.ticks_at(0.5e-6 / 84.0), 0);
    assert_eq!(timer.ticks_at(1.5 / 84.0e6), 1);
    assert_eq!(timer.ticks_at(1.0 + 0.5 / 84.0e6), 84_000_000);
}

/// The register wraps modulo 2^32: 51.13 s at 84 MHz; `start_ticks` moves the wrap (exact).
#[test]
fn register_wraps_at_32_bits() {
    let timer = CaptureTimer {
        tick_hz: 84.0e6,
        start_ticks: u32::MAX - 9,
    };
    assert_eq!(timer.ticks_at(5.5 / 84.0e6), u32::MAX - 4);
    assert_eq!(timer.ticks_at(10.5 / 84.0e6), 0);
    assert_eq!(timer.ticks_at(20.5 / 84.0e6), 10);
    assert_eq!(CaptureTimer::elapsed_ticks(u32::MAX - 4, 10), 15);
    let wrap_s = CaptureTimer::new(84.0e6).wrap_period_s();
    assert!((wrap_s - 51.130_563_047_619).abs() < 1e-9, "{wrap_s}");
}

/// Ticks back to seconds picks the wrap nearest the reference time. Tolerance: one tick period,
/// because a time maps to the start of its tick.
#[test]
fn time_of_ticks_resolves_wraps() {
    let timer = CaptureTimer {
        tick_hz: 84.0e6,
        start_ticks: 3_000_000_000,
    };
    let tick_s = 1.0 / timer.tick_hz;
    for &t_s in &[0.1, 15.0, 16.1, 40.0, 51.2, 120.7, 1000.3] {
        let ticks = timer.ticks_at(t_s);
        for near_s in [t_s - 20.0, t_s, t_s + 20.0] {
            let back_s = timer.time_of_ticks_s(ticks, near_s);
            assert!(
                back_s <= t_s && t_s - back_s < tick_s * 1.000_001,
                "t {t_s} near {near_s} -> {back_s}"
            );
        }
    }
}

/// The clock moves only forward and reads the timer at its current time. (exact)
#[test]
fn clock_advances() {
    let mut clock = SimClock::new(CaptureTimer::new(1.0e6));
    clock.advance_to(1.25e-3);
    assert_eq!(clock.now_ticks(), 1250);
    clock.advance_by(0.5e-3);
    assert_eq!(clock.now_s(), 1.75e-3);
}

#[test]
#[should_panic(expected = "backwards")]
fn clock_refuses_to_go_back() {
    let mut clock = SimClock::default();
    clock.advance_to(1.0);
    clock.advance_to(0.5);
}

#[derive(Debug, PartialEq)]
enum Event {
    Turnaround(u32),
    Telemetry(&'static str),
}

/// Events fire in time order; ties fire in scheduling order (exact).
#[test]
fn events_fire_in_time_order_ties_in_insertion_order() {
    let mut queue = EventQueue::new();
    queue.schedule(3.0, Event::Turnaround(3));
    queue.schedule(1.0, Event::Telemetry("first at 1"));
    queue.schedule(2.0, Event::Turnaround(2));
    queue.schedule(1.0, Event::Telemetry("second at 1"));
    queue.schedule(1.0, Event::Turnaround(1));
    let fired: Vec<_> = std::iter::from_fn(|| queue.pop()).collect();
    assert_eq!(
        fired,
        vec![
            (1.0, Event::Telemetry("first at 1")),
            (1.0, Event::Telemetry("second at 1")),
            (1.0, Event::Turnaround(1)),
            (2.0, Event::Turnaround(2)),
            (3.0, Event::Turnaround(3)),
        ]
    );
}

/// Many equal times: the sequence number, not the heap layout, decides the order. (exact)
#[test]
fn thousand_ties_keep_insertion_order() {
    let mut queue = EventQueue::new();
    for i in 0..1000u32 {
        queue.schedule(if i % 2 == 0 { 0.5 } else { 0.25 }, i);
    }
    let order: Vec<u32> = std::iter::from_fn(|| queue.pop().map(|(_, e)| e)).collect();
    let expected: Vec<u32> = (1..1000).step_by(2).chain((0..1000).step_by(2)).collect();
    assert_eq!(order, expected);
}

/// `pop_until` leaves later events; `fire_next` moves the clock to the exact event time; events
/// scheduled while handling others fire in order.
#[test]
fn run_loop_with_rescheduling() {
    let mut clock = SimClock::default();
    let mut queue = EventQueue::new();
    let period_s = 1.0 / 389.0 / 2.0;
    queue.schedule(period_s, 1u32);
    let mut fired = Vec::new();
    while let Some(n) = queue.fire_next(&mut clock, 10.0 * period_s) {
        fired.push((n, clock.now_s()));
        queue.schedule(f64::from(n + 1) * period_s, n + 1);
    }
    assert_eq!(fired.len(), 10);
    for (n, t_s) in fired {
        assert_eq!(t_s, f64::from(n) * period_s);
    }
    assert_eq!(queue.len(), 1);
    assert_eq!(queue.next_time_s(), Some(11.0 * period_s));
}

#[test]
#[should_panic(expected = "before the last fired event")]
fn scheduling_in_the_past_panics() {
    let mut queue = EventQueue::new();
    queue.schedule(2.0, ());
    queue.pop();
    queue.schedule(1.0, ());
}
