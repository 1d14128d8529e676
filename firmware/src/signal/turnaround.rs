//! Stage 2, the turnaround: pick-off comparator edges (capture-timer ticks) in, the instant to
//! latch the fringe count and sample both photodiodes out. What the latch takes is a
//! [`crate::sample::TurnaroundSample`] (the hardware/logic boundary), which the readout hands
//! to stages 1, 3 and 4.
//!
//! Plain logic, shared by the board (`board::turnaround`: TIM2 captures the edges, the compare
//! fires the latch; registers, fixed delays and the atomic counters stay there) and the
//! simulated board (`hal-sim`, which generates the edges from the simulated dither pick-off).
//!
//! # The chain (on the board)
//! ```text
//! pick-off comparator --capture--> Edge + t_edge (ticks)
//!     Scheduler::on_edge: t_compare = t_edge + half the previous same-polarity interval
//!                         -/+ input-rate shift - pick-off lag
//!                         - fixed delays (comparator path, ADC aperture)
//! compare match at t_compare -> encoder latch + ADC injected pair; the sampling instant (the
//! end of the aperture) lands on the turnaround
//! cycle task: CycleRecord -> rate_shift_ticks -> the shift for the next edges
//! output stage: the stripping's quadrature tap -> the pick-off's lag -> the next edges
//! ```
//!
//! # Prediction (docs/physics.md pitfalls 2 and 3)
//! A turnaround lies a quarter period after a zero crossing of the dither angle. A comparator
//! threshold offset makes rising crossings late and falling ones early by the same amount (or
//! the reverse), so "crossing + T/4" would be off by that amount with alternating sign. Half the
//! previous interval of the same polarity cancels it exactly: after a rising edge at t_r,
//! `t_r + high/2` (high = previous rising-to-falling interval) is the midpoint of that pulse, i.e.
//! the angle maximum, whatever the threshold. Only a slowly varying dither is assumed (a high-Q
//! resonator: period and amplitude change little in one cycle).
//!
//! The input rate moves the turnaround (pitfall 3): the lock-in-free rate Omega_i + psi_ddot (t -
//! t_p) is zero at `t_p - Omega_i/psi_ddot` for a "+" turnaround and `t_p + Omega_i/|psi_ddot|`
//! for a "-" one. The cycle task computes `Omega_i/|psi_ddot|` in timer ticks from each cycle's
//! rate and measured dither ([`rate_shift_ticks`](crate::signal::output::rate_shift_ticks), in
//! stage 6) and hands it to the next edges; at 1 deg/s of input it is 1.3 us, at Earth rate
//! 6 ns. The feedback arrives as a plain `i32`, so this stage imports nothing of the later ones.
//!
//! The pick-off's own lag behind the dither (the gauge and its preamplifier, up to a few
//! microseconds, different on every gyro) delays every comparator edge by as much. It is not a
//! constant of the board: the output stage measures it against the optical angle (the
//! stripping's quadrature tap, `crate::readout::Readout::pickoff_lag_ticks`) and hands it to
//! the next edges as a plain `i32`, like the rate shift. A 5 us lag left in would put the latch
//! 5 us off the turnaround, 0.1 rad of beat phase (pitfall 2).
//!
//! Fixed delays subtracted ([`SchedulerConfig`], calibrated on a board with a scope on the
//! compare's test point): the pick-off path (comparator, input filter, resynchronisation) and the
//! ADC aperture (trigger latency plus sampling time; the hold happens at the end of sampling, so
//! the compare fires that much early and the *sampling* instant lands on the turnaround). The
//! encoder latch then comes ~0.85 us before the turnaround: at psi_ddot ~ 9e9 rad/s^2 the beat
//! phase differs by 9e9 x (0.85e-6)^2 / 2 = 3e-3 rad between the two instants, far inside the
//! quarter fringe the count-plus-fraction resolver tolerates.
//!
//! # Expected timing error (to be measured on the board)
//! | source | size |
//! |---|---|
//! | timer resolution (84 MHz) | +-6 ns |
//! | input filter + resynchronisation, pick-off edge | 95 ns fixed, +-12 ns jitter |
//! | injected trigger latency (2-3 ADC clocks at 21 MHz) | 119 ns mean, +-24 ns jitter |
//! | comparator noise at the zero crossing (sigma_v / slope) | ~10-50 ns (pick-off noise) |
//! | dither period change within one cycle (high-Q resonator) | < 10 ns |
//! | pick-off phase lag vs the true angle | measured online (the stripping), +-10 ns |
//! | comparator delay | fixed: calibrate once |
//! | rate shift taken from the previous cycle | (rate change per cycle) / psi_ddot: 0 for a steady rate |
//!
//! So about +-0.1 us random error once the fixed terms are calibrated, against the ~1 us
//! docs/physics.md asks for; an uncalibrated fixed term of 0.5 us costs psi_ddot dt^2/2 ~ 1e-3 rad.
//!
//! # Cost
//! `on_edge` is integer-only, no division (about 55 instructions on the M4 with the board's
//! register code, `examples/board_cost.rs`); `output::rate_shift_ticks` runs once per cycle in the
//! cycle task (single-precision floating point, one f64 conversion).

