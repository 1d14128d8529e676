//! `cal start/status/abort/result/accept`, and the state that learns coefficients from dither
//! cycles: the calibration session and the online tracking loop ([`CalibrationState`]).
//!
//! Both consume every dither cycle ([`CalibrationState::on_cycle`]), so they live together;
//! `track on/off` is a settings command ([`super::settings`]) but switches the loop held here.
//!
//! Refusals change nothing, with one deliberate exception: `cal result` on a completed run
//! solves the fit, and a fit that fails its checks is answered `ERR 12` with the reason while
//! the session moves to "refused" (the refusal *is* the result; `cal status` reports it).

use super::provenance::Provenance;
use super::{ok_with, Answer};
use crate::calibration::fit::FitResult;
use crate::calibration::session::{CalibrationSession, SessionError, SessionState};
use crate::calibration::tracking::{TrackingLoop, TrackingLoopConfig};
use crate::calibration::validation::AcceptanceLimits;
use crate::protocol::link::{DeviceLink, Identity};
use crate::protocol::respond::Response;
use crate::protocol::ErrorCode;
use crate::signal::compensation::{Coefficients, CompensationSettings};
use crate::signal::lockin::CycleRecord;
use crate::storage::FitSummary;

/// The calibration session and the tracking loop (when on) with its configuration.
#[derive(Clone, Debug)]
pub struct CalibrationState {
    session: CalibrationSession,
    tracking_config: TrackingLoopConfig,
    tracking: Option<TrackingLoop>,
}

impl CalibrationState {
    /// Idle, tracking off (memory 20 000 cycles when it is switched on).
    pub fn new(limits: AcceptanceLimits) -> Self {
        Self {
            session: CalibrationSession::new(limits),
            tracking_config: TrackingLoopConfig::with_memory(20_000.0),
            tracking: None,
        }
    }

    /// Whether a calibration run is collecting cycles (protected commands answer `ERR 10`).
    pub fn running(&self) -> bool {
        matches!(self.session.state(), SessionState::Running { .. })
    }

    /// Whether a completed run waits to be pooled with another or solved (`cal result` would
    /// close it).
    pub fn run_done(&self) -> bool {
        matches!(self.session.state(), SessionState::RunDone)
    }

    /// Whether online tracking runs.
    pub fn tracking(&self) -> bool {
        self.tracking.is_some()
    }

    /// Switches tracking on (from the coefficients `from`) or off; the memory when on.
    pub fn set_tracking(&mut self, on: bool, from: Coefficients) -> Option<f64> {
        self.tracking = on.then(|| TrackingLoop::new(&self.tracking_config, from));
        on.then_some(self.tracking_config.tracking.memory_cycles)
    }

    /// One dither cycle: feeds a running calibration and the tracking loop; returns the
    /// settings to stage when tracking has new coefficients.
    pub fn on_cycle(&mut self, record: &CycleRecord, cycle_s: f64) -> Option<CompensationSettings> {
        self.session.on_cycle(record, cycle_s);
        let tracking = self.tracking.as_mut()?;
        let coefficients = tracking.on_cycle(&self.tracking_config, record, cycle_s)?;
        Some(CompensationSettings {
            coefficients,
            enabled: true,
        })
    }

    /// `cal start <cycles> [<warmup>]`.
    pub fn start(&mut self, cycles: u32, warmup_cycles: u32) -> Answer {
        self.session
            .start_run(warmup_cycles, cycles)
            .map_err(session_error)?;
        Ok(ok_with(format_args!(
            "cal=running cycles={cycles} warmup={warmup_cycles}"
        )))
    }

    /// `cal status`.
    pub fn status(&self) -> Response {
        let cycles = self.session.cycles();
        match self.session.state() {
            SessionState::Idle => ok_with(format_args!("cal=idle")),
            SessionState::Running {
                warmup_left,
                cycles_left,
            } => ok_with(format_args!(
                "cal=running warmup_left={warmup_left} cycles_left={cycles_left} cycles={cycles}"
            )),
            SessionState::RunDone => ok_with(format_args!("cal=run_done cycles={cycles}")),
            SessionState::Ready(_) => ok_with(format_args!("cal=ready cycles={cycles}")),
            SessionState::Refused(reason) => ok_with(format_args!(
                "cal=refused reason={} {}",
                reason.code(),
                reason.text()
            )),
        }
    }

    /// `cal abort`.
    pub fn abort(&mut self) -> Response {
        self.session.abort();
        ok_with(format_args!("cal=idle"))
    }

