//! Stage 6c, the averaged rate: per-cycle compensated increments become the rate averaged over a window,
//! and the input-rate shift that the turnaround prediction (stage 2) needs.
//!
//! Each dither cycle yields a [`CycleOutput`]: the compensated phase increment in Q32 fringes
//! (`i64`, 2^32 per fringe), the cycle's duration in capture-timer ticks, and [`CycleFlags`].
//! The [`RateAverager`] turns them into a rate:
//!
//! - [`AveragingMode::FixedWindow`]: total phase over total time of a window of N cycles.
//! - [`AveragingMode::WholePeriods`] (docs/physics.md pitfall 6): near the dead-band edge the output
//!   advances in slips with a period of many seconds, and a fixed window cuts a slip in two. This
//!   mode times the crossings of whole-fringe boundaries by the accumulated phase (interpolated
//!   inside the cycle) and reports (fringes crossed) / (time between the first and last crossing
//!   in the window), an average over whole output periods. With fewer than two crossings in the
//!   window (a rate below one fringe per window) it falls back to the fixed-window estimate and
//!   sets [`RateReading::whole_periods`] false.
//!
//! The rate is reported in fringes/s and in deg/h (1 fringe/s = SF arcsec/s = SF deg/h). The
//! division runs once per window in f64 (software floating point on the M4F, IEEE-exact like
//! the host's, so both report the same bits).
//!
//! [`rate_shift_ticks`] turns one cycle's rate and measured dither into the turnaround shift
//! `Omega_i / |psi_ddot|` (docs/physics.md pitfall 3) for the next edges: the cycle task hands
//! it to [`crate::signal::turnaround::Scheduler::on_edge`] as a plain number, so the schedule imports
//! nothing from here.

use crate::signal::lockin::{CycleFlags, CycleOutput, CycleRecord};
use crate::signal::turnaround::shift_ticks_for_rate;
use crate::units::Q32_PER_FRINGE;

/// How the averager forms a rate.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum AveragingMode {
    /// Total phase over total time of the window.
    FixedWindow,
    /// Fringes crossed over the time between the first and last crossing (pitfall 6).
    WholePeriods,
}

/// Averager settings (immutable).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AveragerConfig {
    /// Cycles per reading (389 = one second at the paper's dither frequency).
    pub window_cycles: u32,
    /// How the rate is formed.
    pub mode: AveragingMode,
    /// Capture-timer frequency, Hz.
    pub timer_hz: f64,
    /// Scale factor, arcsec per fringe (pulse).
    pub scale_factor_arcsec: f64,
}

/// An averaged rate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RateReading {
    /// Rate in fringes (pulses) per second.
    pub rate_fringes_per_s: f64,
    /// Rate in deg/h (scale factor applied).
    pub rate_deg_per_h: f64,
    /// Seconds of data the rate spans.
    pub span_s: f64,
    /// True when the rate is an average over whole output periods.
    pub whole_periods: bool,
    /// Flags OR-ed over the window.
    pub flags: CycleFlags,
    /// Cycles in the window.
    pub cycles: u32,
}

/// Running state of the averager.
#[derive(Clone, Debug, Default)]
pub struct RateAverager {
    /// Accumulated phase since start, Q32 fringes; time since start, ticks.
    phase_q32: i64,
    time_ticks: u64,
    window_start_phase_q32: i64,
    window_start_ticks: u64,
    /// First and last whole-fringe crossing in the window: (fringe index, time in ticks as f64).
    first_crossing: Option<(i64, f64)>,
    last_crossing: Option<(i64, f64)>,
    cycles: u32,
    flags: CycleFlags,
}

