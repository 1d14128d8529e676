//! The command executor: a parsed [`Command`] and the device's state in, exactly one answer out.
//!
//! Sans-IO: what the protocol needs from the rest of the firmware is the [`DeviceLink`] trait
//! (a status snapshot, staging settings into the readout, storing and loading the calibration),
//! implemented by the board code (critical sections around the readout's staging slot) and by
//! hal-sim's simulated board. The executor owns the slow state: access control, the calibration
//! session, where the coefficients came from, and the stream settings.
//!
//! Rules:
//! - reads (`id`, `status`, `get`, `cal status`, `cal result`, `help`) never need an unlock;
//! - everything that changes coefficients, compensation or flash (`set`, `comp`, `track`,
//!   `cal accept`, `store`, `reload`, `defaults`) needs one, and extends it when it succeeds;
//! - while a calibration run collects cycles, those commands answer `ERR 10` (busy): the run's
//!   data would no longer match the coefficients;
//! - a refused command changes nothing, with one deliberate exception: `cal result` on a
//!   completed run solves the fit, and a fit that fails its checks is answered `ERR 12` while
//!   the session moves to "refused" (the refusal *is* the result; `cal status` reports it).

use super::access::{Access, AccessConfig, UnlockOutcome};
use super::parse::{Coefficient, Command};
use super::respond::Response;
use super::stream::StreamRecord;
use super::ErrorCode;
use crate::calibration::fit::FitResult;
use crate::calibration::session::{CalibrationSession, SessionError, SessionState};
use crate::calibration::tracking::{TrackingLoop, TrackingLoopConfig};
use crate::calibration::validation::AcceptanceLimits;
use crate::signal::compensation::{Coefficients, CompensationSettings};
use crate::signal::cycle::CycleRecord;
use crate::storage::{
    CalibrationRecord, DefaultsReason, FitSummary, LoadOutcome, LoadReport, StoreError,
};

/// What the device is, for `id` (constants of the build and of the board's OTP block).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Identity {
    pub firmware_version: &'static str,
    pub build: &'static str,
    pub board: &'static str,
    /// The gyro's serial number (OTP flash on the board).
    pub serial_number: u32,
    /// The calibration unlock key (OTP flash on the board, written at production).
    pub key: u32,
    /// Scale factor, arcsec per fringe: only for reporting deg/h.
    pub scale_factor_arcsec: f32,
    /// Capture-timer frequency, Hz: the unit of the streamed cycle durations.
    pub capture_timer_hz: u32,
}

/// A snapshot of the readout, for `status`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DeviceStatus {
    /// The last turnaround's photodiode levels were usable.
    pub signal_ok: bool,
    pub dither_hz: f32,
    /// Dither amplitude, beat-phase rad.
    pub dither_amplitude_rad: f32,
    pub turnarounds: u32,
    pub cycles: u32,
    pub counter_glitches: u32,
    pub phase_glitches: u32,
    pub signal_lost: u32,
    pub missed_turnarounds: u32,
    /// Latest averaged output rate, deg/h.
    pub rate_deg_per_h: f32,
}

/// What the protocol needs from the rest of the firmware.
pub trait DeviceLink {
    type FlashError: core::fmt::Debug;
    /// A millisecond tick (wrapping).
    fn now_ms(&self) -> u32;
    fn status(&self) -> DeviceStatus;
    /// The settings the readout applies now.
    fn active_settings(&self) -> CompensationSettings;
    /// Hands settings to the readout; they take effect whole at the next cycle boundary.
    fn stage_settings(&mut self, settings: CompensationSettings);
    /// Pauses the readout, stores the record (read back), resumes; returns its sequence number.
    fn store(&mut self, record: &CalibrationRecord) -> Result<u32, StoreError<Self::FlashError>>;
    /// Reads the newest valid record (or the defaults) with the store's report.
    fn load(&mut self) -> (CalibrationRecord, LoadReport);
}

/// Where the coefficients in force came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Source {
    Flash {
        sequence: u32,
    },
    Defaults(DefaultsReason),
    /// Changed since the last store or load.
    Unsaved,
}

/// The executor's state.
#[derive(Clone, Debug)]
pub struct Executor {
    access: Access,
    access_config: AccessConfig,
    session: CalibrationSession,
    source: Source,
    /// The fit behind the coefficients in force (stored with them), if any.
    fit: Option<FitSummary>,
    boot_count: u32,
    stream_divider: Option<u16>,
    stream_countdown: u16,
    stream_sequence: u32,
    tracking_config: TrackingLoopConfig,
    tracking: Option<TrackingLoop>,
}

