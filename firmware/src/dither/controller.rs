//! The controller: one call per drive tick ([`DitherController::on_tick`]), the commands, the
//! status. It owns the state of every part (window, loops, start-up, supervisor, noise); the
//! parts' settings come in as the immutable [`DitherConfig`].
//!
//! (Over 600 lines, on purpose: the modes of the start-up, the lock and the faults are one
//! state machine over one state, and splitting its transitions across files would hide which
//! mode can follow which. The parts it drives each have their own file.)
//!
//! # One tick
//! Sample k of the pick-off arrives with tick k; the call returns the DAC code of tick k + 1.
//! The sine of that code's phase phi(k + 1) is computed once and serves twice: as the DAC
//! sample and as the regressor of sample k in the half-cycle fit (the fixed offset between the
//! two is [`super::frequency::reference_shift`]). When phi crosses a quarter or three-quarter
//! turn (a peak of the drive; at resonance a zero crossing of the pick-off, the dither's rate
//! peak) the half cycle closes: the fit, the supervisor, the loops, and the new DDS
//! parameters, which take effect with the code returned by that same call.
//!
//! Size (over 600 lines): one state machine whose tick, commands and status read the same fields;
//! its parts (window, loops, start-up, supervisor, noise) already live in files of their own.

use super::amplitude::{AmplitudeLoop, PlantGainProbe};
use super::config::DitherConfig;
use super::dds::{cos_sin_q31, Drive};
use super::estimate::DitherEstimate;
use super::frequency::{phase_in, reference_shift, FrequencyLoop};
use super::measure::{HalfCycle, Window, MAX_WINDOW};
use super::noise::{NoiseDither, MAX_DEPTH_PERCENT};
use super::self_test::{PickoffCheck, PickoffFailure};
use super::startup::{Ring, RingListener};
use super::supervisor::{Backoff, DitherState, FaultCounters, FaultKind, Run};
use crate::sample::AdcCode;
use crate::storage::DitherSetpoints;
use crate::units::Phase;

/// What one tick produced.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Tick {
    /// The DAC code for the next tick.
    pub dac_code: u16,
    /// The DDS parameters changed: `dac_code` is the first sample of a new
    /// [`DitherController::drive`].
    pub drive_changed: bool,
    /// A half cycle closed at this tick: a new [`DitherController::estimate`].
    pub half_cycle: bool,
}

/// Where the start-up is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum StartPhase {
    /// Drive off, timing a ring if there is one.
    Listen,
    /// Sweeping the search range for the resonance.
    Sweep,
    /// At the ring's frequency, ringing up to the setpoint.
    RingUp,
    /// The power-up self-test's low-drive sweep (`super::self_test`).
    SelfTest,
}

/// A command refused (it changed nothing).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum CommandError {
    /// Not a finite number.
    NotFinite,
    /// Outside the settable range.
    OutOfRange,
    /// The drive is inhibited (a failed self-test, a lost clock): it cannot be switched on.
    Inhibited,
}

/// The controller's status (units at the edge: converted here, not in the tick).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DitherStatus {
    /// The state.
    pub state: DitherState,
    /// Where the start-up is (while `Starting`).
    pub start_phase: Option<StartPhase>,
    /// The last half cycle's amplitude, arcsec.
    pub amplitude_arcsec: f32,
    /// The setpoint, arcsec.
    pub setpoint_arcsec: f32,
    /// The drive frequency, Hz.
    pub frequency_hz: f32,
    /// The drive amplitude in force, fraction of full scale (1 = the DAC's half range).
    pub drive_level: f32,
    /// The last phase error, rad (positive: drive below resonance).
    pub phase_error_rad: f32,
    /// The plant gain in use (pick-off codes per second per drive code; 0 before measured).
    pub plant_gain_per_s: f32,
    /// The pick-off's offset from its nominal mid-code, codes (the fit's).
    pub pickoff_offset_codes: f32,
    /// Faults so far, per kind.
    pub faults: FaultCounters,
    /// Faults in a row (the back-off's exponent).
    pub faults_in_a_row: u32,
    /// The back-off of the current fault, or the one the next fault would get, s.
    pub retry_backoff_s: f32,
    /// Time to the retry (in a fault), s.
    pub retry_in_s: Option<f32>,
    /// The noise dither's depth, percent.
    pub noise_depth_percent: f32,
    /// The power-up check that the pick-off answers the drive ([`PickoffCheck`]).
    pub pickoff_check: PickoffCheck,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Request {
    Enable,
    Disable,
    Restart,
    SelfTest,
    Inhibit,
}

