//! The firmware's dither drive in the loop: `firmware::dither::DitherController` ticking on the
//! simulated pick-off, its DDS turned into the driven resonator's drive segments.
//!
//! On the board, TIM4 fires every drive tick (40 kHz, `BoardProfile::drive_tick_hz`): one
//! hardware edge samples the pick-off (ADC3, the sampling instant 0.83 us after the edge:
//! `BoardProfile::aperture_delay_ticks`) and loads the DAC with the code the previous tick's
//! handler wrote; the handler then runs `on_tick` with the new pick-off code and writes the
//! code for the next edge. [`FirmwareDrive::run_until`] does exactly that, tick by tick, on the
//! simulated board: the pick-off code from the board's stream ([`SimBoard::drive_tick_code`]),
//! `on_tick`, and when the controller reports a new DDS ([`firmware::dither::Tick`]'s
//! `drive_changed`) a [`DriveSegment`] from the tick at which its first sample is written.
//!
//! # Why segments, not codes
//! The controller changes its DDS only at its loop updates (about twice per dither cycle), and
//! between two updates its codes are `mid + round(amp sin(phase + n step))` exactly
//! ([`firmware::dither::Drive`]), which the resonator model takes as one segment in closed form
//! (`crate::dither`: the staircase's fundamental; images and the DAC's rounding are bounded
//! there). So the simulator costs one `on_tick` and one pick-off evaluation per tick, and the
//! phase integrator sees about two breakpoints per dither cycle.
//!
//! # Causality
//! The code a tick's handler writes is output at the next edge, so after tick `n` the drive is
//! known up to the edge of tick `n + 2` (tick `n + 1`'s handler can change it from there on at
//! the earliest); the pick-off sample of tick `n` lies before that. The drive never depends on
//! anything later than the pick-off, so a caller may run the drive ahead of the readout by any
//! lead (`crate::gyro::Gyro::drive_lead_s`).
//!
//! # A flash stall
//! On the board the drive tick runs from RAM: while a flash operation stalls every fetch from
//! flash it coasts (`firmware::dither::Coast`: the drive in force continued, the controller
//! not run) and hands the ticks it missed to the controller at its first tick after
//! ([`FirmwareDrive::coast_until`]). The DAC's codes meanwhile are the drive segment already
//! pushed, so a coast pushes nothing; it only counts the ticks.
//!
//! # The lock flag
//! [`FirmwareDrive::locked_at`] tells whether the controller was locked at a given instant (the
//! last tick at or before it): the board's latch copies the drive tick's state into every
//! `TurnaroundSample` (`drive_locked`), and the harness does the same with this.

use crate::board::SimBoard;
use crate::dither::drive::{DacParams, DriveError, DriveSegment};
use firmware::board_timing::selftest::SelfTestReport;
use firmware::dither::{
    Coast, CommandError, DitherConfig, DitherController, DitherState, Drive, Tick,
};
use firmware::profile::BoardProfile;
use firmware::signal::lockin::CycleRecord;
use firmware::storage::DitherSetpoints;
use std::collections::VecDeque;

/// State changes kept for [`FirmwareDrive::locked_at`] (a few seconds of lock changes).
const STATE_HISTORY: usize = 64;

/// The firmware's dither controller driving a simulated board.
#[derive(Clone, Debug)]
pub struct FirmwareDrive {
    config: DitherConfig,
    controller: DitherController,
    dac: DacParams,
    /// The next tick to run (absolute, from t = 0; the controller's tick index is its low 32
    /// bits).
    next_tick: u64,
    /// The drive tick's coast state (the drive in force, the ticks the controller missed).
    coast: Coast,
    /// Ticks before this one coast (a flash operation under way).
    coast_until_tick: u64,
    /// (first tick, locked) at every change of the lock state, oldest first.
    locked_since: VecDeque<(u64, bool)>,
    /// The DAC code the last tick wrote.
    last_code: u16,
    /// Ticks handled since t = 0 (the board's drive-tick count).
    handled: u64,
    /// TIM4 stopped (`BoardFault::StoppedTrigger(DriveTick)`): no tick runs, the DAC holds.
    stopped: bool,
}