use crate::sample::TurnaroundKind;

/// A pick-off comparator edge.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Edge {
    /// The dither angle increasing through the threshold.
    Rising,
    /// The dither angle decreasing through the threshold.
    Falling,
}

/// Where and which turnaround to fire.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Schedule {
    /// Capture-timer value at which to fire the compare (wrapping ticks).
    pub compare_ticks: u32,
    /// Which turnaround the compare latches.
    pub kind: TurnaroundKind,
}

/// What one edge gives.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct EdgeOutcome {
    /// The turnaround to fire, once the same-polarity history exists.
    pub schedule: Option<Schedule>,
    /// The interval since the previous edge was outside the plausible half-period range (a
    /// glitch or a gap): the history was dropped. The board counts these.
    pub implausible: bool,
}

/// Settings of the prediction (immutable; what would live in flash).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SchedulerConfig {
    /// Lower end of the plausible interval between consecutive edges, ticks (inclusive).
    pub min_half_ticks: u32,
    /// Upper end of the plausible interval, ticks (inclusive).
    pub max_half_ticks: u32,
    /// Edge to capture: comparator, input filter, resynchronisation, ticks.
    pub pickoff_delay_ticks: u32,
    /// Compare match to the end of the ADC sampling window, ticks (the sampling instant is
    /// `compare_ticks + aperture_delay_ticks`).
    pub aperture_delay_ticks: u32,
    /// Which turnaround follows a rising pick-off edge (angle increasing through zero: the next
    /// extremum is a maximum, the rate goes from + to -, a "-" turnaround). A pick-off wired with
    /// the other polarity flips it: docs/physics.md pitfall 4.
    pub after_rising_edge: TurnaroundKind,
}

impl SchedulerConfig {
    /// For a dither between `min_hz` and `max_hz` on a timer at `timer_hz`, with the given fixed
    /// delays (ticks).
    pub const fn for_dither_range(
        timer_hz: u32,
        min_hz: u32,
        max_hz: u32,
        pickoff_delay_ticks: u32,
        aperture_delay_ticks: u32,
        after_rising_edge: TurnaroundKind,
    ) -> Self {
        Self {
            // Half periods, with room for a pick-off duty cycle of 30/70.
            min_half_ticks: timer_hz / max_hz * 3 / 10,
            max_half_ticks: timer_hz / min_hz * 7 / 10,
            pickoff_delay_ticks,
            aperture_delay_ticks,
            after_rising_edge,
        }
    }

    /// Total fixed delay subtracted from each prediction, ticks.
    pub const fn fixed_delay_ticks(&self) -> u32 {
        self.pickoff_delay_ticks + self.aperture_delay_ticks
    }
}

/// The prediction's state: the last edge and the last interval of each polarity.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Scheduler {
    last: Option<(Edge, u32)>,
    /// Previous rising-to-falling and falling-to-rising intervals, ticks.
    high_ticks: Option<u32>,
    low_ticks: Option<u32>,
}

impl Scheduler {
    /// No edge seen yet.
    pub const fn new() -> Self {
        Self {
            last: None,
            high_ticks: None,
            low_ticks: None,
        }
    }

    /// Forgets the edge history (after a pause: the next full cycle rebuilds it).
    pub fn reset(&mut self) {
        *self = Self::new();
    }