#[derive(Clone, Copy, Debug)]
enum Mode {
    Off,
    Listen {
        listener: RingListener,
        /// Resume a sweep in this direction (up) when nothing rings.
        resume_up: Option<bool>,
    },
    Sweep {
        up: bool,
    },
    /// The power-up self-test: a sweep at a low drive ([`super::self_test`]).
    SelfTest {
        up: bool,
    },
    Probe {
        probe: PlantGainProbe,
        since: u32,
    },
    Acquire {
        since: u32,
    },
    Locked {
        since: u32,
    },
    Fault {
        kind: FaultKind,
        retry_at: u32,
        wait: u32,
    },
}

/// The dither drive controller's state (sans-IO: ticks in, DAC codes out).
#[derive(Clone, Debug)]
pub struct DitherController {
    tick: u32,
    drive: Drive,
    prev_phase: Phase,
    next_phase: Phase,
    window: Window,
    mode: Mode,
    request: Option<Request>,
    /// The drive is wanted on (enabled, or asked to be): what `store` saves, whatever the
    /// state (a fault, the self-test, an inhibit).
    wanted_on: bool,
    /// Held off for good (until a reset): enable requests are refused.
    inhibited: bool,
    /// The power-up self-test's outcome.
    pickoff_check: PickoffCheck,
    /// Half cycles in a row whose pick-off was flat during the self-test.
    flat: Run,
    /// A fault found outside the tick (the fringe count's amplitude), taken at the next tick.
    pending_fault: Option<FaultKind>,
    setpoint_arcsec: f32,
    setpoint_changed: bool,
    amplitude: AmplitudeLoop,
    frequency: FrequencyLoop,
    noise: NoiseDither,
    faults: FaultCounters,
    backoff: Backoff,
    estimate: DitherEstimate,
    last: HalfCycle,
    phase_error: Phase,
    offset_codes: f32,
    saturated_since: Option<u32>,
    saturated: Run,
    out_of_range: Run,
    in_lock: Run,
    /// The window under way lost samples to a coast ([`Self::coast`]): it is closed without
    /// an update.
    discard_window: bool,
}

impl DitherController {
    /// A controller in `Off` at tick 0 (drive off, the default setpoint, noise off, seed 1).
    pub fn new(config: &DitherConfig) -> Self {
        Self {
            tick: 0,
            drive: Drive::off(0, config.dac_mid_code, config.dac_full_scale),
            prev_phase: Phase::ZERO,
            next_phase: Phase::ZERO,
            window: Window::new(),
            mode: Mode::Off,
            request: None,
            wanted_on: false,
            inhibited: false,
            pickoff_check: PickoffCheck::NotRun,
            flat: Run::default(),
            pending_fault: None,
            setpoint_arcsec: config.default_setpoint_arcsec,
            setpoint_changed: false,
            amplitude: AmplitudeLoop::default(),
            frequency: FrequencyLoop::default(),
            noise: NoiseDither::new(1),
            faults: FaultCounters::default(),
            backoff: Backoff::default(),
            estimate: DitherEstimate::default(),
            last: HalfCycle::default(),
            phase_error: Phase::ZERO,
            offset_codes: 0.0,
            saturated_since: None,
            saturated: Run::default(),
            out_of_range: Run::default(),
            in_lock: Run::default(),
            discard_window: false,
        }
    }

    // ---- commands (take effect at the next tick or half cycle) ----

    /// Starts the dither (from `Off`; the start-up begins at the next tick; during the
    /// self-test, once it has passed). Does nothing while inhibited.
    pub fn enable(&mut self) {
        if !self.inhibited {
            self.wanted_on = true;
            self.request = Some(Request::Enable);
        }
    }

    /// Stops the dither: drive off at the next tick, state `Off` (a self-test under way is
    /// abandoned: its outcome stays "not run").
    pub fn disable(&mut self) {
        self.wanted_on = false;
        self.request = Some(Request::Disable);
    }

    /// Runs the power-up self-test from `Off` (at the next tick): a sweep of the search range
    /// at a low drive that must make the pick-off ring (`dither::self_test`). Passed, the
    /// drive starts if it is wanted on ([`Self::enable`], before or during the test); failed,
    /// the drive is inhibited. Does nothing unless `Off` and not inhibited.
    pub fn start_self_test(&mut self) {
        if !self.inhibited && matches!(self.mode, Mode::Off) {
            self.pickoff_check = PickoffCheck::Running;
            self.request = Some(Request::SelfTest);
        }
    }

    /// Holds the drive off until a reset (the board's power-up checks or its clock failed):
    /// drive off at the next tick, state `Inhibited`, enable refused. What is wanted
    /// ([`Self::setpoints`]) stays as it was, so a `store` does not save the inhibit.
    pub fn inhibit(&mut self) {
        self.inhibited = true;
        self.request = Some(Request::Inhibit);
    }

