//! The simulated board: the gyro and the peripherals assembled into what the firmware's two
//! interrupts receive.
//!
//! Per half dither cycle, [`SimBoard::next_half_cycle`] returns
//! - the photodiode conversions taken since the previous turnaround by the free-running ADC
//!   (regular conversions at [`BoardConfig::lissajous_rate_hz`], not synchronised with the
//!   dither, as on the board: the samples land at all phases of the fringe, even inside the dead
//!   band where the phase at any fixed point of the dither cycle repeats), and
//! - the [`TurnaroundSample`] latched at the turnaround (encoder register, both ADC channels,
//!   capture timer), built by [`latch_turnaround`].
//!
//! The latch instant ([`LatchTiming`], docs/physics.md pitfall 2: aim for ~1 us) is either
//! - [`LatchTiming::Exact`] (the default): the exact turnaround (the zero of dither plus input
//!   rate), standing in for a perfect capture/compare scheduling; or
//! - [`LatchTiming::Scheduled`]: what the board does. The pick-off comparator's edges are found
//!   on the pick-off's noise-free voltage ([`Pickoff`], which follows the dither angle of
//!   either model, [`Gyro::dither_pickoff_arcsec`], with its gain error, lag and non-linearity)
//!   against the comparator threshold: bracketing in steps of T/32, then bisection to 10 ps;
//!   delayed by the pick-off
//!   path and captured by the profile's 84 MHz timer ([`CaptureTimer`], whole ticks), and fed to the
//!   firmware's own [`Scheduler`] (`firmware::signal::turnaround`) with the input-rate
//!   shift that [`rate_shift_ticks`] computes from the latest [`CycleRecord`] the caller hands
//!   back ([`SimBoard::on_cycle`]). The latch is taken at the sampling instant: the compare
//!   instant plus the ADC aperture delay the scheduler subtracted, so a model whose delays match
//!   the scheduler's lands on the turnaround up to the capture's tick quantisation (the capture
//!   and the half-interval round down: about -11 ns on average, within +-35 ns at +-1 deg/s with
//!   a 5 % threshold offset and 1 % amplitude jitter, `tests/board_schedule.rs`). (On the board
//!   the encoder count is latched at the compare, ~0.85 us earlier; the count-plus-fraction
//!   resolver absorbs that, so one instant is used for both here.) A turnaround without a usable
//!   schedule (no history yet after start, an implausible edge, no edge at all, a compare that
//!   does not point at this turnaround) falls back to the exact turnaround and is counted in
//!   [`LatchStats`]: the simulation never hangs.
//!
//! In both modes [`BoardConfig::latch_offset_s`] and [`BoardConfig::latch_jitter_rms_s`] add a
//! residual timing error on top (an uncalibrated fixed delay, trigger jitter). The gyro's truth
//! (turnaround phase, per-traversal lock-in error) stays available through [`SimBoard::gyro`]
//! for tests, and each latch's true turnaround through [`SimBoard::last_latch`].
//!
//! The pick-off is also an ADC channel ([`SimBoard::pickoff_code`]: one conversion at any
//! instant, the firmware's drive loop samples it at every drive tick), and the board passes
//! drive segments on to a driven dither ([`SimBoard::push_drive`], [`DriveSink`]). A scheduled
//! latch searches the pick-off up to one dither period ahead and the exact latch needs the next
//! turnaround: keep the drive known [`Gyro::drive_lead_s`] ahead of [`SimBoard::time_s`]
//! before each [`SimBoard::next_half_cycle`] (the harness does, [`crate::harness`]).
//!
//! Size (over 600 lines): the step that puts every peripheral's events in time order works on the
//! whole board's state; the peripherals live in files of their own.

mod config;
mod faults;
mod pickoff_stream;

use crate::clock::CaptureTimer;
use crate::counter::{latch_turnaround, QuadratureCounter};
use crate::dither::drive::{DriveError, DriveSegment, DriveSink};
use crate::gyro::Gyro;
use crate::gyro::TurnaroundTime;
use crate::param_error::ParamError;
use crate::photodiode::Photodiodes;
use crate::pickoff::Pickoff;
pub use config::{BoardConfig, LatchTiming};
pub use faults::{BoardFault, BoardFaults, Trigger};
use firmware::sample::{AdcCode, OutputSample, TurnaroundKind, TurnaroundSample};
use firmware::signal::lockin::CycleRecord;
use firmware::signal::output::dither_model::PickoffSample;
use firmware::signal::output::rate_shift_ticks;
use firmware::signal::turnaround::{Edge, Scheduler, SchedulerConfig};
use pickoff_stream::PickoffStream;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

