//! Rate monitors: the board watches its own periodic events and names the one whose rate is
//! off.
//!
//! Every periodic event of the board's timing chain is counted where it happens (an interrupt
//! handler increments a wrapping `u32`) and the main loop hands the counts and its millisecond
//! clock to a [`TimingWatch`] on every pass. Each [`Event`] has a monitor: over each window of
//! [`RateSpec::window_ms`] it compares the counted rate with the expected one; a rate off by
//! more than [`RateSpec::tolerance`] in every window for at least [`RateSpec::hold_ms`] raises
//! the event's fault, and the first window back within tolerance clears it (the fault count
//! stays). An event not expected now (no turnarounds while the drive is not locked) is not
//! monitored and its state is cleared.
//!
//! | event | where it is counted | expected | tolerance | window | hold |
//! |---|---|---|---|---|---|
//! | `lissajous` | DMA2 stream 0 half/full transfer (256 photodiode pairs) | 12 347.5 / 256 = 48.2 Hz | 10 % | 1000 ms | 2000 ms |
//! | `drive_tick` | TIM4 CC1, the drive tick's handler | 40 kHz | 2 % | 100 ms | 300 ms |
//! | `turnaround` | the latch handler, a turnaround | 2 x the locked drive's frequency | 5 % | 250 ms | 500 ms |
//! | `output_latch` | the latch handler, an output latch | the sync rate | 5 % | 100 ms | 300 ms |
//! | `sync` | TIM2 CC2, a sync edge or the internal rate's compare | the sync rate | 5 % | 100 ms | 300 ms |
//!
//! The windows hold at least 40 events, so one event more or less (the count's quantisation)
//! and the main loop's millisecond of jitter stay well inside each tolerance; the holds keep a
//! single late window from raising a fault. A rate that goes off is named between hold - window
//! and hold + window after it did (the window it went off in counts from its start): 0.2-0.4 s
//! for the drive tick and the latches, 0.25-0.75 s for the turnarounds, 1-3 s for the
//! photodiode stream. That catches a stopped trigger, a dead input, a handler that no longer
//! runs.
//!
//! What the monitors cannot see: a clock wrong by a steady factor moves every count and the
//! millisecond clock alike (all come from SYSCLK). The power-up self-test checks the clock
//! tree's state, the clock security system reports a crystal that stops ([`TimingWatch::
//! clock_lost`]), and the bring-up measures the 500 Hz on PB3 against a counter.

/// The periodic events the board watches.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Event {
    /// A photodiode DMA half transfer (a Lissajous block of 256 pairs).
    Lissajous,
    /// A dither drive tick.
    DriveTick,
    /// A turnaround latch.
    Turnaround,
    /// An output latch.
    OutputLatch,
    /// A sync edge (or the internal output rate's compare).
    SyncEdge,
}

/// A monitor's limits.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RateSpec {
    /// Largest relative deviation from the expected rate.
    pub tolerance: f32,
    /// The counting window, ms.
    pub window_ms: u32,
    /// How long the rate must be off before the fault is raised, ms.
    pub hold_ms: u32,
}

impl Event {
    /// Every event, in the order of [`TimingWatch::update`]'s arrays.
    pub const ALL: [Self; 5] = [
        Self::Lissajous,
        Self::DriveTick,
        Self::Turnaround,
        Self::OutputLatch,
        Self::SyncEdge,
    ];

    /// The event's name (`status`, `selftest`).
    pub const fn word(self) -> &'static str {
        match self {
            Self::Lissajous => "lissajous",
            Self::DriveTick => "drive_tick",
            Self::Turnaround => "turnaround",
            Self::OutputLatch => "output_latch",
            Self::SyncEdge => "sync",
        }
    }

    /// The event's monitor limits (the module docs' table).
    pub const fn spec(self) -> RateSpec {
        let (tolerance, window_ms, hold_ms) = match self {
            Self::Lissajous => (0.10, 1000, 2000),
            Self::DriveTick => (0.02, 100, 300),
            Self::Turnaround => (0.05, 250, 500),
            Self::OutputLatch | Self::SyncEdge => (0.05, 100, 300),
        };
        RateSpec {
            tolerance,
            window_ms,
            hold_ms,
        }
    }
}

/// One event's monitor.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RateMonitor {
    /// The open window: its start (ms) and the count then.
    window: Option<(u64, u32)>,
    /// Since when the rate has been off, ms (the start of the first off window).
    off_since_ms: Option<u64>,
    /// The fault is raised.
    fault: bool,
    /// Faults raised so far (saturating).
    faults: u32,
    /// The rate of the last closed window, Hz.
    last_hz: f32,
}