    /// The fringe count's dither amplitude (the readout's, per cycle: independent of the
    /// pick-off), arcsec: above the mechanical limit (the pick-off's, [`super::FaultLimits::
    /// max_amplitude_codes`]) the drive goes off with `AmplitudeOutOfRange` at the next tick,
    /// whatever the pick-off reads (a pick-off reading low would otherwise let the loop drive
    /// the dither past its range: the drive can give about 4x the default setpoint).
    pub fn check_count_amplitude(&mut self, config: &DitherConfig, count_amplitude_arcsec: f32) {
        let limit = config.codes_to_arcsec(config.faults.max_amplitude_codes);
        let driven = matches!(
            self.mode,
            Mode::Probe { .. } | Mode::Acquire { .. } | Mode::Locked { .. }
        );
        if driven && count_amplitude_arcsec > limit {
            self.pending_fault = Some(FaultKind::AmplitudeOutOfRange);
        }
    }

    /// Starts again from listening (drive off at the next tick; not a fault): for a drive whose
    /// ticks were interrupted without coasting (a flash stall the drive tick coasts through is
    /// [`Self::coast`] instead). Does nothing while `Off` or in a fault;
    /// the self-test's sweep starts over. A request not yet taken (an enable, the self-test)
    /// stays: it starts afresh anyway.
    pub fn restart(&mut self) {
        if self.request.is_none() {
            self.request = Some(Request::Restart);
        }
    }

    /// The drive ran on unseen for `ticks` ticks: the board's drive tick went on writing the
    /// DAC codes of [`Self::drive`] (its RAM-resident part, while a flash operation stalled
    /// every fetch from flash: `crate::board::ram`) without the controller, which saw none of
    /// those ticks' pick-off samples. Its time and the DDS phase advance by `ticks` (so the next
    /// tick's code continues the drive that was output), the state stays (a locked drive stays
    /// locked: it ran on the drive its loops had set), and the half cycle the gap fell into,
    /// measured only in part, is closed without a loop update. The start-up's listener, which
    /// times a ring from consecutive samples, starts listening again.
    pub fn coast(&mut self, config: &DitherConfig, ticks: u32) {
        if ticks == 0 {
            return;
        }
        let advance = Phase::from_bits(ticks.wrapping_mul(self.drive.step.to_bits()));
        self.tick = self.tick.wrapping_add(ticks);
        self.prev_phase = self.prev_phase + advance;
        self.next_phase = self.next_phase + advance;
        match self.mode {
            Mode::Off | Mode::Fault { .. } => {}
            Mode::Listen { resume_up, .. } => {
                // The drive is off while listening: `listen` keeps it as it is.
                self.listen(config, self.tick.wrapping_sub(1), resume_up);
            }
            Mode::Sweep { .. }
            | Mode::SelfTest { .. }
            | Mode::Probe { .. }
            | Mode::Acquire { .. }
            | Mode::Locked { .. } => {
                self.window = Window::new();
                self.discard_window = true;
            }
        }
    }

    /// Sets the amplitude setpoint, arcsec (within `config.setpoint_range_arcsec`; an error
    /// changes nothing). A locked controller goes back to `Starting` until it is at the new
    /// setpoint.
    pub fn set_setpoint_arcsec(
        &mut self,
        config: &DitherConfig,
        arcsec: f32,
    ) -> Result<(), CommandError> {
        let (lo, hi) = config.setpoint_range_arcsec;
        check_range(arcsec, lo, hi)?;
        self.setpoint_arcsec = arcsec;
        self.setpoint_changed = true;
        Ok(())
    }

    /// Sets the random-noise dither's depth, percent of the drive amplitude (0 = off, at most
    /// [`MAX_DEPTH_PERCENT`]; an error changes nothing). Applied from the next half cycle while
    /// locked.
    pub fn set_noise_depth_percent(&mut self, percent: f32) -> Result<(), CommandError> {
        check_range(percent, 0.0, MAX_DEPTH_PERCENT)?;
        self.noise
            .set_depth_q16(crate::math::round_f32_to_i32(percent * 655.36) as u32);
        Ok(())
    }

    /// Restarts the noise sequence from `seed` (0 counts as 1).
    pub fn set_noise_seed(&mut self, seed: u32) {
        self.noise.reseed(seed);
    }