/// Why a board cannot be built.
#[derive(Debug)]
pub enum BoardError {
    /// The counter cannot follow the comparators.
    Counter(crate::counter::CounterError),
    /// The photodiode configuration is invalid.
    Photodiodes(crate::photodiode::PhotodiodeConfigError),
    /// The pick-off configuration is invalid.
    Pickoff(ParamError),
    /// Another setting is invalid; the text says which.
    Config(&'static str),
}

/// How the turnarounds were latched so far ([`LatchTiming::Scheduled`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LatchStats {
    /// Pick-off edges found and fed to the scheduler.
    pub edges: u64,
    /// Edges the scheduler found implausible (glitch or gap).
    pub implausible_edges: u64,
    /// Latches at the scheduled instant.
    pub scheduled: u64,
    /// Latches that fell back to the exact turnaround (no schedule, or one not pointing at it).
    pub fallbacks: u64,
}

/// One latch and its truth.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LatchRecord {
    /// When the photodiodes were sampled and the count latched, s.
    pub latch_s: f64,
    /// The true turnaround it was meant for (zero of dither + input rate).
    pub turnaround: TurnaroundTime,
    /// True if taken at the scheduled instant (false: exact, or a fallback).
    pub scheduled: bool,
}

/// The pick-off side of a scheduled latch.
#[derive(Clone, Copy, Debug)]
struct EdgeSchedule {
    threshold_v: f64,
    pickoff_delay_s: f64,
    aperture_delay_s: f64,
    rate_shift: bool,
    config: SchedulerConfig,
    scheduler: Scheduler,
    /// Where the next edge search starts: just after the last edge, s.
    cursor_s: f64,
}

/// The simulated board.
pub struct SimBoard {
    gyro: Gyro,
    config: BoardConfig,
    photodiodes: Photodiodes,
    pickoff: Pickoff,
    counter: QuadratureCounter,
    timer: CaptureTimer,
    rng: ChaCha8Rng,
    next_lissajous_s: f64,
    time_s: f64,
    schedule: Option<EdgeSchedule>,
    rate_shift_ticks: i32,
    stats: LatchStats,
    last_latch: Option<LatchRecord>,
    /// The next sync edge, s, and the output latches taken since the last drain.
    next_sync_s: f64,
    outputs: Vec<OutputLatch>,
    /// Injected faults.
    faults: BoardFaults,
    /// Photodiode pairs converted and sync edges seen since t = 0 (the rate monitors' counts).
    lissajous_pairs: u64,
    sync_edges: u64,
    /// The pick-off's conversion at every drive tick.
    stream: PickoffStream,
    /// The pick-off's lag as the readout measures it, ticks (the schedule subtracts it).
    pickoff_lag_ticks: i32,
}

/// One output latch (a sync edge) and its truth.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OutputLatch {
    /// What the latch took (the harness sets `drive_locked` from its drive).
    pub sample: OutputSample,
    /// When, s.
    pub t_s: f64,
    /// The true input angle since t = 0 at the latch, arcsec.
    pub true_angle_arcsec: f64,
}

