//! The on-device calibration procedure (the paper's steps as a device feature).
//!
//! ```text
//!            start_run(rate 1)          run complete            finish()
//!   Idle ──────────────────────► Running ──────────► RunDone ───────────► Ready(fit) ─ accept() ─► Idle
//!     ▲                              │                 │  start_run(rate 2)    │
//!     └──────── abort() ◄────────────┴─────────────────┘  (pooled)            └► Refused(reason)
//! ```
//!
//! A run discards `warmup_cycles`, then feeds `cycles` dither cycles into the least-squares
//! accumulator (flagged cycles are counted and left out). Runs at several input rates (both
//! signs) pool with one intercept each. [`CalibrationSession::finish`] solves and applies the
//! validity checks of [`super::validation`]; an accepted fit becomes Q15.16
//! [`CompensationSettings`] for the readout to stage and the store to persist.
//!
//! The session consumes [`CycleRecord`]s in the low-priority cycle task, not in the turnaround
//! interrupt: the f64 accumulation costs a few microseconds per cycle.

use super::fit::{FitAccumulator, FitResult, SolveError};
use super::validation::{check, AcceptanceLimits, Refusal, RunSummary};
use crate::signal::compensation::{CoefficientError, Coefficients, CompensationSettings};
use crate::signal::lockin::CycleRecord;

/// Where the session stands.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SessionState {
    /// No calibration in progress (initial, and after `accept` or `abort`).
    Idle,
    /// A run is collecting cycles.
    Running {
        /// Warm-up cycles still to discard before the run's cycles count.
        warmup_left: u32,
        /// Cycles still to feed into the fit (flagged ones included, then left out).
        cycles_left: u32,
    },
    /// A run is complete; another may be started (pooled) or the fit finished.
    RunDone,
    /// The fit passed the checks and waits to be accepted.
    Ready(FitResult),
    /// The fit failed a check.
    Refused(Refusal),
}

/// Commands refused in the current state (nothing changes).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum SessionError {
    /// A run is in progress.
    Busy,
    /// `finish` without a completed run.
    NoData,
    /// `accept` without a passing fit.
    NothingToAccept,
    /// A run length of zero cycles.
    ZeroLength,
    /// The fitted coefficients do not fit the Q15.16 format.
    NotRepresentable(CoefficientError),
}

/// The state of a calibration.
#[derive(Clone, Debug)]
pub struct CalibrationSession {
    state: SessionState,
    limits: AcceptanceLimits,
    pooled: FitAccumulator,
    run: FitAccumulator,
    run_sum_rad: f64,
    run_sum_s: f64,
    flagged_cycles: u32,
    amplitude_sum_rad: f64,
    amplitude_count: u32,
    min_abs_run_rate_rad_per_s: f64,
}

impl CalibrationSession {
    /// An idle session that will check its fit against `limits`.
    pub fn new(limits: AcceptanceLimits) -> Self {
        Self {
            state: SessionState::Idle,
            limits,
            pooled: FitAccumulator::new(),
            run: FitAccumulator::new(),
            run_sum_rad: 0.0,
            run_sum_s: 0.0,
            flagged_cycles: 0,
            amplitude_sum_rad: 0.0,
            amplitude_count: 0,
            min_abs_run_rate_rad_per_s: f64::INFINITY,
        }
    }

    /// Where the session stands.
    pub fn state(&self) -> SessionState {
        self.state
    }

    /// Cycles pooled so far (closed runs plus the open one).
    pub fn cycles(&self) -> u64 {
        self.pooled.cycles + self.run.cycles
    }

    /// Starts a run; pooled with the runs before it unless the session was idle (a fresh
    /// calibration) or held a finished fit (which is discarded).
    pub fn start_run(&mut self, warmup_cycles: u32, cycles: u32) -> Result<(), SessionError> {
        if cycles == 0 {
            return Err(SessionError::ZeroLength);
        }
        match self.state {
            SessionState::Running { .. } => return Err(SessionError::Busy),
            SessionState::RunDone => {}
            SessionState::Idle | SessionState::Ready(_) | SessionState::Refused(_) => {
                *self = Self::new(self.limits);
            }
        }
        self.state = SessionState::Running {
            warmup_left: warmup_cycles,
            cycles_left: cycles,
        };
        Ok(())
    }