impl RateMonitor {
    /// The running `count` of the event at `now_ms`; `expected_hz` `None`: not expected now
    /// (the state is cleared, the fault count kept).
    pub fn update(&mut self, spec: RateSpec, now_ms: u64, count: u32, expected_hz: Option<f32>) {
        let Some(expected) = expected_hz else {
            self.restart();
            self.fault = false;
            return;
        };
        let Some((start, at_start)) = self.window else {
            self.window = Some((now_ms, count));
            return;
        };
        let elapsed = now_ms.saturating_sub(start);
        if elapsed < u64::from(spec.window_ms) {
            return;
        }
        let n = count.wrapping_sub(at_start);
        self.last_hz = n as f32 * 1000.0 / elapsed as f32;
        if (self.last_hz - expected).abs() > spec.tolerance * expected {
            let since = *self.off_since_ms.get_or_insert(start);
            if now_ms - since >= u64::from(spec.hold_ms) && !self.fault {
                self.fault = true;
                self.faults = self.faults.saturating_add(1);
            }
        } else {
            self.off_since_ms = None;
            self.fault = false;
        }
        self.window = Some((now_ms, count));
    }

    /// Starts counting afresh at the next update (after a pause: the events stopped on
    /// purpose); a raised fault stays until a window within tolerance.
    pub fn restart(&mut self) {
        self.window = None;
        self.off_since_ms = None;
    }

    /// The fault is raised now.
    pub fn fault(&self) -> bool {
        self.fault
    }

    /// Faults raised so far.
    pub fn faults(&self) -> u32 {
        self.faults
    }

    /// The rate measured over the last closed window, Hz.
    pub fn last_hz(&self) -> f32 {
        self.last_hz
    }
}

/// The raised timing faults: one bit per [`Event`] (in [`Event::ALL`]'s order) and the lost
/// clock.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TimingFaults(pub u8);

impl TimingFaults {
    /// The clock security system switched SYSCLK to the internal oscillator: every rate and
    /// every timestamp is wrong.
    pub const CLOCK_LOST: Self = Self(1 << 5);

    /// The fault bit of `event`.
    pub const fn of(event: Event) -> Self {
        Self(1 << event as u8)
    }

    /// No fault.
    pub const fn is_empty(self) -> bool {
        self.0 == 0
    }

    /// Whether every bit of `other` is raised.
    pub const fn contains(self, other: Self) -> bool {
        self.0 & other.0 == other.0
    }

    /// The first raised fault's name: `clock_lost`, else the event's (`drive_tick`, ...).
    pub fn first_word(self) -> Option<&'static str> {
        if self.contains(Self::CLOCK_LOST) {
            return Some("clock_lost");
        }
        Event::ALL
            .into_iter()
            .find(|&e| self.contains(Self::of(e)))
            .map(Event::word)
    }
}

/// The rates the watch expects now, Hz, in [`Event::ALL`]'s order (`None`: not expected).
pub type ExpectedRates = [Option<f32>; 5];

/// The board's watch over its timing: a monitor per event, and the lost clock.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TimingWatch {
    monitors: [RateMonitor; 5],
    clock_lost: bool,
}

impl TimingWatch {
    /// Nothing watched yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// The events' running counts (wrapping) at `now_ms` and the rates expected now, both in
    /// [`Event::ALL`]'s order.
    pub fn update(&mut self, now_ms: u64, counts: [u32; 5], expected: ExpectedRates) {
        for (i, event) in Event::ALL.into_iter().enumerate() {
            let (Some(monitor), Some(&count), Some(&hz)) =
                (self.monitors.get_mut(i), counts.get(i), expected.get(i))
            else {
                continue;
            };
            monitor.update(event.spec(), now_ms, count, hz);
        }
    }

    /// Every monitor starts afresh (after a flash store: the events stopped on purpose).
    pub fn restart(&mut self) {
        for monitor in &mut self.monitors {
            monitor.restart();
        }
    }

    /// The clock security system reported the crystal lost: raised until a reset.
    pub fn clock_lost(&mut self) {
        self.clock_lost = true;
    }

    /// The faults raised now.
    pub fn faults(&self) -> TimingFaults {
        let events = Event::ALL
            .into_iter()
            .zip(&self.monitors)
            .filter(|(_, m)| m.fault())
            .fold(0u8, |bits, (e, _)| bits | TimingFaults::of(e).0);
        let clock = if self.clock_lost {
            TimingFaults::CLOCK_LOST.0
        } else {
            0
        };
        TimingFaults(events | clock)
    }