impl SimBoard {
    /// The board around `gyro`, at t = 0.
    pub fn new(mut gyro: Gyro, config: BoardConfig) -> Result<Self, BoardError> {
        config
            .photodiodes
            .validate()
            .map_err(BoardError::Photodiodes)?;
        if !(config.timer_hz > 0.0 && config.lissajous_rate_hz > 0.0) {
            return Err(BoardError::Config(
                "timer and Lissajous rates must be positive",
            ));
        }
        if !(config.latch_offset_s.is_finite() && config.latch_jitter_rms_s >= 0.0) {
            return Err(BoardError::Config("latch timing must be finite"));
        }
        config.pickoff.validate().map_err(BoardError::Pickoff)?;
        if let Some(hz) = config.sync_hz {
            if !(hz.is_finite() && (1.0..=100_000.0).contains(&hz)) {
                return Err(BoardError::Config("sync rate must be in 1..=100000 Hz"));
            }
        }
        let schedule = Self::schedule(&config)?;
        let profile = config.profile();
        let stream = PickoffStream::new(
            f64::from(profile.drive_tick_hz),
            f64::from(profile.aperture_delay_ticks) / config.timer_hz,
        );
        let psi_h0 = gyro.advance_to(0.0) - gyro.eps_rad(0.0);
        let counter = QuadratureCounter::new(&config.photodiodes, config.counter, psi_h0)
            .map_err(BoardError::Counter)?;
        Ok(Self {
            photodiodes: Photodiodes::new(config.photodiodes, config.seed),
            pickoff: Pickoff::new(config.pickoff, config.seed ^ 0x5049_434b_4f46_4621),
            rng: ChaCha8Rng::seed_from_u64(config.seed.wrapping_add(1)),
            timer: CaptureTimer::new(config.timer_hz),
            next_lissajous_s: 0.5 / config.lissajous_rate_hz,
            time_s: 0.0,
            schedule,
            rate_shift_ticks: 0,
            stats: LatchStats::default(),
            last_latch: None,
            next_sync_s: config.sync_hz.map_or(f64::INFINITY, |hz| 1.0 / hz),
            outputs: Vec::new(),
            faults: BoardFaults::default(),
            lissajous_pairs: 0,
            sync_edges: 0,
            stream,
            pickoff_lag_ticks: 0,
            counter,
            config,
            gyro,
        })
    }

    fn schedule(config: &BoardConfig) -> Result<Option<EdgeSchedule>, BoardError> {
        let LatchTiming::Scheduled {
            comparator_offset_arcsec,
            pickoff_delay_ticks,
            aperture_delay_ticks,
            rate_shift,
        } = config.latch
        else {
            return Ok(None);
        };
        if !(comparator_offset_arcsec.is_finite() && config.timer_hz < u32::MAX as f64) {
            return Err(BoardError::Config(
                "comparator threshold must be finite, the timer below 2^32 Hz",
            ));
        }
        Ok(Some(EdgeSchedule {
            threshold_v: config.pickoff.threshold_v(comparator_offset_arcsec),
            pickoff_delay_s: pickoff_delay_ticks as f64 / config.timer_hz,
            aperture_delay_s: aperture_delay_ticks as f64 / config.timer_hz,
            rate_shift,
            // The profile's dither range and pick-off polarity (the pick-off reads the dither
            // angle in the sense of the beat phase: after a rising edge comes a maximum, a "-"
            // turnaround), with this board's timer and delays.
            config: config.profile().scheduler_config(),
            scheduler: Scheduler::new(),
            cursor_s: 0.0,
        }))
    }

    /// Runs to the next turnaround: fills `lissajous` with the conversions taken on the way and
    /// returns the turnaround latch.
    pub fn next_half_cycle(&mut self, lissajous: &mut Vec<(AdcCode, AdcCode)>) -> TurnaroundSample {
        lissajous.clear();
        let (kind, latch_s, record) = match self.schedule {
            None => {
                let turnaround = self.gyro.upcoming_turnaround();
                let latch_s = self.with_latch_error(turnaround.time_s).max(self.time_s);
                let record = LatchRecord {
                    latch_s,
                    turnaround,
                    scheduled: false,
                };
                (turnaround.kind, latch_s, record)
            }
            Some(schedule) => self.scheduled_latch(schedule, lissajous),
        };
        self.last_latch = Some(record);
        self.sample_lissajous_until(latch_s, lissajous);
        let psi_h = self.gyro.advance_to(latch_s) - self.eps_at(latch_s);
        self.time_s = latch_s;
        latch_turnaround(
            kind,
            latch_s,
            psi_h,
            &mut self.counter,
            &mut self.photodiodes,
            &self.timer,
        )
    }

    /// `t_s` plus the residual error of the latch instant (offset and a jitter draw), s.
    fn with_latch_error(&mut self, t_s: f64) -> f64 {
        let jitter: f64 = if self.config.latch_jitter_rms_s > 0.0 {
            let z: f64 = StandardNormal.sample(&mut self.rng);
            z * self.config.latch_jitter_rms_s
        } else {
            0.0
        };
        t_s + self.config.latch_offset_s + jitter
    }