/// What a dither cycle asks of the serial task.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CycleActions {
    /// A stream frame to send.
    pub frame: Option<StreamRecord>,
    /// Coefficients the tracking loop wants staged (compensation on).
    pub stage: Option<CompensationSettings>,
}

const HELP: &str =
    "commands: id status get{a|b|coeffs} set{a|b}<rad/s> comp{on|off} track{on|off} \
cal{start<n>[<warmup>]|status|abort|result|accept} store reload defaults stream{on[<n>]|off} \
unlock<key> lock help";

impl Executor {
    /// The state after boot: locked, coefficients as `load` found them.
    pub fn new(
        report: &LoadReport,
        fit: Option<FitSummary>,
        boot_count: u32,
        limits: AcceptanceLimits,
    ) -> Self {
        Self {
            access: Access::new(),
            access_config: AccessConfig::DEFAULT,
            session: CalibrationSession::new(limits),
            source: source_of(report),
            fit,
            boot_count,
            stream_divider: None,
            stream_countdown: 0,
            stream_sequence: 0,
            tracking_config: TrackingLoopConfig::with_memory(20_000.0),
            tracking: None,
        }
    }

    /// Whether online tracking runs.
    pub fn tracking(&self) -> bool {
        self.tracking.is_some()
    }

    pub fn source(&self) -> Source {
        self.source
    }

    /// Whether binary streaming is on.
    pub fn streaming(&self) -> bool {
        self.stream_divider.is_some()
    }

    /// Every dither cycle (from the low-priority cycle task): feeds a running calibration and
    /// the tracking loop; returns a stream frame when one is due and coefficients to stage when
    /// tracking has new ones.
    pub fn on_cycle(&mut self, record: &CycleRecord, cycle_s: f64) -> CycleActions {
        self.session.on_cycle(record, cycle_s);
        let mut actions = CycleActions::default();
        if let Some(tracking) = self.tracking.as_mut() {
            if let Some(coefficients) = tracking.on_cycle(&self.tracking_config, record, cycle_s) {
                actions.stage = Some(CompensationSettings {
                    coefficients,
                    enabled: true,
                });
                self.source = Source::Unsaved;
                self.fit = None;
            }
        }
        if let Some(divider) = self.stream_divider {
            if self.stream_countdown > 1 {
                self.stream_countdown -= 1;
            } else {
                self.stream_countdown = divider;
                actions.frame = Some(StreamRecord::from_cycle(self.stream_sequence, record));
                self.stream_sequence = self.stream_sequence.wrapping_add(1);
            }
        }
        actions
    }

    /// Executes one command.
    pub fn execute<D: DeviceLink>(
        &mut self,
        id: &Identity,
        device: &mut D,
        command: Command,
    ) -> Response {
        let now = device.now_ms();
        if protected(&command) {
            if !self.access.is_unlocked(now) {
                return Response::err(ErrorCode::Locked);
            }
            if matches!(self.session.state(), SessionState::Running { .. }) {
                return Response::err(ErrorCode::Busy);
            }
        }
        let answer = self.run(id, device, now, command);
        if protected(&command) && answer.is_ok() {
            self.access.touch(&self.access_config, now);
        }
        answer.unwrap_or_else(Response::err)
    }