impl FirmwareDrive {
    /// The controller of `profile` (its settings, the drive enabled with the default
    /// setpoints) ticking at the DAC's rate; its first tick is at t = 0. The DAC's tick rate
    /// must be the profile's (the controller's phase detector assumes it).
    pub fn new(profile: &BoardProfile, dac: DacParams) -> Result<Self, DriveError> {
        let config = DitherConfig::for_profile(profile);
        if (dac.tick_hz - f64::from(profile.drive_tick_hz)).abs() > 1e-9 * dac.tick_hz {
            return Err(DriveError::Invalid(
                "the resonator's DAC ticks at another rate than the board's drive",
            ));
        }
        let mut controller = DitherController::new(&config);
        controller.enable();
        Ok(Self {
            coast: Coast::new(&controller),
            controller,
            config,
            dac,
            next_tick: 0,
            coast_until_tick: 0,
            locked_since: VecDeque::from([(0, false)]),
            last_code: profile.dac_full_scale / 2 + 1,
            handled: 0,
            stopped: false,
        })
    }

    /// The board's power-up, before the first tick (`board::resources::start_dither`): the
    /// stored setpoints ([`DitherController::apply_stored`]), then, with the board's
    /// clock, timer and trigger checks passed, the pick-off check (the half-drive sweep) and
    /// the start-up if the drive is wanted on; with one failed, the drive inhibited. `None`:
    /// no self-test (the controller as [`Self::new`] left it, but with the stored setpoints).
    pub fn power_up(&mut self, stored: Option<DitherSetpoints>, selftest: Option<&SelfTestReport>) {
        self.controller = DitherController::new(&self.config);
        self.coast = Coast::new(&self.controller);
        self.controller.apply_stored(&self.config, stored);
        match selftest {
            Some(report) if report.hardware_passed() => self.controller.start_self_test(),
            Some(_) => self.controller.inhibit(),
            None => {}
        }
    }

    /// The fringe count's amplitude over `record`'s cycle against the mechanical limit
    /// ([`DitherController::check_count_amplitude`]), as the board's main loop does with
    /// every closed cycle.
    pub fn check_count_amplitude(&mut self, record: &CycleRecord, scale_factor_arcsec: f64) {
        let arcsec = firmware::dither::count_amplitude_arcsec(record, scale_factor_arcsec as f32);
        self.controller.check_count_amplitude(&self.config, arcsec);
    }

    /// Ticks handled since t = 0 (the board counts them for its rate monitor).
    pub fn ticks_handled(&self) -> u64 {
        self.handled
    }

    /// TIM4 stops from the next edge (a fault): no tick runs any more and the DAC holds the
    /// last code written (a constant drive).
    pub fn stop_ticks(&mut self, board: &mut SimBoard) -> Result<(), DriveError> {
        if self.stopped {
            return Ok(());
        }
        self.stopped = true;
        self.hold_code(board, f64::from(self.last_code))
    }

    /// The drive taken off by software (`board::dither::force_mid`: the board's reaction to a
    /// stopped drive tick or a lost clock): mid-scale from the next edge, the controller
    /// inhibited.
    pub fn take_off(&mut self, board: &mut SimBoard) -> Result<(), DriveError> {
        self.controller.inhibit();
        self.last_code = self.config.dac_mid_code;
        self.hold_code(board, f64::from(self.config.dac_mid_code))
    }

    /// A constant DAC code from the next edge on (with the ticks stopped: from where the
    /// drive is known).
    fn hold_code(&mut self, board: &mut SimBoard, code: f64) -> Result<(), DriveError> {
        let start_s = self
            .tick_time_s(self.next_tick)
            .max(board.drive_known_until_s());
        let hold = DriveSegment::from_codes(start_s, 0.0, 0.0, 0.0, code, &self.dac);
        board.extend_drive_until(start_s)?;
        board.push_drive(hold)
    }

    /// The controller (status, setpoints, estimate).
    pub fn controller(&self) -> &DitherController {
        &self.controller
    }

    /// The controller and its settings, for commands between ticks (they take effect at the
    /// next tick, as on the board).
    pub fn controller_mut(&mut self) -> (&mut DitherController, &DitherConfig) {
        (&mut self.controller, &self.config)
    }

    /// Sets the amplitude setpoint (arcsec), the noise dither's depth (percent of the drive
    /// amplitude) and restarts its sequence from `seed`, as the serial commands `dither amp`
    /// and `dither noise` do between ticks. The first refused value names itself in the error
    /// (`"setpoint"` or `"noise depth"`); a refused setpoint changes nothing.
    pub fn set_setpoints(
        &mut self,
        amplitude_arcsec: f32,
        noise_percent: f32,
        seed: u32,
    ) -> Result<(), (&'static str, CommandError)> {
        self.controller
            .set_setpoint_arcsec(&self.config, amplitude_arcsec)
            .map_err(|e| ("setpoint", e))?;
        self.controller
            .set_noise_depth_percent(noise_percent)
            .map_err(|e| ("noise depth", e))?;
        self.controller.set_noise_seed(seed);
        Ok(())
    }