    /// The free-running conversions, the pick-off stream and the output latches before
    /// `until_s`, in time order.
    fn sample_lissajous_until(&mut self, until_s: f64, lissajous: &mut Vec<(AdcCode, AdcCode)>) {
        loop {
            let tick_s = self.stream.next_instant_s();
            if tick_s < until_s && tick_s <= self.next_lissajous_s.min(self.next_sync_s) {
                if self.faults.stopped(Trigger::DriveTick) {
                    // TIM4 stopped: no conversion of the pick-off, a gap in the stream.
                    self.stream.skip_next();
                } else {
                    self.stream
                        .take_next(&mut self.pickoff, &self.gyro, &self.timer);
                }
                continue;
            }
            let sync_first = self.next_sync_s < self.next_lissajous_s;
            let t = self.next_lissajous_s.min(self.next_sync_s);
            if t >= until_s {
                return;
            }
            let psi_h = self.gyro.advance_to(t) - self.eps_at(t);
            self.counter.advance_to(psi_h);
            let codes = self.photodiodes.sample_codes(psi_h);
            if sync_first && self.faults.stopped(Trigger::Sync) {
                // No sync edge: no output latch.
                let hz = self.config.sync_hz.unwrap_or(f64::INFINITY);
                self.next_sync_s = ((t * hz).round() + 1.0) / hz;
            } else if sync_first {
                self.sync_edges += 1;
                self.outputs.push(OutputLatch {
                    sample: OutputSample {
                        encoder_count: self.counter.count(),
                        adc_a_code: codes.a_code,
                        adc_b_code: codes.b_code,
                        pickoff_code: self.pickoff.sample_latch_code(&self.gyro, t),
                        timestamp_ticks: self.timer.ticks_at(t),
                        drive_locked: true,
                    },
                    t_s: t,
                    true_angle_arcsec: self.gyro.input_angle_arcsec(t),
                });
                // From the sync count, not by adding periods: no drift of the edge times.
                let hz = self.config.sync_hz.unwrap_or(f64::INFINITY);
                self.next_sync_s = ((t * hz).round() + 1.0) / hz;
            } else {
                if !self.faults.stopped(Trigger::Lissajous) {
                    lissajous.push((codes.a_code, codes.b_code));
                    self.lissajous_pairs += 1;
                }
                self.next_lissajous_s += 1.0 / self.config.lissajous_rate_hz;
            }
        }
    }

    /// Hands over the output latches taken since the last call (a sync edge each, in order).
    pub fn drain_outputs(&mut self, into: &mut Vec<OutputLatch>) {
        into.clear();
        into.append(&mut self.outputs);
    }

    /// Hands over the pick-off stream's conversions up to the board's time since the last call
    /// (in time order, on the capture timer's time base like the output latches).
    pub fn drain_pickoff_samples(&mut self, into: &mut Vec<PickoffSample>) {
        self.stream.drain(into);
    }

    /// The pick-off's conversion at drive tick `n` (absolute, from t = 0): the firmware's drive
    /// reads it at each tick; the readout gets the same conversion from the stream.
    pub fn drive_tick_code(&mut self, n: u64) -> AdcCode {
        self.stream.code(&mut self.pickoff, &self.gyro, n)
    }

    /// The pick-off's lag as the readout measures it (`Readout::pickoff_lag_ticks`): the
    /// schedule subtracts it from the next latches, as the board's readout task publishes it to
    /// the pick-off handler. `None` keeps the last value.
    pub fn set_pickoff_lag_ticks(&mut self, lag_ticks: Option<i32>) {
        if let Some(lag) = lag_ticks {
            self.pickoff_lag_ticks = lag;
        }
    }