    fn run<D: DeviceLink>(
        &mut self,
        id: &Identity,
        device: &mut D,
        now: u32,
        command: Command,
    ) -> Result<Response, ErrorCode> {
        let mut r = Response::ok();
        match command {
            Command::Help => {
                r.field(format_args!("{HELP}"));
            }
            Command::Identify => {
                r.field(format_args!(
                    "fw={} build={} board={} serial={} sf_arcsec={} timer_hz={}",
                    id.firmware_version,
                    id.build,
                    id.board,
                    id.serial_number,
                    id.scale_factor_arcsec,
                    id.capture_timer_hz
                ));
            }
            Command::Status => self.status(id, device, now, &mut r),
            Command::Get(which) => {
                let c = device.active_settings().coefficients;
                match which {
                    Some(Coefficient::A) => r.field(format_args!("a={}", c.a_rad_per_s())),
                    Some(Coefficient::B) => r.field(format_args!("b={}", c.b_rad_per_s())),
                    None => r.field(format_args!(
                        "a={} b={} lock_in_deg_h={} eps_rad={}",
                        c.a_rad_per_s(),
                        c.b_rad_per_s(),
                        lock_in_deg_h(&c, id),
                        eps_rad(&c)
                    )),
                };
            }
            Command::Set(which, value) => {
                let mut settings = device.active_settings();
                let (a, b) = (
                    settings.coefficients.a_rad_per_s(),
                    settings.coefficients.b_rad_per_s(),
                );
                let (a, b) = match which {
                    Coefficient::A => (value, b),
                    Coefficient::B => (a, value),
                };
                settings.coefficients =
                    Coefficients::from_rad_per_s(a, b).map_err(|_| ErrorCode::OutOfRange)?;
                device.stage_settings(settings);
                self.source = Source::Unsaved;
                self.fit = None;
                match which {
                    Coefficient::A => {
                        r.field(format_args!("a={}", settings.coefficients.a_rad_per_s()))
                    }
                    Coefficient::B => {
                        r.field(format_args!("b={}", settings.coefficients.b_rad_per_s()))
                    }
                };
            }
            Command::Compensation(on) => {
                let mut settings = device.active_settings();
                settings.enabled = on;
                device.stage_settings(settings);
                self.source = Source::Unsaved;
                r.field(format_args!("comp={}", if on { "on" } else { "off" }));
            }
            Command::Tracking(on) => {
                self.tracking = on.then(|| {
                    TrackingLoop::new(&self.tracking_config, device.active_settings().coefficients)
                });
                if on {
                    r.field(format_args!(
                        "track=on memory_cycles={}",
                        self.tracking_config.tracking.memory_cycles
                    ));
                } else {
                    r.field(format_args!("track=off"));
                }
            }
            Command::CalStart {
                cycles,
                warmup_cycles,
            } => {
                self.session
                    .start_run(warmup_cycles, cycles)
                    .map_err(session_error)?;
                r.field(format_args!(
                    "cal=running cycles={cycles} warmup={warmup_cycles}"
                ));
            }
            Command::CalStatus => cal_status(self.session.state(), self.session.cycles(), &mut r),
            Command::CalAbort => {
                self.session.abort();
                r.field(format_args!("cal=idle"));
            }
            Command::CalResult => {
                let state = match self.session.state() {
                    SessionState::RunDone => self.session.finish().map_err(session_error)?,
                    s => s,
                };
                match state {
                    SessionState::Ready(fit) => fit_fields(&fit, id, &mut r),
                    SessionState::Refused(reason) => {
                        // An error answer with the reason attached (cal result is not protected,
                        // so returning it as Ok does not extend an unlock).
                        let mut e = Response::err(ErrorCode::FitRefused);
                        e.field(format_args!("reason={} {}", reason.code(), reason.text()));
                        return Ok(e);
                    }
                    SessionState::Running { .. } => return Err(ErrorCode::Busy),
                    _ => return Err(ErrorCode::WrongState),
                }
            }
            Command::CalAccept => {
                let (settings, fit) = self.session.accept().map_err(session_error)?;
                device.stage_settings(settings);
                self.source = Source::Unsaved;
                self.fit = Some(FitSummary::from_fit(&fit));
                r.field(format_args!(
                    "a={} b={} comp=on",
                    settings.coefficients.a_rad_per_s(),
                    settings.coefficients.b_rad_per_s()
                ));
            }
            Command::Store => {
                let settings = device.active_settings();
                let record = CalibrationRecord {
                    serial_number: id.serial_number,
                    boot_count: self.boot_count,
                    settings,
                    fit: self.fit,
                    reset_to_defaults: false,
                };
                let sequence = device.store(&record).map_err(|_| ErrorCode::FlashError)?;
                self.source = Source::Flash { sequence };
                r.field(format_args!("stored seq={sequence} readout=resynchronised"));
            }
            Command::Reload => {
                let (record, report) = device.load();
                device.stage_settings(record.settings);
                self.source = source_of(&report);
                self.fit = record.fit;
                r.field(format_args!("coeffs={}", SourceText(self.source)));
            }
            Command::Defaults => {
                device.stage_settings(CalibrationRecord::DEFAULTS.settings);
                self.source = Source::Unsaved;
                self.fit = None;
                r.field(format_args!("a=0 b=0 comp=off"));
            }
            Command::Stream(divider) => {
                self.stream_divider = divider;
                self.stream_countdown = 1;
                match divider {
                    Some(n) => r.field(format_args!(
                        "stream=on divider={n} frame_bytes={}",
                        super::stream::MAX_FRAME
                    )),
                    None => r.field(format_args!("stream=off")),
                };
            }
            Command::Unlock(given) => {
                match self.access.unlock(&self.access_config, now, id.key, given) {
                    UnlockOutcome::Unlocked => {
                        r.field(format_args!(
                            "unlocked for_s={}",
                            self.access_config.unlock_timeout_ms / 1000
                        ));
                    }
                    UnlockOutcome::WrongKey => return Err(ErrorCode::WrongKey),
                    UnlockOutcome::RateLimited { wait_ms } => {
                        let mut e = Response::err(ErrorCode::RateLimited);
                        e.field(format_args!("wait_ms={wait_ms}"));
                        return Ok(e);
                    }
                }
            }
            Command::Lock => {
                self.access.lock();
                r.field(format_args!("locked"));
            }
        }
        Ok(r)
    }