    /// One edge captured at `t_ticks` (wrapping); `rate_shift_ticks` = Omega_i/|psi_ddot| in
    /// ticks (signed, [`rate_shift_ticks`](crate::signal::output::rate_shift_ticks));
    /// `pickoff_lag_ticks` = how far the pick-off lags the dither (signed,
    /// `Readout::pickoff_lag_ticks`, 0 until measured). Integer only, no division.
    pub fn on_edge(
        &mut self,
        config: &SchedulerConfig,
        edge: Edge,
        t_ticks: u32,
        rate_shift_ticks: i32,
        pickoff_lag_ticks: i32,
    ) -> EdgeOutcome {
        let mut implausible = false;
        if let Some((previous, t0)) = self.last {
            let interval = t_ticks.wrapping_sub(t0);
            let plausible = (config.min_half_ticks..=config.max_half_ticks).contains(&interval);
            match (previous, edge) {
                _ if !plausible => {
                    // A glitch or a gap: neither this edge nor the history can be trusted.
                    implausible = true;
                    (self.high_ticks, self.low_ticks) = (None, None);
                }
                (Edge::Rising, Edge::Falling) => self.high_ticks = Some(interval),
                (Edge::Falling, Edge::Rising) => self.low_ticks = Some(interval),
                // Two edges of one polarity: a lost edge; start over.
                _ => (self.high_ticks, self.low_ticks) = (None, None),
            }
        }
        self.last = Some((edge, t_ticks));
        EdgeOutcome {
            schedule: self.predict(config, edge, t_ticks, rate_shift_ticks, pickoff_lag_ticks),
            implausible,
        }
    }

    fn predict(
        &self,
        config: &SchedulerConfig,
        edge: Edge,
        t_ticks: u32,
        rate_shift_ticks: i32,
        pickoff_lag_ticks: i32,
    ) -> Option<Schedule> {
        let (half_same_polarity, kind) = match edge {
            Edge::Rising => (self.high_ticks?, config.after_rising_edge),
            Edge::Falling => (self.low_ticks?, opposite(config.after_rising_edge)),
        };
        let shift = match kind {
            TurnaroundKind::Plus => -rate_shift_ticks,
            TurnaroundKind::Minus => rate_shift_ticks,
        };
        let quarter = (half_same_polarity / 2) as i32;
        let lead = quarter + shift
            - pickoff_lag_ticks.clamp(-quarter / 2, quarter / 2)
            - config.fixed_delay_ticks() as i32;
        Some(Schedule {
            compare_ticks: t_ticks.wrapping_add_signed(lead),
            kind,
        })
    }
}

/// The other kind of turnaround.
pub fn opposite(kind: TurnaroundKind) -> TurnaroundKind {
    match kind {
        TurnaroundKind::Plus => TurnaroundKind::Minus,
        TurnaroundKind::Minus => TurnaroundKind::Plus,
    }
}

/// `Omega_i / |psi_ddot|` in ticks for a rate (rad/s of beat phase) and a sine dither of
/// `amplitude_rad` (beat phase) at `dither_hz`: `psi_ddot = amplitude * (2 pi f)^2`. Clamped to
/// +-T/16: beyond that the parabolic turnaround model no longer holds anyway. 0 for a
/// non-finite rate or no dither.
pub fn shift_ticks_for_rate(
    rate_rad_per_s: f32,
    amplitude_rad: f32,
    dither_hz: f32,
    timer_hz: u32,
) -> i32 {
    let w = core::f32::consts::TAU * dither_hz;
    let psi_ddot = amplitude_rad * w * w;
    if !(psi_ddot.is_finite() && psi_ddot > 0.0 && rate_rad_per_s.is_finite() && dither_hz > 0.0) {
        return 0;
    }
    let limit = timer_hz as f32 / dither_hz / 16.0;
    let ticks = rate_rad_per_s / psi_ddot * timer_hz as f32;
    ticks.clamp(-limit, limit) as i32
}

#[cfg(test)]
mod tests {
    use super::*;

    const TIMER_HZ: u32 = 84_000_000;
    /// One dither period at 389 Hz, ticks (rounded to even, so T/4 is exact).
    const PERIOD: u32 = 215_936;
    /// Comparator threshold offset as a time shift of the edges, ticks (8.3 us).
    const OFFSET: u32 = 700;
    const CONFIG: SchedulerConfig =
        SchedulerConfig::for_dither_range(TIMER_HZ, 200, 1500, 18, 70, TurnaroundKind::Minus);