    /// The next pick-off edge, its capture and its schedule; the kind and instant of the latch.
    /// Runs the gyro (and the Lissajous stream) up to the edge.
    fn scheduled_latch(
        &mut self,
        mut schedule: EdgeSchedule,
        lissajous: &mut Vec<(AdcCode, AdcCode)>,
    ) -> (TurnaroundKind, f64, LatchRecord) {
        let period_s = 1.0 / self.gyro.params().dither_hz;
        let mut planned = None;
        match self.next_edge(&schedule, period_s) {
            Some((edge, edge_s)) => {
                schedule.cursor_s = edge_s;
                self.stats.edges += 1;
                self.sample_lissajous_until(edge_s, lissajous);
                if edge_s > self.gyro.t_s() {
                    self.gyro.advance_to(edge_s);
                }
                let capture_s = edge_s + schedule.pickoff_delay_s;
                let capture_ticks = self.timer.ticks_at(capture_s);
                let shift = if schedule.rate_shift {
                    self.rate_shift_ticks
                } else {
                    0
                };
                let outcome = schedule.scheduler.on_edge(
                    &schedule.config,
                    edge,
                    capture_ticks,
                    shift,
                    self.pickoff_lag_ticks,
                );
                self.stats.implausible_edges += outcome.implausible as u64;
                planned = outcome.schedule.map(|s| {
                    let compare_s = self.timer.time_of_ticks_s(s.compare_ticks, capture_s);
                    (s.kind, compare_s, compare_s + schedule.aperture_delay_s)
                });
            }
            // No edge for a whole period (no dither, a threshold beyond the amplitude, a lost
            // pick-off): this half cycle falls back to the turnaround, and the next search
            // starts there (not a period on: the cursor must not run ahead of the board's time).
            None => {
                let next = self.gyro.upcoming_turnaround().time_s;
                schedule.cursor_s = schedule.cursor_s.max(next);
            }
        }
        self.schedule = Some(schedule);
        let turnaround = self.gyro.upcoming_turnaround();
        let on_time = planned.filter(|&(kind, compare_s, sample_s)| {
            kind == turnaround.kind
                && compare_s > self.gyro.t_s()
                && (sample_s - turnaround.time_s).abs() < period_s / 8.0
        });
        let (kind, at_s, scheduled) = match on_time {
            Some((kind, _, sample_s)) => {
                self.stats.scheduled += 1;
                (kind, sample_s, true)
            }
            None => {
                self.stats.fallbacks += 1;
                (turnaround.kind, turnaround.time_s, false)
            }
        };
        let latch_s = self.with_latch_error(at_s).max(self.gyro.t_s());
        let record = LatchRecord {
            latch_s,
            turnaround,
            scheduled,
        };
        (kind, latch_s, record)
    }

    /// The first crossing of the comparator threshold by the pick-off after the search cursor,
    /// within one dither period: bracketed in steps of T/32, then bisected to 10 ps. Returns the
    /// first instant on the far side (so the next search starts past it).
    fn next_edge(&self, schedule: &EdgeSchedule, period_s: f64) -> Option<(Edge, f64)> {
        if !(self.gyro.free_phase().dither().is_on() && period_s.is_finite()) {
            return None;
        }
        let above = |t: f64| {
            self.pickoff
                .comparator_high(&self.gyro, t, schedule.threshold_v)
        };
        let step = period_s / 32.0;
        let mut a = schedule.cursor_s;
        let side = above(a);
        for _ in 0..32 {
            let mut b = a + step;
            if above(b) == side {
                a = b;
                continue;
            }
            // 10 ps, or adjacent floats (after ~1e5 s of simulated time).
            while b - a > 1e-11 {
                let m = 0.5 * (a + b);
                if m <= a || m >= b {
                    break;
                }
                if above(m) == side {
                    a = m;
                } else {
                    b = m;
                }
            }
            let edge = if side { Edge::Falling } else { Edge::Rising };
            return Some((edge, b));
        }
        None
    }

    /// Hands the board the cycle the firmware just closed: its input-rate shift times the next
    /// scheduled turnarounds (as the board's cycle task publishes it to the pick-off handler).
    pub fn on_cycle(&mut self, record: &CycleRecord) {
        self.rate_shift_ticks = rate_shift_ticks(record, self.config.timer_hz.round() as u32);
    }

    /// The input-rate shift in use, ticks (Omega_i/|psi_ddot|, from the last [`Self::on_cycle`]).
    pub fn rate_shift_ticks(&self) -> i32 {
        self.rate_shift_ticks
    }

    /// The board's configuration.
    pub fn config(&self) -> &BoardConfig {
        &self.config
    }

    /// How the turnarounds were latched so far.
    pub fn latch_stats(&self) -> LatchStats {
        self.stats
    }

    /// The last latch and the true turnaround it was meant for.
    pub fn last_latch(&self) -> Option<LatchRecord> {
        self.last_latch
    }