    fn status<D: DeviceLink>(&mut self, id: &Identity, device: &D, now: u32, r: &mut Response) {
        let s = device.status();
        let settings = device.active_settings();
        let amplitude_arcsec =
            s.dither_amplitude_rad * id.scale_factor_arcsec / core::f32::consts::TAU;
        r.field(format_args!(
            "signal={} dither_hz={:.3} dither_amp_arcsec={:.2} rate_deg_h={:.4} turnarounds={} cycles={} \
counter_glitches={} phase_glitches={} signal_lost={} missed={} comp={} track={} coeffs={} locked={}",
            if s.signal_ok { "ok" } else { "lost" },
            s.dither_hz,
            amplitude_arcsec,
            s.rate_deg_per_h,
            s.turnarounds,
            s.cycles,
            s.counter_glitches,
            s.phase_glitches,
            s.signal_lost,
            s.missed_turnarounds,
            if settings.enabled { "on" } else { "off" },
            if self.tracking.is_some() { "on" } else { "off" },
            SourceText(self.source),
            if self.access.is_unlocked(now) { "no" } else { "yes" },
        ));
    }
}

/// Commands that change coefficients, compensation or flash.
fn protected(command: &Command) -> bool {
    matches!(
        command,
        Command::Set(..)
            | Command::Compensation(_)
            | Command::Tracking(_)
            | Command::CalAccept
            | Command::Store
            | Command::Reload
            | Command::Defaults
    )
}

fn source_of(report: &LoadReport) -> Source {
    match report.outcome {
        LoadOutcome::Loaded { sequence } => Source::Flash { sequence },
        LoadOutcome::Defaults { reason } => Source::Defaults(reason),
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

fn lock_in_deg_h(c: &Coefficients, id: &Identity) -> f32 {
    let (a, b) = (c.a_rad_per_s(), c.b_rad_per_s());
    libm::hypotf(a, b) * id.scale_factor_arcsec / core::f32::consts::TAU
}

fn eps_rad(c: &Coefficients) -> f32 {
    libm::atan2f(c.b_rad_per_s(), c.a_rad_per_s()) - core::f32::consts::FRAC_PI_4
}

fn cal_status(state: SessionState, cycles: u64, r: &mut Response) {
    match state {
        SessionState::Idle => r.field(format_args!("cal=idle")),
        SessionState::Running {
            warmup_left,
            cycles_left,
        } => r.field(format_args!(
            "cal=running warmup_left={warmup_left} cycles_left={cycles_left} cycles={cycles}"
        )),
        SessionState::RunDone => r.field(format_args!("cal=run_done cycles={cycles}")),
        SessionState::Ready(_) => r.field(format_args!("cal=ready cycles={cycles}")),
        SessionState::Refused(reason) => r.field(format_args!(
            "cal=refused reason={} {}",
            reason.code(),
            reason.text()
        )),
    };
}

fn fit_fields(fit: &FitResult, id: &Identity, r: &mut Response) {
    let to_deg_h = id.scale_factor_arcsec as f64 / core::f64::consts::TAU;
    r.field(format_args!(
        "a={:.4} b={:.4} a_std={:.2e} b_std={:.2e} lock_in_deg_h={:.4} eps_rad={:.5} var_red={:.6} cond={:.3} \
mean_rate_deg_h={:.4} cycles={} runs={}",
        fit.a_rad_per_s,
        fit.b_rad_per_s,
        fit.a_std_rad_per_s,
        fit.b_std_rad_per_s,
        fit.lock_in_rad_per_s * to_deg_h,
        fit.eps_rad,
        fit.variance_reduction,
        fit.condition_number,
        fit.mean_rate_rad_per_s * to_deg_h,
        fit.cycles,
        fit.runs
    ));
}

/// `flash:<seq>`, `defaults:<why>` or `unsaved`.
struct SourceText(Source);

impl core::fmt::Display for SourceText {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self.0 {
            Source::Flash { sequence } => write!(f, "flash:{sequence}"),
            Source::Defaults(DefaultsReason::Erased) => write!(f, "defaults:erased"),
            Source::Defaults(DefaultsReason::NoValidRecord) => {
                write!(f, "defaults:no_valid_record")
            }
            Source::Defaults(DefaultsReason::Reset { sequence }) => {
                write!(f, "defaults:reset:{sequence}")
            }
            Source::Defaults(DefaultsReason::ReadFailed) => write!(f, "defaults:read_failed"),
            Source::Unsaved => write!(f, "unsaved"),
        }
    }
}