    /// `event`'s monitor.
    pub fn monitor(&self, event: Event) -> RateMonitor {
        self.monitors
            .get(event as usize)
            .copied()
            .unwrap_or_default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Feeds `watch` from `from_ms` to `to_ms` in steps of `step_ms` with events at `rates`
    /// (Hz, exact), returning the counts reached.
    fn feed(
        watch: &mut TimingWatch,
        counts: &mut [f64; 5],
        from_ms: u64,
        to_ms: u64,
        step_ms: u64,
        rates: [f64; 5],
        expected: ExpectedRates,
    ) {
        let mut t = from_ms;
        while t < to_ms {
            t += step_ms;
            for (c, r) in counts.iter_mut().zip(rates) {
                *c += r * step_ms as f64 / 1000.0;
            }
            watch.update(t, counts.map(|c| c as u64 as u32), expected);
        }
    }

    const NOMINAL: [f64; 5] = [48.23, 40_000.0, 778.0, 1000.0, 1000.0];
    const EXPECTED: ExpectedRates = [
        Some(48.23),
        Some(40_000.0),
        Some(778.0),
        Some(1000.0),
        Some(1000.0),
    ];

    /// At the nominal rates (and at the edges of their quantisation, a main loop passing every
    /// 1-3 ms) nothing is raised over a minute.
    #[test]
    fn nominal_rates_raise_nothing() {
        for step in [1, 2, 3] {
            let mut w = TimingWatch::new();
            let mut counts = [0.0; 5];
            feed(&mut w, &mut counts, 0, 60_000, step, NOMINAL, EXPECTED);
            assert!(w.faults().is_empty(), "step {step}: {:?}", w.faults());
            let m = w.monitor(Event::DriveTick);
            assert!((m.last_hz() - 40_000.0).abs() < 400.0, "{}", m.last_hz());
        }
    }

    /// Each event stopped in turn: its fault (and only its) is raised between hold - window and
    /// hold + window after; it clears once the event comes back (the count kept).
    #[test]
    fn a_stopped_event_is_named_within_hold_and_window() {
        for (i, event) in Event::ALL.into_iter().enumerate() {
            let spec = event.spec();
            let mut w = TimingWatch::new();
            let mut counts = [0.0; 5];
            feed(&mut w, &mut counts, 0, 5_000, 1, NOMINAL, EXPECTED);
            let mut rates = NOMINAL;
            rates[i] = 0.0;
            let mut t = 5_000;
            while w.faults().is_empty() {
                feed(&mut w, &mut counts, t, t + 1, 1, rates, EXPECTED);
                t += 1;
                assert!(t < 20_000, "{event:?} never raised");
            }
            let took = t - 5_000;
            assert_eq!(w.faults(), TimingFaults::of(event), "{event:?}");
            assert_eq!(w.faults().first_word(), Some(event.word()));
            assert!(
                took + u64::from(spec.window_ms) >= u64::from(spec.hold_ms)
                    && took <= u64::from(spec.hold_ms + spec.window_ms) + 1,
                "{event:?}: raised after {took} ms"
            );
            feed(&mut w, &mut counts, t, t + 3_000, 1, NOMINAL, EXPECTED);
            assert!(w.faults().is_empty(), "{event:?} not cleared");
            assert_eq!(w.monitor(event).faults(), 1);
        }
    }

    /// A rate off by more than its tolerance raises the fault, one just inside does not: at
    /// 1.5x and 0.8x the tolerance, both directions.
    #[test]
    fn the_tolerance_is_the_boundary() {
        for (i, event) in Event::ALL.into_iter().enumerate() {
            let tol = f64::from(event.spec().tolerance);
            for (factor, raised) in [(1.5, true), (0.8, false)] {
                for sign in [-1.0, 1.0] {
                    let mut w = TimingWatch::new();
                    let mut counts = [0.0; 5];
                    let mut rates = NOMINAL;
                    rates[i] *= 1.0 + sign * factor * tol;
                    feed(&mut w, &mut counts, 0, 30_000, 1, rates, EXPECTED);
                    assert_eq!(
                        w.faults().contains(TimingFaults::of(event)),
                        raised,
                        "{event:?} at {factor} x tolerance, sign {sign}"
                    );
                }
            }
        }
    }

    /// Not expected (the turnarounds while the drive is not locked): never raised, and the
    /// state is cleared; a restart (a store's pause) does not raise anything either.
    #[test]
    fn unexpected_events_and_pauses_raise_nothing() {
        let mut w = TimingWatch::new();
        let mut counts = [0.0; 5];
        let mut expected = EXPECTED;
        expected[2] = None;
        let mut rates = NOMINAL;
        rates[2] = 0.0;
        feed(&mut w, &mut counts, 0, 10_000, 1, rates, expected);
        assert!(w.faults().is_empty());
        // A 2.1 s store: nothing is counted and the loop does not run; then a restart.
        w.restart();
        let mut c2 = counts;
        feed(&mut w, &mut c2, 12_100, 20_000, 1, rates, expected);
        assert!(w.faults().is_empty(), "{:?}", w.faults());
        w.clock_lost();
        assert_eq!(w.faults().first_word(), Some("clock_lost"));
    }

    /// Counts wrap (the drive tick's after 30 hours): no false rate at the wrap.
    #[test]
    fn counts_wrap_without_a_false_rate() {
        let mut m = RateMonitor::default();
        let spec = Event::DriveTick.spec();
        let mut count = u32::MAX - 10_000;
        for t in 0..2_000u64 {
            m.update(spec, t, count, Some(40_000.0));
            count = count.wrapping_add(40);
        }
        assert!(!m.fault());
        assert_eq!(m.last_hz(), 40_000.0);
    }
}