    /// Worst compare error against the true turnaround (ticks), compares seen, next start.
    struct Run {
        worst: i64,
        compares: u32,
        implausible: u32,
        next_t: u32,
    }

    /// Feeds `cycles` dither cycles starting at `t0` (a true rising zero crossing), edges moved
    /// by the threshold offset (rising late, falling early) and the pick-off delay; compares
    /// against the true extremum minus the aperture, shifted by the rate with the kind's sign.
    fn run(s: &mut Scheduler, t0: u32, cycles: u32, drift_per_cycle: i32, shift: i32) -> Run {
        let mut r = Run {
            worst: 0,
            compares: 0,
            implausible: 0,
            next_t: t0,
        };
        let mut period = PERIOD as i32;
        for _ in 0..cycles {
            let t = r.next_t;
            let half = (period / 2) as u32;
            let rise = t.wrapping_add(OFFSET + CONFIG.pickoff_delay_ticks);
            let fall = t.wrapping_add(half - OFFSET + CONFIG.pickoff_delay_ticks);
            for (edge, at, extremum) in [
                (Edge::Rising, rise, t.wrapping_add(half / 2)),
                (Edge::Falling, fall, t.wrapping_add(half + half / 2)),
            ] {
                let outcome = s.on_edge(&CONFIG, edge, at, shift, 0);
                r.implausible += outcome.implausible as u32;
                let Some(c) = outcome.schedule else { continue };
                let expect_kind = match edge {
                    Edge::Rising => CONFIG.after_rising_edge,
                    Edge::Falling => opposite(CONFIG.after_rising_edge),
                };
                assert_eq!(c.kind, expect_kind);
                let sign = if c.kind == TurnaroundKind::Plus {
                    -1
                } else {
                    1
                };
                let want = extremum
                    .wrapping_sub(CONFIG.aperture_delay_ticks)
                    .wrapping_add_signed(sign * shift);
                let err = c.compare_ticks.wrapping_sub(want) as i32 as i64;
                if err.abs() > r.worst.abs() {
                    r.worst = err;
                }
                r.compares += 1;
            }
            r.next_t = t.wrapping_add(period as u32);
            period += drift_per_cycle;
        }
        r
    }

    #[test]
    fn threshold_offset_and_pickoff_delay_cancel() {
        let mut s = Scheduler::new();
        let r = run(&mut s, 1_000, 8, 0, 0);
        assert!(r.worst.abs() <= 1, "worst {} ticks", r.worst);
        // The first rising and the first falling edge have no history: 16 - 2.
        assert_eq!(r.compares, 14);
        assert_eq!(r.implausible, 0);
    }

    #[test]
    fn the_32_bit_wrap_is_harmless() {
        let mut s = Scheduler::new();
        let r = run(&mut s, u32::MAX - 3 * PERIOD, 8, 0, 0);
        assert!(r.worst.abs() <= 1, "worst {} ticks", r.worst);
        assert_eq!(r.compares, 14);
    }

    #[test]
    fn rate_shift_moves_plus_earlier_and_minus_later() {
        let shift = 500;
        let mut s = Scheduler::new();
        let r = run(&mut s, 1_000, 8, 0, shift);
        assert!(r.worst.abs() <= 1, "worst {} ticks", r.worst);
        // Directly: the same edges with and without the shift.
        let (mut a, mut b) = (Scheduler::new(), Scheduler::new());
        for (edge, t) in [(Edge::Rising, 0), (Edge::Falling, PERIOD / 2)] {
            a.on_edge(&CONFIG, edge, t, 0, 0);
            b.on_edge(&CONFIG, edge, t, shift, 0);
        }
        for (edge, t) in [(Edge::Rising, PERIOD), (Edge::Falling, PERIOD * 3 / 2)] {
            let plain = a.on_edge(&CONFIG, edge, t, 0, 0).schedule.unwrap();
            let shifted = b.on_edge(&CONFIG, edge, t, shift, 0).schedule.unwrap();
            let moved = shifted.compare_ticks.wrapping_sub(plain.compare_ticks) as i32;
            match shifted.kind {
                TurnaroundKind::Plus => assert_eq!(moved, -shift),
                TurnaroundKind::Minus => assert_eq!(moved, shift),
            }
        }
    }