impl RateAverager {
    /// An empty first window.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds one cycle; returns a reading when the window is complete.
    pub fn push(&mut self, config: &AveragerConfig, cycle: CycleOutput) -> Option<RateReading> {
        let start_phase = self.phase_q32;
        let start_ticks = self.time_ticks;
        self.phase_q32 = self.phase_q32.wrapping_add(cycle.increment.to_q32());
        self.time_ticks = self.time_ticks.wrapping_add(cycle.duration_ticks as u64);
        self.note_crossing(start_phase, start_ticks, cycle.duration_ticks);
        self.cycles = self.cycles.saturating_add(1);
        self.flags = self.flags.union(cycle.flags);
        if self.cycles < config.window_cycles.max(1) {
            return None;
        }
        let reading = self.reading(config);
        self.restart_window();
        Some(reading)
    }

    /// Records the last whole-fringe boundary crossed during a cycle, timed by linear
    /// interpolation of the phase inside the cycle.
    fn note_crossing(&mut self, start_phase: i64, start_ticks: u64, duration_ticks: u32) {
        let before = start_phase >> 32;
        let after = self.phase_q32 >> 32;
        if before == after {
            return;
        }
        // The boundary crossed last: the upper one going up, the lower one going down.
        let (index, boundary_q32) = if after > before {
            (after, after << 32)
        } else {
            (after + 1, (after + 1) << 32)
        };
        let rise = (self.phase_q32 - start_phase) as f64;
        let fraction = (boundary_q32 - start_phase) as f64 / rise;
        let time = start_ticks as f64 + fraction * duration_ticks as f64;
        if self.first_crossing.is_none() {
            // The first crossing's index counts as the boundary reached by then.
            self.first_crossing = Some((index, time));
        }
        self.last_crossing = Some((index, time));
    }

    /// The reading of the window so far (a partial window), restarting the window.
    pub fn flush(&mut self, config: &AveragerConfig) -> RateReading {
        let reading = self.reading(config);
        self.restart_window();
        reading
    }

    fn reading(&self, config: &AveragerConfig) -> RateReading {
        let ticks_per_s = config.timer_hz;
        let crossing_rate = match (config.mode, self.first_crossing, self.last_crossing) {
            (AveragingMode::WholePeriods, Some((i0, t0)), Some((i1, t1)))
                if i1 != i0 && t1 > t0 =>
            {
                Some((
                    (i1 - i0) as f64 / ((t1 - t0) / ticks_per_s),
                    (t1 - t0) / ticks_per_s,
                ))
            }
            _ => None,
        };
        let (rate_fringes_per_s, span_s, whole_periods) = match crossing_rate {
            Some((rate, span)) => (rate, span, true),
            None => {
                let span = (self.time_ticks - self.window_start_ticks) as f64 / ticks_per_s;
                let phase = (self.phase_q32 - self.window_start_phase_q32) as f64 / Q32_PER_FRINGE;
                let rate = if span > 0.0 { phase / span } else { 0.0 };
                (rate, span, false)
            }
        };
        RateReading {
            rate_fringes_per_s,
            rate_deg_per_h: rate_fringes_per_s * config.scale_factor_arcsec,
            span_s,
            whole_periods,
            flags: self.flags,
            cycles: self.cycles,
        }
    }

    fn restart_window(&mut self) {
        self.window_start_phase_q32 = self.phase_q32;
        self.window_start_ticks = self.time_ticks;
        self.first_crossing = None;
        self.last_crossing = None;
        self.cycles = 0;
        self.flags = CycleFlags::empty();
    }
}