    /// Applies stored or commanded setpoints whole: the amplitude and the noise depth are
    /// range-checked first, so an error changes nothing; the drive is enabled or disabled only
    /// if that differs from [`Self::enabled`] (a running start-up is not restarted). Setpoints
    /// with the drive on are refused while it is inhibited ([`CommandError::Inhibited`]): the
    /// answer must not say `dither=on` for a drive that stays off.
    pub fn apply_setpoints(
        &mut self,
        config: &DitherConfig,
        setpoints: DitherSetpoints,
    ) -> Result<(), CommandError> {
        let (lo, hi) = config.setpoint_range_arcsec;
        check_range(setpoints.amplitude_arcsec, lo, hi)?;
        check_range(setpoints.noise_percent, 0.0, MAX_DEPTH_PERCENT)?;
        if self.inhibited && setpoints.enabled {
            return Err(CommandError::Inhibited);
        }
        if setpoints.amplitude_arcsec != self.setpoint_arcsec {
            self.set_setpoint_arcsec(config, setpoints.amplitude_arcsec)?;
        }
        self.set_noise_depth_percent(setpoints.noise_percent)?;
        match (setpoints.enabled, self.enabled()) {
            (true, false) => self.enable(),
            (false, true) => self.disable(),
            _ => {}
        }
        Ok(())
    }

    /// The setpoints stored in flash, at power-up (`None`: none stored, the defaults with the
    /// drive wanted on). A record the drive refuses (another firmware's wider range) leaves
    /// the default setpoints but keeps its `enabled`: a drive stored off stays off. Returns
    /// whether the record was applied whole.
    pub fn apply_stored(&mut self, config: &DitherConfig, stored: Option<DitherSetpoints>) -> bool {
        match stored {
            None => {
                self.enable();
                false
            }
            Some(setpoints) => match self.apply_setpoints(config, setpoints) {
                Ok(()) => true,
                Err(_) => {
                    if setpoints.enabled {
                        self.enable();
                    }
                    false
                }
            },
        }
    }

    // ---- queries ----

    /// Whether the drive is wanted on (a fault with its retry pending counts as on, and so
    /// do the self-test and an inhibit when it was wanted on before; a request not yet taken
    /// by a tick counts as given).
    pub fn enabled(&self) -> bool {
        self.wanted_on
    }

    /// Held off until a reset ([`Self::inhibit`], or a failed pick-off check).
    pub fn inhibited(&self) -> bool {
        self.inhibited
    }

    /// The power-up self-test's outcome.
    pub fn pickoff_check(&self) -> PickoffCheck {
        self.pickoff_check
    }

    /// The setpoints in force, as a `store` saves them.
    pub fn setpoints(&self) -> DitherSetpoints {
        DitherSetpoints {
            enabled: self.enabled(),
            amplitude_arcsec: self.setpoint_arcsec,
            noise_percent: self.noise.depth_q16() as f32 / 655.36,
        }
    }

    /// The DDS parameters in force: an exact description of every DAC sample from
    /// `drive().start_tick` until the next change.
    pub fn drive(&self) -> Drive {
        self.drive
    }

    /// The latest half cycle's estimate of the dither (valid only while locked).
    pub fn estimate(&self) -> DitherEstimate {
        self.estimate
    }

    /// The last closed half cycle (extremes, rails, fit).
    pub fn last_half_cycle(&self) -> HalfCycle {
        self.last
    }

    /// The tick index the next `on_tick` call's pick-off sample belongs to.
    pub fn tick(&self) -> u32 {
        self.tick
    }

    /// The state.
    pub fn state(&self) -> DitherState {
        match self.mode {
            // Asked to start, the first tick not yet run.
            _ if self.inhibited => DitherState::Inhibited,
            Mode::Off if matches!(self.request, Some(Request::Enable | Request::SelfTest)) => {
                DitherState::Starting
            }
            Mode::Off => DitherState::Off,
            Mode::Locked { .. } => DitherState::Locked,
            Mode::Fault { kind, .. } => DitherState::Fault(kind),
            _ => DitherState::Starting,
        }
    }

    /// The status, in physical units.
    pub fn status(&self, config: &DitherConfig) -> DitherStatus {
        let secs = |ticks: u32| ticks as f32 / config.tick_hz;
        let (retry_backoff_s, retry_in_s) = match self.mode {
            Mode::Fault { retry_at, wait, .. } => (
                secs(wait),
                Some(secs(retry_at.wrapping_sub(self.tick).min(wait))),
            ),
            _ => (secs(self.backoff.next_wait(&config.faults)), None),
        };
        let start_phase = match self.mode {
            Mode::Listen { .. } => Some(StartPhase::Listen),
            Mode::Sweep { .. } => Some(StartPhase::Sweep),
            Mode::SelfTest { .. } => Some(StartPhase::SelfTest),
            Mode::Probe { .. } | Mode::Acquire { .. } => Some(StartPhase::RingUp),
            _ => None,
        };
        let half_range = (config.dac_full_scale as f32 + 1.0) / 2.0;
        DitherStatus {
            state: self.state(),
            start_phase,
            amplitude_arcsec: config.codes_to_arcsec(self.amplitude_codes()),
            setpoint_arcsec: self.setpoint_arcsec,
            frequency_hz: step_hz(self.drive.step, config.tick_hz),
            drive_level: self.drive.amplitude_codes() as f32 / half_range,
            phase_error_rad: turns_to_rad(self.phase_error),
            plant_gain_per_s: self.amplitude.plant_gain_per_s(),
            pickoff_offset_codes: self.offset_codes,
            faults: self.faults,
            faults_in_a_row: self.backoff.in_a_row,
            retry_backoff_s,
            retry_in_s,
            noise_depth_percent: self.noise.depth_q16() as f32 / 655.36,
            pickoff_check: self.pickoff_check,
        }
    }