    /// Feeds one dither cycle (call for every cycle; ignored unless running).
    pub fn on_cycle(&mut self, record: &CycleRecord, cycle_s: f64) {
        let SessionState::Running {
            warmup_left,
            cycles_left,
        } = self.state
        else {
            return;
        };
        if warmup_left > 0 {
            self.state = SessionState::Running {
                warmup_left: warmup_left - 1,
                cycles_left,
            };
            return;
        }
        if record.output.flags.is_empty() {
            let y = record.raw_increment_rad();
            if self.run.push_cycle(record, cycle_s) {
                self.run_sum_rad += y;
                self.run_sum_s += cycle_s;
                self.amplitude_sum_rad += record.dither_amplitude_rad as f64;
                self.amplitude_count += 1;
            }
        } else {
            self.flagged_cycles = self.flagged_cycles.saturating_add(1);
        }
        let cycles_left = cycles_left - 1;
        if cycles_left == 0 {
            self.close_run();
            self.state = SessionState::RunDone;
        } else {
            self.state = SessionState::Running {
                warmup_left: 0,
                cycles_left,
            };
        }
    }

    fn close_run(&mut self) {
        self.run.end_run();
        if self.run_sum_s > 0.0 {
            let rate = libm::fabs(self.run_sum_rad / self.run_sum_s);
            self.min_abs_run_rate_rad_per_s = self.min_abs_run_rate_rad_per_s.min(rate);
        }
        self.pooled.pool(&self.run);
        self.run = FitAccumulator::new();
        self.run_sum_rad = 0.0;
        self.run_sum_s = 0.0;
    }

    /// Solves the pooled runs and checks the fit: `Ready` or `Refused`.
    pub fn finish(&mut self) -> Result<SessionState, SessionError> {
        match self.state {
            SessionState::Running { .. } => return Err(SessionError::Busy),
            SessionState::RunDone => {}
            _ => return Err(SessionError::NoData),
        }
        let summary = RunSummary {
            flagged_cycles: self.flagged_cycles,
            dither_amplitude_rad: if self.amplitude_count > 0 {
                self.amplitude_sum_rad / self.amplitude_count as f64
            } else {
                0.0
            },
            min_abs_run_rate_rad_per_s: self.min_abs_run_rate_rad_per_s,
        };
        self.state = match self.pooled.solve() {
            Err(SolveError::TooFewCycles) => SessionState::Refused(Refusal::TooFewCycles),
            Err(SolveError::Singular) => SessionState::Refused(Refusal::Singular),
            Ok(fit) => match check(&fit, &summary, &self.limits) {
                Ok(()) => SessionState::Ready(fit),
                Err(reason) => SessionState::Refused(reason),
            },
        };
        Ok(self.state)
    }

    /// Takes a passing fit as compensation settings (enabled), returning the session to idle.
    pub fn accept(&mut self) -> Result<(CompensationSettings, FitResult), SessionError> {
        let SessionState::Ready(fit) = self.state else {
            return Err(SessionError::NothingToAccept);
        };
        let coefficients =
            Coefficients::from_rad_per_s(fit.a_rad_per_s as f32, fit.b_rad_per_s as f32)
                .map_err(SessionError::NotRepresentable)?;
        *self = Self::new(self.limits);
        Ok((
            CompensationSettings {
                coefficients,
                enabled: true,
            },
            fit,
        ))
    }