/// The input-rate shift `Omega_i / |psi_ddot|` of the next turnarounds, in ticks of a timer at
/// `timer_hz`, from one cycle (docs/physics.md pitfall 3): Omega_i = the cycle's increment over its
/// duration, psi_ddot = measured amplitude x (2 pi f)^2. The increment is the compensated one
/// (the lock-in error removed: the best estimate of the input rate; with compensation off it is
/// the raw increment). 0 without a usable dither or duration.
pub fn rate_shift_ticks(record: &CycleRecord, timer_hz: u32) -> i32 {
    let duration_s = record.output.duration_ticks as f32 / timer_hz as f32;
    let fringes = record.output.increment.fringes_f64() as f32;
    let rate_rad_per_s = fringes * core::f32::consts::TAU / duration_s;
    shift_ticks_for_rate(
        rate_rad_per_s,
        record.dither_amplitude_rad,
        record.dither_hz,
        timer_hz,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::units::{PhaseDelta, TotalPhase};

    const Q32: f64 = Q32_PER_FRINGE;
    /// The board's capture-timer clock, Hz.
    const TIMER_HZ: u32 = 84_000_000;

    fn config(mode: AveragingMode, window_cycles: u32) -> AveragerConfig {
        AveragerConfig {
            window_cycles,
            mode,
            timer_hz: 84e6,
            scale_factor_arcsec: 1.8655,
        }
    }

    fn cycle(increment_fringes: f64, ticks: u32) -> CycleOutput {
        CycleOutput {
            increment: PhaseDelta::from_q32((increment_fringes * Q32).round() as i64),
            correction: PhaseDelta::ZERO,
            duration_ticks: ticks,
            flags: CycleFlags::empty(),
        }
    }

    /// A steady rate is reported exactly by both modes (to f64 rounding of the Q32 increments:
    /// 1e-9 relative).
    #[test]
    fn steady_rate_both_modes() {
        let ticks = 215_938; // 84 MHz / 389 Hz
        let per_cycle = 7.44 / 389.0; // 13.888 deg/h at SF 1.8655 ~ 7.44 fringes/s
        for mode in [AveragingMode::FixedWindow, AveragingMode::WholePeriods] {
            let cfg = config(mode, 389 * 4);
            let mut avg = RateAverager::new();
            let mut reading = None;
            for _ in 0..389 * 4 {
                reading = avg.push(&cfg, cycle(per_cycle, ticks)).or(reading);
            }
            let r = reading.expect("a reading after one window");
            let want = per_cycle * 84e6 / ticks as f64;
            assert!(
                (r.rate_fringes_per_s / want - 1.0).abs() < 1e-6,
                "{mode:?} {r:?}"
            );
            assert!((r.rate_deg_per_h - want * 1.8655).abs() < 1e-5);
            assert_eq!(r.whole_periods, mode == AveragingMode::WholePeriods);
        }
    }

    /// Slips: one whole fringe every 10 cycles, nothing in between. A fixed window of 25 cycles
    /// sees 2 or 3 slips depending on where it starts; whole-period averaging reports the true
    /// slip rate, 0.1 fringe per cycle, every time.
    #[test]
    fn whole_periods_remove_the_window_phase_error() {
        let ticks = 1000;
        let cfg_whole = config(AveragingMode::WholePeriods, 25);
        let cfg_fixed = config(AveragingMode::FixedWindow, 25);
        let (mut whole, mut fixed) = (RateAverager::new(), RateAverager::new());
        let (mut whole_rates, mut fixed_rates) = (vec![], vec![]);
        for i in 0..500 {
            let c = cycle(if i % 10 == 3 { 1.0 } else { 0.0 }, ticks);
            whole_rates.extend(whole.push(&cfg_whole, c));
            fixed_rates.extend(fixed.push(&cfg_fixed, c));
        }
        let true_rate = 0.1 * 84e6 / ticks as f64;
        for r in &whole_rates {
            assert!(r.whole_periods);
            assert!(
                (r.rate_fringes_per_s / true_rate - 1.0).abs() < 1e-9,
                "{r:?}"
            );
        }
        let worst_fixed = fixed_rates
            .iter()
            .map(|r| (r.rate_fringes_per_s / true_rate - 1.0).abs())
            .fold(0.0, f64::max);
        assert!(
            worst_fixed > 0.1,
            "the fixed window shows the slip beat: {worst_fixed}"
        );
    }

    #[test]
    fn flags_are_collected_over_the_window_and_cleared() {
        let cfg = config(AveragingMode::FixedWindow, 3);
        let mut avg = RateAverager::new();
        let mut glitchy = cycle(0.01, 1000);
        glitchy.flags = CycleFlags::COUNTER_GLITCH;
        assert!(avg.push(&cfg, cycle(0.01, 1000)).is_none());
        assert!(avg.push(&cfg, glitchy).is_none());
        let r = avg.push(&cfg, cycle(0.01, 1000)).unwrap();
        assert!(r.flags.contains(CycleFlags::COUNTER_GLITCH));
        for _ in 0..2 {
            assert!(avg.push(&cfg, cycle(0.01, 1000)).is_none());
        }
        assert!(avg.push(&cfg, cycle(0.01, 1000)).unwrap().flags.is_empty());
    }

    /// Negative rates cross boundaries downwards; the estimate keeps its sign.
    #[test]
    fn negative_rates() {
        let cfg = config(AveragingMode::WholePeriods, 200);
        let mut avg = RateAverager::new();
        let mut last = None;
        for _ in 0..200 {
            last = avg.push(&cfg, cycle(-0.37, 1000)).or(last);
        }
        let r = last.unwrap();
        assert!(r.whole_periods);
        assert!(
            (r.rate_fringes_per_s / (-0.37 * 84e3) - 1.0).abs() < 1e-6,
            "{r:?}"
        );
    }

    /// A record of one 389 Hz cycle advancing `fringes`, at the docs/physics.md dither amplitude.
    fn record(fringes: f64, dither_hz: f32, amplitude_rad: f32) -> CycleRecord {
        let duration_ticks = (TIMER_HZ as f64 / 389.0).round() as u32;
        CycleRecord {
            output: CycleOutput {
                increment: PhaseDelta::from_q32((fringes * Q32_PER_FRINGE).round() as i64),
                duration_ticks,
                ..Default::default()
            },
            raw_increment: PhaseDelta::ZERO,
            terms: Default::default(),
            end_phase: TotalPhase::from_q32(0),
            dither_amplitude_rad: amplitude_rad,
            dither_hz,
        }
    }

    #[test]
    fn rate_shift_of_one_degree_per_second() {
        // 1 deg/s = 3600 arcsec/s at SF 1.8655 arcsec/pulse; 450 arcsec amplitude, 389 Hz:
        // Omega_i / (A w^2) = 1.34 us = 112 ticks, with the sign of the rate.
        let sf = 1.8655;
        let amplitude = (450.0 / sf * core::f64::consts::TAU) as f32;
        let per_cycle = 3600.0 / sf / 389.0;
        let plus = rate_shift_ticks(&record(per_cycle, 389.0, amplitude), TIMER_HZ);
        let minus = rate_shift_ticks(&record(-per_cycle, 389.0, amplitude), TIMER_HZ);
        assert!((110..=115).contains(&plus), "{plus} ticks");
        assert_eq!(minus, -plus);
        // Earth rate: a few ns.
        let earth = rate_shift_ticks(&record(15.0 / sf / 389.0, 389.0, amplitude), TIMER_HZ);
        assert_eq!(earth, 0);
    }

    #[test]
    fn no_usable_dither_or_duration_gives_no_shift() {
        let r = record(5.0, 389.0, 0.0);
        assert_eq!(rate_shift_ticks(&r, TIMER_HZ), 0);
        let r = record(5.0, 0.0, 1515.6);
        assert_eq!(rate_shift_ticks(&r, TIMER_HZ), 0);
        let mut r = record(5.0, 389.0, 1515.6);
        r.output.duration_ticks = 0;
        assert_eq!(rate_shift_ticks(&r, TIMER_HZ), 0);
    }

    #[test]
    fn a_huge_rate_is_clamped_to_a_sixteenth_period() {
        let r = record(1e5, 389.0, 1515.6);
        let limit = (TIMER_HZ as f32 / 389.0 / 16.0) as i32;
        assert_eq!(rate_shift_ticks(&r, TIMER_HZ), limit);
    }
}