    /// A pick-off lag moves both kinds of turnaround earlier by as much; a lag beyond an
    /// eighth of the period (a wiring fault, not a lag) is clamped there.
    #[test]
    fn a_pickoff_lag_moves_every_latch_earlier() {
        let lag = 420; // 5 us
        let (mut a, mut b, mut c) = (Scheduler::new(), Scheduler::new(), Scheduler::new());
        for (edge, t) in [(Edge::Rising, 0), (Edge::Falling, PERIOD / 2)] {
            a.on_edge(&CONFIG, edge, t, 0, 0);
            b.on_edge(&CONFIG, edge, t, 0, lag);
            c.on_edge(&CONFIG, edge, t, 0, i32::MAX);
        }
        for (edge, t) in [(Edge::Rising, PERIOD), (Edge::Falling, PERIOD * 3 / 2)] {
            let plain = a.on_edge(&CONFIG, edge, t, 0, 0).schedule.unwrap();
            let lagged = b.on_edge(&CONFIG, edge, t, 0, lag).schedule.unwrap();
            let clamped = c.on_edge(&CONFIG, edge, t, 0, i32::MAX).schedule.unwrap();
            assert_eq!(plain.compare_ticks.wrapping_sub(lagged.compare_ticks), 420);
            let moved = plain.compare_ticks.wrapping_sub(clamped.compare_ticks);
            assert_eq!(moved, PERIOD / 8, "{:?}", clamped.kind);
        }
    }

    #[test]
    fn a_slow_period_drift_costs_a_few_ticks() {
        // 20 ticks (93 ppm) per cycle.
        let mut s = Scheduler::new();
        let r = run(&mut s, 1_000, 8, 20, 0);
        assert!(r.worst.abs() <= 20, "worst {} ticks", r.worst);
    }

    #[test]
    fn a_lost_edge_gives_no_compare_until_the_history_is_rebuilt() {
        let mut s = Scheduler::new();
        let t = run(&mut s, 1_000, 3, 0, 0).next_t;
        assert!(s
            .on_edge(&CONFIG, Edge::Rising, t + OFFSET, 0, 0)
            .schedule
            .is_some());
        // The falling edge is lost: the next rising edge comes a full period later, which is
        // a plausible interval (< 0.7 x 1/200 Hz) but of the wrong polarity pattern.
        let o = s.on_edge(&CONFIG, Edge::Rising, t + PERIOD + OFFSET, 0, 0);
        assert_eq!(o, EdgeOutcome::default());
        let r = run(&mut s, t + PERIOD + PERIOD / 2, 3, 0, 0);
        assert!(
            r.compares >= 3 && r.worst.abs() <= 1,
            "{} {}",
            r.compares,
            r.worst
        );
    }

    #[test]
    fn a_glitch_is_implausible_and_drops_the_history() {
        let mut s = Scheduler::new();
        let t = run(&mut s, 1_000, 3, 0, 0).next_t;
        s.on_edge(&CONFIG, Edge::Rising, t + OFFSET, 0, 0);
        let g = s.on_edge(&CONFIG, Edge::Falling, t + OFFSET + 10, 0, 0);
        assert!(g.implausible);
        assert!(g.schedule.is_none());
        // A gap (no dither for a second) is implausible too.
        let gap = s.on_edge(&CONFIG, Edge::Rising, t + TIMER_HZ, 0, 0);
        assert!(gap.implausible && gap.schedule.is_none());
        // One full cycle later the prediction is back.
        let r = run(&mut s, t + TIMER_HZ + PERIOD - OFFSET, 3, 0, 0);
        assert_eq!(r.implausible, 0);
        assert!(
            r.compares >= 3 && r.worst.abs() <= 1,
            "{} {}",
            r.compares,
            r.worst
        );
    }

    #[test]
    fn reset_forgets_the_history() {
        let mut s = Scheduler::new();
        run(&mut s, 1_000, 2, 0, 0);
        s.reset();
        assert_eq!(s, Scheduler::new());
    }
}