    /// The controller's settings.
    pub fn config(&self) -> &DitherConfig {
        &self.config
    }

    /// The edge time of absolute tick `n`, s.
    pub fn tick_time_s(&self, n: u64) -> f64 {
        n as f64 / self.dac.tick_hz
    }

    /// Time of the next tick to run, s: the drive is known up to the edge after it.
    pub fn next_tick_s(&self) -> f64 {
        self.tick_time_s(self.next_tick)
    }

    /// Runs every tick whose edge is at or before `t_s`; the board's drive is then known up to
    /// the edge after the last tick run (beyond `t_s`).
    pub fn run_until(&mut self, board: &mut SimBoard, t_s: f64) -> Result<(), DriveError> {
        if self.stopped {
            // No tick: the DAC holds; the drive is known as far as asked.
            return board.extend_drive_until(t_s.max(board.drive_known_until_s()));
        }
        while self.tick_time_s(self.next_tick) <= t_s {
            self.tick(board)?;
        }
        Ok(())
    }

    /// One tick: sample the pick-off, run the controller (or coast: [`Self::coast_until`]),
    /// pass a new DDS on as a segment.
    fn tick(&mut self, board: &mut SimBoard) -> Result<(), DriveError> {
        let n = self.next_tick;
        // The DAC holds this tick's code until the next edge at least.
        board.extend_drive_until(self.tick_time_s(n + 1))?;
        // The board's pick-off stream: the conversion an aperture delay after the edge.
        let code = board.drive_tick_code(n);
        if n < self.coast_until_tick {
            // The controller's code is in flash: the drive in force goes on (the segment
            // already pushed describes it).
            self.last_code = self.coast.code();
            self.next_tick = n + 1;
            self.handled += 1;
            return Ok(());
        }
        self.coast.hand_over(&mut self.controller, &self.config);
        let tick: Tick = self.controller.on_tick(&self.config, code);
        self.coast.follow(&self.controller);
        if tick.drive_changed {
            let segment = self.segment(self.controller.drive(), n + 1)?;
            board.push_drive(segment)?;
        }
        let locked = self.controller.state() == DitherState::Locked;
        self.note_lock(n, locked);
        self.next_tick = n + 1;
        self.last_code = tick.dac_code;
        self.handled += 1;
        Ok(())
    }

    fn note_lock(&mut self, tick: u64, locked: bool) {
        if self.locked_since.back().is_none_or(|&(_, l)| l != locked) {
            if self.locked_since.len() == STATE_HISTORY {
                self.locked_since.pop_front();
            }
            self.locked_since.push_back((tick, locked));
        }
    }

    /// A flash operation stalls the board's fetches from flash from the next tick until
    /// `until_s`: the ticks meanwhile coast (module docs), the controller takes over again at
    /// the first tick after. (The drive runs ahead of the board's time, so the coast starts at
    /// the drive's next tick, up to its lead after the instant of the command.)
    pub fn coast_until(&mut self, until_s: f64) {
        let resume = (until_s * self.dac.tick_hz).ceil() as u64;
        self.coast_until_tick = self.coast_until_tick.max(resume);
    }

    /// The segment of `drive`, whose first sample is written at the edge of absolute tick
    /// `first` (the controller's wrapping tick count must agree).
    fn segment(&self, drive: Drive, first: u64) -> Result<DriveSegment, DriveError> {
        if drive.start_tick != first as u32 {
            return Err(DriveError::Invalid(
                "the controller's drive does not start at the next tick",
            ));
        }
        let turns = |bits: u32| f64::from(bits) / firmware::units::Q32_PER_TURN;
        Ok(DriveSegment::from_codes(
            self.tick_time_s(first),
            core::f64::consts::TAU * turns(drive.phase.to_bits()),
            core::f64::consts::TAU * turns(drive.step.to_bits()),
            drive.amplitude_codes(),
            f64::from(drive.mid_code),
            &self.dac,
        ))
    }

    /// Whether the controller was locked after the last tick at or before `t_s` (false before
    /// the first tick, and for instants older than the kept history).
    pub fn locked_at(&self, t_s: f64) -> bool {
        let tick = (t_s * self.dac.tick_hz).floor();
        if tick < 0.0 {
            return false;
        }
        let tick = tick as u64;
        self.locked_since
            .iter()
            .rev()
            .find(|&&(since, _)| since <= tick)
            .is_some_and(|&(_, locked)| locked)
    }
}