    /// Drops everything; back to idle.
    pub fn abort(&mut self) {
        *self = Self::new(self.limits);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::signal::lockin::LockinTerms;
    use crate::signal::lockin::{CycleFlags, CycleOutput};
    use crate::units::{PhaseDelta, TotalPhase};

    const Q32: f64 = crate::units::Q32_PER_FRINGE;
    const TAU: f64 = core::f64::consts::TAU;
    const K: f64 = 26.3e-6;
    const A: f64 = 344.0;
    const B: f64 = 579.0;

    /// A synthetic cycle at `rate` rad/s whose error is exactly a P1 + b P2.
    fn cycle(i: u32, rate: f64, flags: CycleFlags) -> CycleRecord {
        let (u, v) = (
            (i as f64 * 0.618).fract() * TAU,
            (i as f64 * 0.414).fract() * TAU,
        );
        let terms = LockinTerms {
            p1_s: (K * (u.cos() + v.sin())) as f32,
            p2_s: (K * (v.cos() - u.sin())) as f32,
        };
        let y = rate / 389.0 + A * terms.p1_s as f64 + B * terms.p2_s as f64;
        let q = (y / TAU * Q32).round() as i64;
        CycleRecord {
            output: CycleOutput {
                increment: PhaseDelta::from_q32(q),
                correction: PhaseDelta::ZERO,
                duration_ticks: 215_938,
                flags,
            },
            raw_increment: PhaseDelta::from_q32(q),
            terms,
            end_phase: TotalPhase::from_q32(0),
            dither_amplitude_rad: (TAU * 450.0 / 1.8655) as f32,
            dither_hz: 389.0,
        }
    }

    fn run(s: &mut CalibrationSession, rate: f64, n: u32) {
        s.start_run(10, n).unwrap();
        for i in 0..n + 10 {
            s.on_cycle(&cycle(i, rate, CycleFlags::empty()), 1.0 / 389.0);
        }
        assert_eq!(s.state(), SessionState::RunDone);
    }

    /// Two runs at +-13.888 deg/h pool into a fit that recovers a and b (1e-6: Q32 rounding of
    /// the synthetic outputs) and is accepted as Q15.16 settings.
    #[test]
    fn pooled_runs_fit_check_and_accept() {
        let mut s = CalibrationSession::new(AcceptanceLimits::DEFAULT);
        let rate = TAU * 13.888 / 1.8655;
        run(&mut s, rate, 3000);
        run(&mut s, -rate, 3000);
        let SessionState::Ready(fit) = s.finish().unwrap() else {
            panic!("refused: {:?}", s.state());
        };
        assert_eq!((fit.runs, fit.cycles), (2, 6000));
        assert!((fit.a_rad_per_s / A - 1.0).abs() < 1e-6, "{fit:?}");
        assert!((fit.b_rad_per_s / B - 1.0).abs() < 1e-6);
        let (settings, _) = s.accept().unwrap();
        assert!(settings.enabled);
        assert!((settings.coefficients.a_rad_per_s() as f64 - A).abs() < 1e-4);
        assert_eq!(s.state(), SessionState::Idle);
    }

    /// A run at 1 deg/h, inside the 3.358 deg/h dead band, is refused with its reason.
    #[test]
    fn inside_the_dead_band_is_refused() {
        let mut s = CalibrationSession::new(AcceptanceLimits::DEFAULT);
        run(&mut s, TAU * 1.0 / 1.8655, 3000);
        assert_eq!(
            s.finish(),
            Ok(SessionState::Refused(Refusal::InsideDeadBand))
        );
        assert_eq!(s.accept(), Err(SessionError::NothingToAccept));
    }

    #[test]
    fn flagged_cycles_refuse_the_fit() {
        let mut s = CalibrationSession::new(AcceptanceLimits::DEFAULT);
        s.start_run(0, 3000).unwrap();
        for i in 0..3000 {
            let flags = if i == 1500 {
                CycleFlags::COUNTER_GLITCH
            } else {
                CycleFlags::empty()
            };
            s.on_cycle(&cycle(i, 46.8, flags), 1.0 / 389.0);
        }
        assert_eq!(
            s.finish(),
            Ok(SessionState::Refused(Refusal::SignalProblems))
        );
    }

    /// Commands out of order are refused and change nothing.
    #[test]
    fn commands_out_of_order() {
        let mut s = CalibrationSession::new(AcceptanceLimits::DEFAULT);
        assert_eq!(s.finish(), Err(SessionError::NoData));
        assert_eq!(s.start_run(0, 0), Err(SessionError::ZeroLength));
        s.start_run(0, 100).unwrap();
        let running = s.state();
        assert_eq!(s.start_run(0, 100), Err(SessionError::Busy));
        assert_eq!(s.finish(), Err(SessionError::Busy));
        assert_eq!(s.state(), running);
        s.abort();
        assert_eq!(s.state(), SessionState::Idle);
        assert_eq!(s.cycles(), 0);
    }

    /// Too few cycles is its own refusal.
    #[test]
    fn too_few_cycles() {
        let mut s = CalibrationSession::new(AcceptanceLimits::DEFAULT);
        run(&mut s, 46.8, 500);
        assert_eq!(s.finish(), Ok(SessionState::Refused(Refusal::TooFewCycles)));
    }
}