    // ---- the tick ----

    /// One drive tick: `pickoff_code` is the pick-off ADC code sampled at this tick; returns the
    /// DAC code for the next tick, and whether the DDS parameters changed with it.
    pub fn on_tick(&mut self, config: &DitherConfig, pickoff_code: AdcCode) -> Tick {
        let k = self.tick;
        self.tick = k.wrapping_add(1);
        let mut changed = false;
        if let Some(request) = self.request.take() {
            changed = self.apply_request(config, request, k);
        }
        if let Some(kind) = self.pending_fault.take() {
            if matches!(
                self.mode,
                Mode::Probe { .. } | Mode::Acquire { .. } | Mode::Locked { .. }
            ) {
                changed |= self.fault(config, kind, k);
            }
        }
        match &self.mode {
            Mode::Off => return self.idle(changed),
            &Mode::Fault { retry_at, .. } => {
                if (k.wrapping_sub(retry_at) as i32) < 0 {
                    return self.idle(changed);
                }
                self.listen(config, k, None);
                changed = true;
            }
            _ => {}
        }
        let theta = self.next_phase;
        let (cos, sin) = cos_sin_q31(theta);
        let x = pickoff_code - config.pickoff_mid_code;
        self.window.push(
            pickoff_code.to_bits(),
            x,
            cos >> 16,
            sin >> 16,
            config.faults.rail_code,
        );
        let mut half_cycle = false;
        if let Mode::Listen { listener, .. } = &mut self.mode {
            if let Some(ring) = listener.push(k, x, config.startup.ring_half_periods) {
                changed |= self.on_ring(config, k, ring);
            }
        }
        let quarter = Phase::QUARTER_TURN;
        let crossed = ((self.prev_phase + quarter).to_bits() ^ (theta + quarter).to_bits()) >> 31;
        if self.next_phase == theta && (crossed != 0 || self.window.len() >= MAX_WINDOW) {
            if self.discard_window {
                // Part of this half cycle was coasted through, unseen (`coast`).
                self.window = Window::new();
                self.discard_window = false;
            } else {
                changed |= self.update(config, k, theta);
                half_cycle = true;
            }
        }
        let sin = if self.next_phase == theta {
            sin
        } else {
            cos_sin_q31(self.next_phase).1
        };
        if changed {
            self.drive.start_tick = self.tick;
            self.drive.phase = self.next_phase;
        }
        let dac_code = self.drive.code_from_sin(sin);
        self.prev_phase = self.next_phase;
        self.next_phase = self.next_phase + self.drive.step;
        Tick {
            dac_code,
            drive_changed: changed,
            half_cycle,
        }
    }

    fn idle(&mut self, changed: bool) -> Tick {
        if changed {
            self.drive.start_tick = self.tick;
        }
        Tick {
            dac_code: self.drive.mid_code,
            drive_changed: changed,
            half_cycle: false,
        }
    }

    fn apply_request(&mut self, config: &DitherConfig, request: Request, k: u32) -> bool {
        match (request, self.mode) {
            (Request::Inhibit, _) => {
                self.mode = Mode::Off;
                if self.pickoff_check == PickoffCheck::Running {
                    self.pickoff_check = PickoffCheck::NotRun;
                }
                self.set_drive(0, Phase::ZERO)
            }
            (_, _) if self.inhibited => false,
            (Request::Disable, Mode::Off) => false,
            (Request::Disable, _) => {
                self.mode = Mode::Off;
                if self.pickoff_check == PickoffCheck::Running {
                    self.pickoff_check = PickoffCheck::NotRun;
                }
                self.set_drive(0, Phase::ZERO)
            }
            (Request::Enable, Mode::Off) => {
                self.listen(config, k, None);
                true
            }
            (Request::SelfTest, Mode::Off) | (Request::Restart, Mode::SelfTest { .. }) => {
                self.window = Window::new();
                self.flat.clear();
                self.mode = Mode::SelfTest { up: true };
                self.set_drive(
                    config.startup.self_test_drive_q16 as i32,
                    config.startup.search_steps.0,
                );
                true
            }
            (Request::Restart, Mode::Off | Mode::Fault { .. })
            | (Request::Enable | Request::SelfTest, _) => false,
            (Request::Restart, _) => {
                self.listen(config, k, None);
                true
            }
        }
    }