    /// The photodiode phase offset at `t_s`, rad.
    pub fn eps_at(&self, t_s: f64) -> f64 {
        self.gyro.eps_rad(t_s)
            + self.config.eps_drift_rad_per_s * t_s.min(self.config.eps_drift_until_s)
    }

    /// Simulated time of the last latch, s.
    pub fn time_s(&self) -> f64 {
        self.time_s
    }

    /// The gyro, with its truth.
    pub fn gyro(&self) -> &Gyro {
        &self.gyro
    }

    /// Drains the gyro's log of completed traversals (the truth about lock-in, for tests).
    pub fn take_traversals(&mut self) -> Vec<crate::gyro::Traversal> {
        self.gyro.take_traversals()
    }

    /// The counter, for glitch injection in tests.
    pub fn counter_mut(&mut self) -> &mut QuadratureCounter {
        &mut self.counter
    }

    /// One conversion of the pick-off's ADC channel at `t_s` (one noise draw), the 12-bit
    /// code: what the firmware's drive loop reads at a drive tick. Needs only the dither (not
    /// the beat phase), so it may run ahead of [`Self::time_s`], within the known drive.
    pub fn pickoff_code(&mut self, t_s: f64) -> AdcCode {
        self.pickoff.sample_code(&self.gyro, t_s)
    }

    /// The pick-off's output at `t_s` with one noise draw, V.
    pub fn pickoff_v(&mut self, t_s: f64) -> f64 {
        self.pickoff.sample_v(&self.gyro, t_s)
    }

    /// The pick-off (its configuration, whether it is lost).
    pub fn pickoff(&self) -> &Pickoff {
        &self.pickoff
    }

    /// The pick-off, for fault injection ([`Pickoff::set_lost`]).
    pub fn pickoff_mut(&mut self) -> &mut Pickoff {
        &mut self.pickoff
    }

    /// Passes a drive segment on to the gyro's driven dither ([`Gyro::push_drive`]).
    pub fn push_drive(&mut self, segment: DriveSegment) -> Result<(), DriveError> {
        self.gyro.push_drive(segment)
    }

    /// The last drive segment holds at least until `t_s` ([`Gyro::extend_drive_until`]).
    pub fn extend_drive_until(&mut self, t_s: f64) -> Result<(), DriveError> {
        self.gyro.extend_drive_until(t_s)
    }

    /// The time up to which the dither is known, s ([`Gyro::drive_known_until_s`]).
    pub fn drive_known_until_s(&self) -> f64 {
        self.gyro.drive_known_until_s()
    }

    /// The next turnaround if the known drive reaches it ([`Gyro::try_upcoming_turnaround`]):
    /// a caller feeding the drive checks it before [`Self::next_half_cycle`].
    pub fn try_upcoming_turnaround(&mut self) -> Option<TurnaroundTime> {
        self.gyro.try_upcoming_turnaround()
    }

    /// The photodiodes, for fault injection in tests ([`Photodiodes::set_fault`]).
    pub fn photodiodes_mut(&mut self) -> &mut Photodiodes {
        &mut self.photodiodes
    }

    /// Injects a fault of the timing chain, the clock or the pick-off ([`BoardFault`]).
    pub fn inject(&mut self, fault: BoardFault) {
        self.faults.inject(fault);
        if fault == BoardFault::DeadPickoff {
            self.pickoff.set_lost(true);
        }
    }

    /// The faults injected so far.
    pub fn faults(&self) -> &BoardFaults {
        &self.faults
    }

    /// Photodiode pairs converted since t = 0 (256 make a DMA half transfer on the board).
    pub fn lissajous_pairs(&self) -> u64 {
        self.lissajous_pairs
    }

    /// Sync edges (or internal output compares) since t = 0.
    pub fn sync_edges(&self) -> u64 {
        self.sync_edges
    }
}

impl DriveSink for SimBoard {
    fn push_drive(&mut self, segment: DriveSegment) -> Result<(), DriveError> {
        SimBoard::push_drive(self, segment)
    }

    fn extend_drive_until(&mut self, t_s: f64) -> Result<(), DriveError> {
        SimBoard::extend_drive_until(self, t_s)
    }

    fn drive_known_until_s(&self) -> f64 {
        SimBoard::drive_known_until_s(self)
    }
}
