//! The harness's own tests: replay, stalls, the run window.

use super::*;

fn harness() -> Harness {
    HarnessOptions::new(GyroParams::default(), InputProfile::constant(10.0))
        .build()
        .unwrap()
}

/// A replayed readout sees what the harness's own readout saw: the same cycles, bit for
/// bit, whatever the feed.
#[test]
fn a_replayed_readout_matches_the_harness_readout() {
    let mut h = harness();
    let mut twin = Readout::new(h.config(), CompensationSettings::default());
    let mut cycles = 0;
    for i in 0..400 {
        let feed = match i {
            150 => Feed::MissTurnaround,
            200..=210 => Feed::Stalled,
            _ => Feed::Everything,
        };
        let half = h.step_with(feed);
        assert_eq!(h.replay_into(&mut twin), half.record, "half cycle {i}");
        cycles += usize::from(half.record.is_some());
        if i == 210 {
            h.readout_mut().resynchronise();
            twin.resynchronise();
        }
    }
    assert!(cycles > 150, "{cycles} cycles");
    assert_eq!(h.readout().counters(), twin.counters());
}

/// A stalled half cycle feeds nothing; the board runs on.
#[test]
fn a_stall_feeds_nothing() {
    let mut h = harness();
    h.step();
    let before = h.readout().counters();
    let t = h.time_s();
    let half = h.step_with(Feed::Stalled);
    assert!(half.latch_s() > t);
    assert_eq!(half.record, None);
    assert_eq!(h.readout().counters(), before);
    h.step_with(Feed::MissTurnaround);
    assert_eq!(h.readout().counters().turnarounds, before.turnarounds);
}

/// `run_until` stops at the first latch at or past its end; `run_cycles` hands over exactly
/// the cycles closed inside its window.
#[test]
fn run_cycles_keeps_to_its_window() {
    let mut h = harness();
    let (mut latches, mut ends) = (Vec::new(), Vec::new());
    h.run_until(0.05, |_, half| {
        latches.push(half.latch_s());
        if half.record.is_some() {
            ends.push(half.latch_s());
        }
    });
    assert!(latches[latches.len() - 2] < 0.05 && h.time_s() >= 0.05);
    let in_window = ends.iter().filter(|&&t| t > 0.02 && t <= 0.05).count();
    let mut n = 0;
    harness().run_cycles(0.02, 0.05, |_| n += 1);
    assert_eq!(n, in_window);
    assert!(n > 10 && n < ends.len(), "{n} of {}", ends.len());
}