    /// Drive off, the DDS running at the last (or lowest) frequency for the windows, timing a
    /// ring from the next sample.
    fn listen(&mut self, config: &DitherConfig, k: u32, resume_up: Option<bool>) {
        let step = if self.drive.step == Phase::ZERO {
            config.startup.search_steps.0
        } else {
            self.drive.step
        };
        self.set_drive(0, step);
        let hysteresis = (config.startup.ring_threshold_codes / 2) as i32;
        let center = crate::math::round_f32_to_i32(self.offset_codes);
        self.mode = Mode::Listen {
            listener: RingListener::new(k.wrapping_add(1), center, hysteresis),
            resume_up,
        };
        self.window = Window::new();
        self.discard_window = false;
    }

    /// A ring was timed: start the ring-up at its frequency, 90 degrees ahead of it.
    fn on_ring(&mut self, config: &DitherConfig, k: u32, ring: Ring) -> bool {
        let step = ring.step();
        let (lo, hi) = config.startup.search_steps;
        let Mode::Listen {
            listener,
            resume_up,
        } = self.mode
        else {
            return false;
        };
        if step.to_bits() < lo.to_bits() || step.to_bits() > hi.to_bits() {
            // Not a ring of this resonator: listen again.
            self.listen(config, k, resume_up);
            return false;
        }
        // The drive's phase at the last crossing is a quarter turn ahead of the pick-off's
        // (rising: 1/4, falling: 3/4); advanced to this sample, then to the regressor phase.
        let at_crossing = if ring.rising {
            Phase::QUARTER_TURN
        } else {
            Phase::QUARTER_TURN + Phase::HALF_TURN
        };
        let since = listener.elapsed(k) as f32 - ring.last_crossing;
        let advance = crate::math::round_to_i64(step.to_bits() as f64 * since as f64) as u32;
        let shift = reference_shift(step, config.sample_delay_q16);
        self.next_phase = at_crossing + Phase::from_bits(advance) + shift;
        self.prev_phase = self.next_phase;
        self.window = Window::new();
        self.frequency.start(step);
        self.saturated_since = Some(k);
        self.mode = Mode::Probe {
            probe: PlantGainProbe::default(),
            since: k,
        };
        self.set_drive(config.amplitude.drive_limit_q16 as i32, step);
        true
    }

    /// Sets the DDS amplitude and step; true if they changed.
    fn set_drive(&mut self, amplitude_q16: i32, step: Phase) -> bool {
        let amplitude_q16 = amplitude_q16.max(0) as u32;
        let changed = amplitude_q16 != self.drive.amplitude_q16 || step != self.drive.step;
        self.drive.amplitude_q16 = amplitude_q16;
        self.drive.step = step;
        changed
    }

    fn amplitude_codes(&self) -> f32 {
        self.last.fit.map_or(0.0, |f| f.amplitude_codes)
    }

    // ---- the half cycle ----