    /// `cal result`: solves a completed run, then reports the fit or why it was refused.
    pub fn result(&mut self, id: &Identity) -> Answer {
        let state = match self.session.state() {
            SessionState::RunDone => self.session.finish().map_err(session_error)?,
            s => s,
        };
        match state {
            SessionState::Ready(fit) => Ok(fit_fields(&fit, id)),
            SessionState::Refused(reason) => {
                // An error answer with the reason attached (cal result is not protected, so
                // returning it as Ok does not extend an unlock).
                let mut e = Response::err(ErrorCode::FitRefused);
                e.field(format_args!("reason={} {}", reason.code(), reason.text()));
                Ok(e)
            }
            SessionState::Running { .. } => Err(ErrorCode::Busy),
            _ => Err(ErrorCode::WrongState),
        }
    }

    /// `cal accept`: stages the passing fit's coefficients (compensation on).
    pub fn accept<D: DeviceLink>(&mut self, device: &mut D, provenance: &mut Provenance) -> Answer {
        let (settings, fit) = self.session.accept().map_err(session_error)?;
        device.stage_settings(settings);
        provenance.changed();
        provenance.fit = Some(FitSummary::from_fit(&fit));
        Ok(ok_with(format_args!(
            "a={} b={} comp=on",
            settings.coefficients.a_rad_per_s(),
            settings.coefficients.b_rad_per_s()
        )))
    }
}

fn session_error(e: SessionError) -> ErrorCode {
    match e {
        SessionError::Busy => ErrorCode::Busy,
        SessionError::ZeroLength => ErrorCode::OutOfRange,
        SessionError::NoData | SessionError::NothingToAccept => ErrorCode::WrongState,
        SessionError::NotRepresentable(_) => ErrorCode::OutOfRange,
    }
}

