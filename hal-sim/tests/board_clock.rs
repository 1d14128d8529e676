//! The capture timer: tick conversion with wraps, at the board profile's clock.
//!
//! Tolerances: the models are deterministic and discrete, so counts, codes, bytes and ticks are
//! compared exactly, marked "(exact)"; statistical and floating checks state bound and reason.

use firmware::profile::BoardProfile;
use hal_sim::clock::CaptureTimer;

/// Ticks are `floor(t * f)`; exact for times off tick boundaries (tolerance: none).
#[test]
fn ticks_at_84_mhz() {
    let timer = CaptureTimer::default();
    assert_eq!(timer.tick_hz, f64::from(BoardProfile::F405.timer_hz));
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