    /// Closes the window at sample `k` (regressor phase `theta`) and runs everything that runs
    /// once per half cycle; true if the drive changed.
    fn update(&mut self, config: &DitherConfig, k: u32, theta: Phase) -> bool {
        let h = self.window.close();
        self.window = Window::new();
        self.last = h;
        let step = self.drive.step;
        if let Some(fit) = h.fit {
            self.offset_codes = fit.offset_codes;
            let shift = reference_shift(step, config.sample_delay_q16);
            // At resonance the pick-off lags the DAC by a quarter turn plus the amplifier's lag.
            self.phase_error = fit.phase + shift + config.drive_lag(step) - Phase::HALF_TURN;
            self.estimate = DitherEstimate {
                tick: k,
                amplitude_arcsec: config.codes_to_arcsec(fit.amplitude_codes),
                frequency_hz: step_hz(step, config.tick_hz),
                angle_phase: theta + fit.phase - phase_in(step, config.sample_delay_q16),
                valid: false,
            };
        }
        if let Mode::SelfTest { up } = self.mode {
            return self.self_test_half_cycle(config, k, &h, up);
        }
        if let Some(kind) = self.check(config, &h, k) {
            return self.fault(config, kind, k);
        }
        let amplitude = self.amplitude_codes();
        let setpoint = config.arcsec_to_codes(self.setpoint_arcsec);
        let (drive, step) = match self.mode {
            Mode::Listen {
                listener,
                resume_up,
            } => {
                if listener.elapsed(k) <= config.startup.listen_timeout_ticks {
                    return false;
                }
                let up = resume_up.unwrap_or(true);
                let start = if resume_up.is_some() {
                    step
                } else {
                    config.startup.search_steps.0
                };
                self.mode = Mode::Sweep { up };
                (config.amplitude.drive_limit_q16 as i32, start)
            }
            Mode::Sweep { up } => return self.sweep(config, k, &h, up),
            Mode::Probe { mut probe, since } => {
                let limit = config.amplitude.drive_limit_codes();
                let gain = probe.push(&config.amplitude, k, amplitude, limit, config.tick_hz);
                self.mode = Mode::Probe { probe, since };
                if let Some(gain) = gain {
                    if gain.is_nan() || gain < config.amplitude.min_plant_gain_per_s {
                        return self.fault(config, FaultKind::NoOscillation, k);
                    }
                    self.amplitude
                        .start(config.amplitude.drive_limit_q16 as i32, gain);
                    self.mode = Mode::Acquire { since };
                    self.in_lock.clear();
                }
                let step = self.frequency.update(&config.frequency, self.phase_error);
                (config.amplitude.drive_limit_q16 as i32, step)
            }
            Mode::Acquire { since } => {
                let drive = self
                    .amplitude
                    .update(&config.amplitude, setpoint, amplitude);
                let step = self.frequency.update(&config.frequency, self.phase_error);
                let near = (amplitude - setpoint).abs() <= config.startup.lock_tolerance * setpoint
                    && self.phase_error.to_signed().unsigned_abs()
                        <= config.startup.lock_phase_error.to_bits();
                if self.in_lock.exceeds(near, config.startup.lock_half_cycles) {
                    self.mode = Mode::Locked { since: k };
                    self.amplitude
                        .retune(&config.amplitude, &config.amplitude_locked);
                    self.saturated.clear();
                    self.out_of_range.clear();
                } else if k.wrapping_sub(since) > config.faults.acquire_timeout_ticks {
                    return self.fault(config, FaultKind::AmplitudeOutOfRange, k);
                }
                (drive, step)
            }
            Mode::Locked { since } => {
                let loop_config = if self.setpoint_changed {
                    self.mode = Mode::Acquire { since: k };
                    self.in_lock.clear();
                    self.amplitude
                        .retune(&config.amplitude_locked, &config.amplitude);
                    &config.amplitude
                } else {
                    if k.wrapping_sub(since) >= config.faults.stable_ticks {
                        self.backoff.on_stable();
                    }
                    &config.amplitude_locked
                };
                let drive = self.amplitude.update(loop_config, setpoint, amplitude);
                let step = self.frequency.update(&config.frequency, self.phase_error);
                let drive = if matches!(self.mode, Mode::Locked { .. }) {
                    self.noise.apply(drive)
                } else {
                    drive
                };
                (drive, step)
            }
            Mode::Off | Mode::Fault { .. } | Mode::SelfTest { .. } => return false,
        };
        self.setpoint_changed = false;
        self.estimate.valid = matches!(self.mode, Mode::Locked { .. });
        let limit = config.amplitude.drive_limit_q16 as i32;
        self.set_drive(drive.clamp(0, limit), step)
    }

    /// One half cycle of the sweep: a ring stops it; the step moves by the sweep rate over the
    /// window; up to the top of the range, then down; at the bottom again: no resonance.
    fn sweep(&mut self, config: &DitherConfig, k: u32, h: &HalfCycle, up: bool) -> bool {
        if u32::from(h.range_codes()) > 2 * u32::from(config.startup.ring_threshold_codes) {
            self.listen(config, k, Some(up));
            return true;
        }
        let (lo, hi) = config.startup.search_steps;
        let delta = config.startup.sweep_step_per_tick.saturating_mul(h.samples);
        let step = self.drive.step.to_bits();
        let next = if up {
            step.saturating_add(delta)
        } else {
            step.saturating_sub(delta)
        };
        let (up, next) = match (up, next > hi.to_bits(), next < lo.to_bits()) {
            (true, true, _) => (false, hi.to_bits()),
            (false, _, true) => return self.fault(config, FaultKind::NoOscillation, k),
            _ => (up, next),
        };
        self.mode = Mode::Sweep { up };
        self.set_drive(
            config.amplitude.drive_limit_q16 as i32,
            Phase::from_bits(next),
        )
    }