fn fit_fields(fit: &FitResult, id: &Identity) -> Response {
    // Formatted in f32 (7 significant digits, more than any field shows) and in decimal: the f64
    // and the exponential formatting code would cost 2.5 and 1.5 KiB of flash for nothing the
    // answer needs (the standard errors to 1 mrad/s, finer than any fit reaches).
    let to_deg_h = id.scale_factor_arcsec as f64 / core::f64::consts::TAU;
    let f = |x: f64| x as f32;
    ok_with(format_args!(
        "a={:.4} b={:.4} a_std={:.3} b_std={:.3} lock_in_deg_h={:.4} eps_rad={:.5} var_red={:.6} cond={:.3} \
mean_rate_deg_h={:.4} cycles={} runs={}",
        f(fit.a_rad_per_s),
        f(fit.b_rad_per_s),
        f(fit.a_std_rad_per_s),
        f(fit.b_std_rad_per_s),
        f(fit.lock_in_rad_per_s * to_deg_h),
        f(fit.eps_rad),
        f(fit.variance_reduction),
        f(fit.condition_number),
        f(fit.mean_rate_rad_per_s * to_deg_h),
        fit.cycles,
        fit.runs
    ))
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::protocol::commands::provenance::Source;
    use crate::protocol::commands::testing::{report, text, MemDevice, ID};
    use crate::signal::lockin::LockinTerms;
    use crate::signal::lockin::{CycleFlags, CycleOutput};
    use crate::storage::{DefaultsReason, LoadOutcome};
    use crate::units::{PhaseDelta, TotalPhase};

    const TAU: f64 = core::f64::consts::TAU;

    /// A synthetic cycle at `rate` rad/s whose error is exactly a P1 + b P2 (a = 344, b = 579
    /// rad/s), as in the session's own tests.
    pub(crate) fn cycle(i: u32, rate: f64) -> CycleRecord {
        let (u, v) = (
            (i as f64 * 0.618).fract() * TAU,
            (i as f64 * 0.414).fract() * TAU,
        );
        let k = 26.3e-6;
        let terms = LockinTerms {
            p1_s: (k * (u.cos() + v.sin())) as f32,
            p2_s: (k * (v.cos() - u.sin())) as f32,
        };
        let y = rate / 389.0 + 344.0 * terms.p1_s as f64 + 579.0 * terms.p2_s as f64;
        let q = (y / TAU * crate::units::Q32_PER_FRINGE).round() as i64;
        CycleRecord {
            output: CycleOutput {
                increment: PhaseDelta::from_q32(q),
                correction: PhaseDelta::ZERO,
                duration_ticks: 215_938,
                flags: CycleFlags::empty(),
            },
            raw_increment: PhaseDelta::from_q32(q),
            terms,
            end_phase: TotalPhase::from_q32(0),
            dither_amplitude_rad: (TAU * 450.0 / 1.8655) as f32,
            dither_hz: 389.0,
        }
    }

    fn run(cal: &mut CalibrationState, rate: f64, n: u32) {
        cal.start(n, 10).unwrap();
        assert!(cal.running());
        for i in 0..n + 10 {
            assert_eq!(cal.on_cycle(&cycle(i, rate), 1.0 / 389.0), None);
        }
        assert!(!cal.running());
    }

    fn boot() -> Provenance {
        let reason = DefaultsReason::Erased;
        Provenance::new(&report(LoadOutcome::Defaults { reason }), None, 1)
    }

    #[test]
    fn start_status_abort() {
        let mut cal = CalibrationState::new(AcceptanceLimits::DEFAULT);
        assert_eq!(text(cal.status()).trim_end(), "OK cal=idle");
        let started = text(cal.start(100, 5).unwrap());
        assert_eq!(started.trim_end(), "OK cal=running cycles=100 warmup=5");
        assert_eq!(
            text(cal.status()).trim_end(),
            "OK cal=running warmup_left=5 cycles_left=100 cycles=0"
        );
        // A second start while running is refused and the run goes on.
        assert_eq!(cal.start(10, 0).unwrap_err(), ErrorCode::Busy);
        assert!(cal.running());
        assert_eq!(cal.result(&ID).unwrap_err(), ErrorCode::Busy);
        assert_eq!(text(cal.abort()).trim_end(), "OK cal=idle");
        assert!(!cal.running());
    }

    #[test]
    fn refusals_change_nothing() {
        let mut cal = CalibrationState::new(AcceptanceLimits::DEFAULT);
        let (mut device, mut provenance) = (MemDevice::default(), boot());
        assert_eq!(cal.start(0, 0).unwrap_err(), ErrorCode::OutOfRange);
        assert_eq!(cal.result(&ID).unwrap_err(), ErrorCode::WrongState);
        let accept = cal.accept(&mut device, &mut provenance);
        assert_eq!(accept.unwrap_err(), ErrorCode::WrongState);
        assert_eq!(text(cal.status()).trim_end(), "OK cal=idle");
        assert_eq!(device, MemDevice::default());
        assert_eq!(provenance, boot());
    }

    #[test]
    fn pooled_runs_give_a_result_that_accept_stages() {
        let mut cal = CalibrationState::new(AcceptanceLimits::DEFAULT);
        let rate = TAU * 13.888 / 1.8655;
        run(&mut cal, rate, 3000);
        run(&mut cal, -rate, 3000);
        assert_eq!(text(cal.status()).trim_end(), "OK cal=run_done cycles=6000");
        let result = text(cal.result(&ID).unwrap());
        assert!(result.starts_with("OK a=344.0000 b=579.0000 "), "{result}");
        assert!(
            result.trim_end().ends_with("cycles=6000 runs=2"),
            "{result}"
        );
        assert_eq!(text(cal.status()).trim_end(), "OK cal=ready cycles=6000");

        let (mut device, mut provenance) = (MemDevice::default(), boot());
        let accepted = text(cal.accept(&mut device, &mut provenance).unwrap());
        assert_eq!(accepted.trim_end(), "OK a=344 b=579 comp=on");
        assert!(device.settings.enabled);
        assert_eq!(device.staged, 1);
        assert_eq!(provenance.source, Source::Unsaved);
        assert!(provenance.fit.is_some());
        assert_eq!(text(cal.status()).trim_end(), "OK cal=idle");
    }

    #[test]
    fn a_failing_fit_is_answered_err_12_with_the_reason() {
        let mut cal = CalibrationState::new(AcceptanceLimits::DEFAULT);
        // One short run at zero rate: the fit fails the validation checks (one run, too few
        // cycles), so `cal result` answers ERR 12 with the reason and the session says so.
        run(&mut cal, 0.0, 20);
        match cal.result(&ID) {
            Ok(r) => {
                let line = text(r);
                assert!(
                    line.starts_with("ERR 12 ") && line.contains("reason="),
                    "{line}"
                );
                assert!(text(cal.status()).starts_with("OK cal=refused reason="));
            }
            Err(code) => panic!("refusal expected, got {code:?}"),
        }
    }

    #[test]
    fn tracking_switches_and_reports_its_memory() {
        let mut cal = CalibrationState::new(AcceptanceLimits::DEFAULT);
        let c = Coefficients::from_rad_per_s(0.0, 0.0).unwrap();
        assert_eq!(cal.set_tracking(true, c), Some(20_000.0));
        assert!(cal.tracking());
        assert_eq!(cal.set_tracking(false, c), None);
        assert!(!cal.tracking());
    }
}