    /// One half cycle of the self-test's sweep ([`super::self_test`]): a ring passes it (the
    /// start-up follows if the drive is wanted on: it hears the ring at once); rails, a flat
    /// pick-off, or the whole range swept up and down without a ring fail it and inhibit the
    /// drive.
    fn self_test_half_cycle(
        &mut self,
        config: &DitherConfig,
        k: u32,
        h: &HalfCycle,
        up: bool,
    ) -> bool {
        let failure = if h.rail_samples >= config.faults.rail_samples {
            Some(PickoffFailure::Rail)
        } else if self.flat.exceeds(
            h.range_codes() <= config.faults.flat_codes,
            super::self_test::FLAT_HALF_CYCLES,
        ) {
            Some(PickoffFailure::Flat)
        } else {
            None
        };
        if let Some(failure) = failure {
            self.pickoff_check = PickoffCheck::Fail(failure);
            self.inhibited = true;
            self.mode = Mode::Off;
            return self.set_drive(0, Phase::ZERO);
        }
        if u32::from(h.range_codes()) > 2 * u32::from(config.startup.ring_threshold_codes) {
            self.pickoff_check = PickoffCheck::Pass;
            if self.wanted_on {
                self.listen(config, k, None);
                return true;
            }
            self.mode = Mode::Off;
            return self.set_drive(0, Phase::ZERO);
        }
        let (lo, hi) = config.startup.search_steps;
        let delta = config.startup.sweep_step_per_tick.saturating_mul(h.samples);
        let step = self.drive.step.to_bits();
        let next = if up {
            step.saturating_add(delta)
        } else {
            step.saturating_sub(delta)
        };
        let (up, next) = match (up, next > hi.to_bits(), next < lo.to_bits()) {
            (true, true, _) => (false, hi.to_bits()),
            (false, _, true) => {
                self.pickoff_check = PickoffCheck::Fail(PickoffFailure::NoResponse);
                self.inhibited = true;
                self.mode = Mode::Off;
                return self.set_drive(0, Phase::ZERO);
            }
            _ => (up, next),
        };
        self.mode = Mode::SelfTest { up };
        self.set_drive(
            config.startup.self_test_drive_q16 as i32,
            Phase::from_bits(next),
        )
    }

    /// The supervisor's checks on a closed half cycle (module docs of `supervisor`).
    fn check(&mut self, config: &DitherConfig, h: &HalfCycle, k: u32) -> Option<FaultKind> {
        let limits = &config.faults;
        let amplitude = self.amplitude_codes();
        if h.rail_samples >= limits.rail_samples {
            return Some(FaultKind::PickoffSaturated);
        }
        if amplitude > limits.max_amplitude_codes {
            return Some(FaultKind::AmplitudeOutOfRange);
        }
        let ringing = matches!(
            self.mode,
            Mode::Probe { .. } | Mode::Acquire { .. } | Mode::Locked { .. }
        );
        if !ringing {
            return None;
        }
        if h.range_codes() <= limits.flat_codes {
            return Some(FaultKind::PickoffLost);
        }
        if amplitude.is_nan() || amplitude < limits.lost_amplitude_codes {
            return Some(FaultKind::NoOscillation);
        }
        let at_limit = match self.mode {
            Mode::Probe { .. } => true,
            _ => self.amplitude.at_limit(&config.amplitude),
        };
        if let Mode::Locked { .. } = self.mode {
            if self
                .saturated
                .exceeds(at_limit, limits.saturated_half_cycles)
            {
                return Some(FaultKind::DriveSaturated);
            }
            let setpoint = config.arcsec_to_codes(self.setpoint_arcsec);
            let off = (amplitude - setpoint).abs() > limits.band * setpoint;
            if self
                .out_of_range
                .exceeds(off, limits.out_of_range_half_cycles.saturating_sub(1))
            {
                return Some(FaultKind::AmplitudeOutOfRange);
            }
            return None;
        }
        match (at_limit, self.saturated_since) {
            (false, _) => self.saturated_since = None,
            (true, None) => self.saturated_since = Some(k),
            (true, Some(since)) if k.wrapping_sub(since) > limits.ramp_saturated_ticks => {
                return Some(FaultKind::DriveSaturated)
            }
            _ => {}
        }
        None
    }

    /// The safe reaction: drive off, state `Fault(kind)`, counted, retry after the back-off.
    fn fault(&mut self, config: &DitherConfig, kind: FaultKind, k: u32) -> bool {
        self.faults.count(kind);
        let wait = self.backoff.on_fault(&config.faults);
        self.mode = Mode::Fault {
            kind,
            retry_at: k.wrapping_add(wait),
            wait,
        };
        self.estimate.valid = false;
        self.saturated.clear();
        self.out_of_range.clear();
        self.saturated_since = None;
        self.set_drive(0, Phase::ZERO)
    }
}

fn check_range(value: f32, lo: f32, hi: f32) -> Result<(), CommandError> {
    if !value.is_finite() {
        return Err(CommandError::NotFinite);
    }
    if value < lo || value > hi {
        return Err(CommandError::OutOfRange);
    }
    Ok(())
}

/// The frequency of DDS step `step` in `f32` (no `f64` in the half-cycle path: the M4F has no
/// double-precision unit).
fn step_hz(step: Phase, tick_hz: f32) -> f32 {
    step.to_bits() as f32 * (tick_hz / crate::units::Q32_PER_TURN_F32)
}

fn turns_to_rad(p: Phase) -> f32 {
    p.to_signed() as f32 * (core::f32::consts::TAU / crate::units::Q32_PER_TURN_F32)
}
