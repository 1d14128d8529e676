//! The firmware in the loop: the simulated board feeding the firmware's own readout, one half
//! dither cycle at a time. The host runs of the firmware's signal chain go through [`Harness`]:
//! the sweep of `rlg-sim`, the system tests, the scheduled-latch tests; the API also serves the
//! simulated device (`device.rs`, which adds the serial protocol and the flash on top: one half
//! cycle at a time, a stalled CPU, the readout between steps).
//!
//! # One step
//!
//! A step ([`Harness::step`]) is one half dither cycle, in the order the board's interrupts see
//! it:
//! 1. the board ([`SimBoard::next_half_cycle`]) runs the gyro to the next turnaround latch
//!    (exact, or scheduled from the pick-off: [`LatchTiming`]), collecting the free-running
//!    photodiode conversions, the pick-off stream (a conversion per drive tick) and the output
//!    latches on the way;
//! 2. the conversions go to [`Readout::on_lissajous_sample`] (the ADC DMA stream), the pick-off
//!    stream to [`Readout::on_pickoff_sample`] and each output latch, after the stream up to
//!    it, to [`Readout::on_output_latch`]; then the latch to [`Readout::on_turnaround`] (the
//!    turnaround interrupt); the pick-off lag the output stage measures goes back to the
//!    board's schedule;
//! 3. a dither cycle the latch closed goes back to the board ([`SimBoard::on_cycle`]: the
//!    input-rate shift of the next scheduled latches, the board's cycle task) **before** the
//!    caller sees it, so no caller can forget it.
//!
//! The step returns a [`HalfCycle`]: the latched sample, the latch instant with the true
//! turnaround it was meant for, and the closed cycle. [`Feed`] says what the firmware sees of a
//! step: everything, the conversions but not the latch (a missed interrupt), or nothing (the
//! CPU stalled by a flash erase while the peripherals run on; the caller then calls
//! [`Readout::resynchronise`] through [`Harness::readout_mut`], as the firmware does).
//!
//! # Running
//!
//! - [`Harness::run_until`]: steps until a simulated time, handing each half cycle and the
//!   harness itself to a callback (which may inject faults, stage compensation settings or read
//!   the truth between steps);
//! - [`Harness::run_cycles`]: the common case, every cycle closed in a time window (the warm-up
//!   before it skipped);
//! - [`Harness::step`] / [`Harness::step_with`] for loops that need more control.
//!
//! The board and the gyro's truth stay reachable between steps ([`Harness::board`],
//! [`Harness::board_mut`] for fault injection, [`Harness::take_traversals`]), and so does the
//! readout ([`Harness::readout_mut`]: staging compensation, resynchronising, counters).
//!
//! # Design and trade-offs
//!
//! - The harness owns one board and one readout: the board's rate shift follows that readout's
//!   cycles, as on the board. A second readout on the same signals (a static and a tracked
//!   compensation side by side) is fed by [`Harness::replay_into`], which hands it exactly what
//!   the harness's own readout got in the last step, through the same code; its cycles do not
//!   go back to the board. (Two harnesses with the same seed would also see the same latches as
//!   long as the latch is exact, but a scheduled latch depends on the readout's cycles, and the
//!   board would be simulated twice.)
//! - Callbacks, not iterators: a callback gets `&mut Harness` between steps, which an iterator
//!   over half cycles borrowing the harness could not give.
//! - A driven dither ([`crate::params::DitherModel::Driven`]) needs its drive ahead of the
//!   board: by default the harness feeds the open-loop drive of the parameters
//!   ([`GyroParams::open_loop_drive`]: `dither_amplitude_arcsec` at `dither_hz`, a segment every
//!   half cycle), keeping it [`crate::gyro::Gyro::drive_lead_s`] ahead of the board's time
//!   before every step. [`HarnessOptions::drive`] replaces it, or (`None`) leaves the feeding
//!   to the caller through [`Harness::board_mut`] (a firmware drive loop, which reads the
//!   pick-off with [`SimBoard::pickoff_code`]); the board panics if the drive runs out.
//! - The readout's settings come from the board's profile ([`BoardConfig::readout_config`],
//!   i.e. `firmware::profile::BoardProfile::F405` with the simulated board's timer and counter):
//!   the firmware is configured for the board it runs on, never by a copy of its constants.
//!
//! Size (over 600 lines): the options, the step and the replay share the harness's state; the board
//! it drives is `crate::board`.

use crate::board::{
    BoardConfig, BoardError, LatchRecord, LatchTiming, OutputLatch, SimBoard, Trigger,
};
use crate::dither::drive::DriveError;
use crate::dither::open_loop::OpenLoopDrive;
use crate::drive_loop::FirmwareDrive;
use crate::gyro::{Gyro, Traversal};
use crate::input::InputProfile;
use crate::param_error::ParamError;
use crate::params::GyroParams;
use crate::tmp117::SimTmp117;
use firmware::profile::BoardProfile;
use firmware::readout::{Readout, ReadoutConfig};
use firmware::sample::{AdcCode, TurnaroundSample};
use firmware::signal::compensation::CompensationSettings;
use firmware::signal::lockin::CycleRecord;
use firmware::signal::output::dither_model::PickoffSample;
use firmware::signal::output::record::{OutputRecord, OutputStatus};
use firmware::thermal::model::ThermalModel;
use firmware::thermal::sensor::{SensorConfig, SensorMonitor, SensorUpdate};
use firmware::thermal::state::ThermalState;
use firmware::thermal::tmp117::{Tmp117, ADDRESS};

/// The simulated TMP117's fixed error, °C (inside the part's ±0.1 °C).
pub const SENSOR_OFFSET_C: f64 = 0.02;
/// The simulated TMP117's noise, °C rms (about one LSB with 8 averages).
pub const SENSOR_NOISE_C: f64 = 0.0078;

/// How far ahead of the board's time the harness feeds an open-loop drive at most while it
/// looks for the next turnaround, s.
pub const MAX_DRIVE_LOOKAHEAD_S: f64 = 1.0;

/// Everything a [`Harness`] is built from.
#[derive(Clone, Debug)]
pub struct HarnessOptions {
    /// The gyro: scale factor, lock-in, eps, the dither model (amplitude jitter, random-noise
    /// dither), the noise (angle random walk) and the seed of every random process.
    pub params: GyroParams,
    /// What the gyro measures.
    pub input: InputProfile,
    /// The board around the gyro: photodiodes, counter, latch timing, eps drift, its own seed.
    pub board: BoardConfig,
    /// The compensation settings the readout starts with (on a board: from flash).
    pub compensation: CompensationSettings,
    /// What drives a driven dither (nothing for the prescribed sine).
    pub drive: DriveSource,
}

/// What drives a driven dither ([`crate::params::DitherModel::Driven`]).
#[derive(Clone, Debug)]
pub enum DriveSource {
    /// The caller feeds the drive through [`Harness::board_mut`] (or the dither is the
    /// prescribed sine, which takes none).
    External,
    /// A fixed open-loop drive ([`GyroParams::open_loop_drive`]: a sine at `dither_hz`
    /// holding `dither_amplitude_arcsec` in steady state).
    OpenLoop(OpenLoopDrive),
    /// The firmware's dither controller in the loop ([`FirmwareDrive`]): what a board does.
    Firmware(Box<FirmwareDrive>),
}

impl DriveSource {
    /// The firmware's drive for `params`' driven dither (the F405 profile, enabled, default
    /// setpoints); [`DriveSource::External`] for the prescribed sine.
    pub fn firmware(params: &GyroParams) -> Result<Self, HarnessError> {
        match params.resonator() {
            None => Ok(Self::External),
            Some(r) => FirmwareDrive::new(&BoardProfile::F405, r.dac)
                .map(|d| Self::Firmware(Box::new(d)))
                .map_err(HarnessError::Drive),
        }
    }
}

impl HarnessOptions {
    /// The default board for `params` ([`BoardConfig::for_gyro`]: exact latch), compensation
    /// off, and for a driven dither its open-loop drive ([`GyroParams::open_loop_drive`]).
    pub fn new(params: GyroParams, input: InputProfile) -> Self {
        Self {
            board: BoardConfig::for_gyro(&params),
            drive: params
                .open_loop_drive()
                .map_or(DriveSource::External, DriveSource::OpenLoop),
            params,
            input,
            compensation: CompensationSettings::default(),
        }
    }

    /// With `drive` driving a driven dither.
    pub fn drive(mut self, drive: DriveSource) -> Self {
        self.drive = drive;
        self
    }

    /// With the turnaround latch timed by `latch`.
    pub fn latch(mut self, latch: LatchTiming) -> Self {
        self.board.latch = latch;
        self
    }

    /// With output latches on a sync at `sync_hz` ([`BoardConfig::sync_hz`]).
    pub fn sync_hz(mut self, sync_hz: Option<f64>) -> Self {
        self.board.sync_hz = sync_hz;
        self
    }

    /// With the readout starting from `settings`.
    pub fn compensation(mut self, settings: CompensationSettings) -> Self {
        self.compensation = settings;
        self
    }

    /// Builds the harness.
    pub fn build(self) -> Result<Harness, HarnessError> {
        Harness::new(self)
    }
}

/// Why a harness cannot be built.
#[derive(Debug)]
pub enum HarnessError {
    /// The gyro parameters are invalid.
    Gyro(ParamError),
    /// The board configuration is invalid.
    Board(BoardError),
    /// The drive cannot drive this dither.
    Drive(DriveError),
}

impl core::fmt::Display for HarnessError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Gyro(e) => write!(f, "gyro: {e}"),
            Self::Board(e) => write!(f, "board: {e:?}"),
            Self::Drive(e) => write!(f, "drive: {e:?}"),
        }
    }
}

impl std::error::Error for HarnessError {}

/// What the firmware sees of one half cycle.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Feed {
    /// Both interrupts: the photodiode conversions, then the turnaround latch.
    #[default]
    Everything,
    /// The conversions only: the turnaround interrupt was missed.
    MissTurnaround,
    /// Nothing: the readout is paused for a flash erase while the peripherals run on. The
    /// firmware calls [`Readout::resynchronise`] when it runs again.
    Stalled,
}

/// One half dither cycle as the harness ran it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HalfCycle {
    /// What the turnaround interrupt latched (delivered to the readout or not, see [`Feed`]).
    pub sample: TurnaroundSample,
    /// When it was latched, and the true turnaround it was meant for.
    pub latch: LatchRecord,
    /// The dither cycle this latch closed, already handed back to the board.
    pub record: Option<CycleRecord>,
}

impl HalfCycle {
    /// Simulated time of the latch, s.
    pub fn latch_s(&self) -> f64 {
        self.latch.latch_s
    }
}

/// The simulated board with the firmware's readout in the loop.
pub struct Harness {
    board: SimBoard,
    config: ReadoutConfig,
    readout: Readout,
    /// The photodiode conversions of the last half cycle.
    lissajous: Vec<(AdcCode, AdcCode)>,
    /// The pick-off stream of the last half cycle.
    pickoff: Vec<PickoffSample>,
    /// The output latches of the last half cycle, and the records the readout made of them
    /// (none when stalled).
    latches: Vec<OutputLatch>,
    outputs: Vec<(OutputLatch, OutputRecord)>,
    /// What drives a driven dither.
    drive: DriveSource,
    /// How far ahead of the board's time the drive is kept known, s.
    lead_s: f64,
    /// The last latch and what the readout was fed of it (for [`Harness::replay_into`]).
    last: Option<(TurnaroundSample, Feed)>,
    /// Status bits added to every output record ([`Harness::set_output_mark`]).
    output_mark: OutputStatus,
    /// Turnaround and output latches delivered to the readout since t = 0.
    turnarounds_fed: u64,
    outputs_fed: u64,
    /// The block's temperature sensor on its I2C bus, with the firmware's driver and monitor,
    /// polled after every step as the board's main loop polls it.
    sensor: Tmp117<SimTmp117>,
    monitor: SensorMonitor,
    /// The thermal state and model, when the harness applies them itself (`None`: the caller
    /// takes the sensor's updates, [`Harness::take_sensor_updates`], as the simulated device's
    /// command service does).
    thermal: Option<ThermalState>,
    sensor_updates: Vec<SensorUpdate>,
}

impl Harness {
    /// A gyro, its board and the firmware's readout at t = 0.
    pub fn new(options: HarnessOptions) -> Result<Self, HarnessError> {
        let gyro = Gyro::new(options.params, options.input).map_err(HarnessError::Gyro)?;
        let config = options.board.readout_config(options.params.dither_hz);
        let lead_s = gyro.drive_lead_s();
        let sensor = SimTmp117::new(
            options.params.thermal.profile,
            SENSOR_OFFSET_C,
            SENSOR_NOISE_C,
            options.params.seed ^ 0x544d_5031_3137_0001,
        );
        let drive = match options.params.resonator() {
            Some(_) => options.drive,
            None => DriveSource::External,
        };
        let board = SimBoard::new(gyro, options.board).map_err(HarnessError::Board)?;
        Ok(Self {
            drive,
            lead_s,
            readout: Readout::new(&config, options.compensation),
            board,
            config,
            lissajous: Vec::new(),
            pickoff: Vec::new(),
            latches: Vec::new(),
            outputs: Vec::new(),
            last: None,
            output_mark: OutputStatus::empty(),
            turnarounds_fed: 0,
            outputs_fed: 0,
            sensor: Tmp117::new(sensor, ADDRESS),
            monitor: SensorMonitor::new(),
            thermal: Some(ThermalState::new()),
            sensor_updates: Vec::new(),
        })
    }

    /// The sensor's poll after a step, at the board's time (the main loop's, on the board).
    fn poll_sensor(&mut self) {
        let t_s = self.board.time_s();
        self.sensor.i2c_mut().set_time_s(t_s);
        let now_ms = (t_s * 1e3) as u64;
        let Some(update) = self
            .monitor
            .poll(&SensorConfig::DEFAULT, &mut self.sensor, now_ms)
        else {
            return;
        };
        match &mut self.thermal {
            Some(state) => {
                let input = state.on_sensor(update, self.config.output.scale_factor_arcsec);
                self.readout.set_thermal(input);
            }
            None => self.sensor_updates.push(update),
        }
    }

    /// Puts a thermal model in force (`None`: none) in the harness's own thermal state.
    pub fn set_thermal_model(&mut self, model: Option<ThermalModel>) {
        if let Some(state) = &mut self.thermal {
            let sf = self.config.output.scale_factor_arcsec;
            let input = state.set_model(model, model.is_some(), sf);
            self.readout.set_thermal(input);
        }
    }

    /// The harness's own thermal state (`None` when the caller keeps it).
    pub fn thermal(&self) -> Option<&ThermalState> {
        self.thermal.as_ref()
    }

    /// From now on the caller keeps the thermal state: the sensor's updates wait in
    /// [`Self::take_sensor_updates`] (the simulated device's command service).
    pub fn hand_over_thermal(&mut self) {
        self.thermal = None;
    }

    /// The sensor's updates since the last call (after [`Self::hand_over_thermal`]).
    pub fn take_sensor_updates(&mut self) -> Vec<SensorUpdate> {
        core::mem::take(&mut self.sensor_updates)
    }

    /// The simulated sensor, for fault injection.
    pub fn sensor_mut(&mut self) -> &mut SimTmp117 {
        self.sensor.i2c_mut()
    }

    /// One half dither cycle with everything fed to the readout.
    pub fn step(&mut self) -> HalfCycle {
        self.step_with(Feed::Everything)
    }

    /// One half dither cycle, the readout fed as `feed` says; a closed cycle goes back to the
    /// board before it is returned (and, with the firmware's drive, its count amplitude to the
    /// drive's over-amplitude check, as the board's main loop does). A stopped latch trigger
    /// (`BoardFault::StoppedTrigger(LatchCompare)`) delivers no latch at all.
    pub fn step_with(&mut self, mut feed: Feed) -> HalfCycle {
        self.feed_drive();
        let mut sample = self.board.next_half_cycle(&mut self.lissajous);
        self.board.drain_outputs(&mut self.latches);
        self.board.drain_pickoff_samples(&mut self.pickoff);
        if self.board.faults().stopped(Trigger::LatchCompare) {
            self.latches.clear();
            if feed == Feed::Everything {
                feed = Feed::MissTurnaround;
            }
        }
        if let DriveSource::Firmware(drive) = &self.drive {
            // The latch copies the drive tick's state, as `board::turnaround::latch` does.
            sample.drive_locked = drive.locked_at(self.board.time_s());
            for latch in &mut self.latches {
                latch.sample.drive_locked = drive.locked_at(latch.t_s);
            }
        }
        let latch = self
            .board
            .last_latch()
            .expect("the board records every latch");
        self.outputs.clear();
        let record = feed_readout(
            &mut self.readout,
            &self.config,
            Fed {
                lissajous: &self.lissajous,
                pickoff: &self.pickoff,
                latches: &self.latches,
                sample,
                feed,
                mark: self.output_mark,
            },
            |latch, out| self.outputs.push((*latch, out)),
        );
        if feed != Feed::Stalled {
            self.outputs_fed += self.latches.len() as u64;
        }
        if feed == Feed::Everything {
            self.turnarounds_fed += 1;
        }
        if let Some(record) = &record {
            self.board.on_cycle(record);
            if let DriveSource::Firmware(drive) = &mut self.drive {
                let sf = f64::from(self.config.output.scale_factor_arcsec);
                drive.check_count_amplitude(record, sf);
            }
        }
        self.board
            .set_pickoff_lag_ticks(self.readout.pickoff_lag_ticks(&self.config));
        if feed != Feed::Stalled {
            self.poll_sensor();
        }
        self.last = Some((sample, feed));
        HalfCycle {
            sample,
            latch,
            record,
        }
    }

    /// Feeds the drive (open loop, or the firmware's ticks) a lead ahead of the board's time,
    /// and further, a lead at a time, until the next turnaround is known (a dither still
    /// building up from rest may not turn around within one lead); gives up after
    /// [`MAX_DRIVE_LOOKAHEAD_S`] (the board then panics: there is no turnaround to latch).
    fn feed_drive(&mut self) {
        if matches!(self.drive, DriveSource::External) {
            return;
        }
        if self.board.faults().stopped(Trigger::DriveTick) {
            if let DriveSource::Firmware(drive) = &mut self.drive {
                drive
                    .stop_ticks(&mut self.board)
                    .expect("the held code's segment is valid");
            }
        }
        let now = self.board.time_s();
        let mut until = now + self.lead_s;
        loop {
            match &mut self.drive {
                DriveSource::External => return,
                DriveSource::OpenLoop(drive) => drive
                    .keep_ahead(&mut self.board, until)
                    .expect("the open-loop drive's segments are valid"),
                DriveSource::Firmware(drive) => drive
                    .run_until(&mut self.board, until)
                    .expect("the firmware's drive segments are valid"),
            }
            if self.board.try_upcoming_turnaround().is_some() || until > now + MAX_DRIVE_LOOKAHEAD_S
            {
                return;
            }
            until += self.lead_s;
        }
    }

    /// A flash operation stalls the board's fetches from flash until `until_s`: the firmware's
    /// drive coasts as on the board ([`FirmwareDrive::coast_until`]). Nothing happens to an
    /// open-loop or external drive. (Whether the readout pauses too is the caller's: it steps
    /// with [`Feed::Stalled`] through an erase.)
    pub fn coast_drive(&mut self, until_s: f64) {
        if let DriveSource::Firmware(drive) = &mut self.drive {
            drive.coast_until(until_s);
        }
    }

    /// Status bits added to every output record from the next step on (the board's readout task
    /// marks every output latch `TIMING_FAULT` while its watch has a fault raised);
    /// `OutputStatus::empty()` to stop.
    pub fn set_output_mark(&mut self, mark: OutputStatus) {
        self.output_mark = mark;
    }

    /// The running counts of the board's periodic events, as its handlers count them, in
    /// `firmware::board_timing::monitor::Event::ALL`'s order: DMA half transfers (256 pairs),
    /// drive ticks, turnaround latches and output latches delivered, sync edges (wrapping).
    pub fn event_counts(&self) -> [u32; 5] {
        let ticks = match &self.drive {
            DriveSource::Firmware(drive) => drive.ticks_handled(),
            _ => 0,
        };
        [
            self.board.lissajous_pairs() / 256,
            ticks,
            self.turnarounds_fed,
            self.outputs_fed,
            self.board.sync_edges(),
        ]
        .map(|c| c as u32)
    }

    /// The board's reaction to a stopped drive tick or a lost clock
    /// ([`FirmwareDrive::take_off`]): mid-scale by software, the drive inhibited. Nothing for
    /// another drive.
    pub fn take_drive_off(&mut self) {
        if let DriveSource::Firmware(drive) = &mut self.drive {
            drive
                .take_off(&mut self.board)
                .expect("the mid-scale segment is valid");
        }
    }

    /// The firmware's dither drive, when it drives the dither.
    pub fn firmware_drive(&self) -> Option<&FirmwareDrive> {
        match &self.drive {
            DriveSource::Firmware(drive) => Some(drive),
            _ => None,
        }
    }

    /// The firmware's dither drive, for commands between steps.
    pub fn firmware_drive_mut(&mut self) -> Option<&mut FirmwareDrive> {
        self.firmware_parts_mut().1
    }

    /// The firmware's two contexts the command service reaches between steps: the readout and
    /// the dither drive (when the firmware drives the dither).
    pub fn firmware_parts_mut(&mut self) -> (&mut Readout, Option<&mut FirmwareDrive>) {
        let drive = match &mut self.drive {
            DriveSource::Firmware(drive) => Some(drive.as_mut()),
            _ => None,
        };
        (&mut self.readout, drive)
    }

    /// Steps until the simulated time reaches `end_s` (the last latch is the first at or past
    /// it), calling `each` after every half cycle with the harness, which it may change.
    pub fn run_until(&mut self, end_s: f64, mut each: impl FnMut(&mut Self, &HalfCycle)) {
        while self.time_s() < end_s {
            let half = self.step();
            each(self, &half);
        }
    }

    /// Runs to `until_s` and hands `on_cycle` every cycle closed by a latch in
    /// `(from_s, until_s]`: the cycles before `from_s` are the warm-up.
    pub fn run_cycles(
        &mut self,
        from_s: f64,
        until_s: f64,
        mut on_cycle: impl FnMut(&CycleRecord),
    ) {
        self.run_until(until_s, |_, half| {
            let t = half.latch_s();
            if let Some(record) = &half.record {
                if t > from_s && t <= until_s {
                    on_cycle(record);
                }
            }
        });
    }

    /// Feeds another readout the last half cycle exactly as the harness's own readout got it
    /// (the same conversions and latch, the same [`Feed`]); returns the cycle it closes. Its
    /// cycles do not go back to the board. Nothing happens before the first step.
    pub fn replay_into(&self, readout: &mut Readout) -> Option<CycleRecord> {
        let (sample, feed) = self.last?;
        let fed = Fed {
            lissajous: &self.lissajous,
            pickoff: &self.pickoff,
            latches: &self.latches,
            sample,
            feed,
            mark: self.output_mark,
        };
        feed_readout(readout, &self.config, fed, |_, _| {})
    }

    /// The output latches of the last half cycle with the records the readout made of them
    /// (empty without a sync, or when the CPU stalled).
    pub fn outputs(&self) -> &[(OutputLatch, OutputRecord)] {
        &self.outputs
    }

    /// Simulated time of the last latch, s.
    pub fn time_s(&self) -> f64 {
        self.board.time_s()
    }

    /// The photodiode conversions of the last half cycle.
    pub fn lissajous(&self) -> &[(AdcCode, AdcCode)] {
        &self.lissajous
    }

    /// The board (latch statistics, the last latch, its configuration).
    pub fn board(&self) -> &SimBoard {
        &self.board
    }

    /// The board, for fault injection between steps (counter glitches, photodiode faults).
    pub fn board_mut(&mut self) -> &mut SimBoard {
        &mut self.board
    }

    /// The gyro, with its truth.
    pub fn gyro(&self) -> &Gyro {
        self.board.gyro()
    }

    /// Drains the gyro's log of completed traversals (the truth about lock-in).
    pub fn take_traversals(&mut self) -> Vec<Traversal> {
        self.board.take_traversals()
    }

    /// The readout's settings.
    pub fn config(&self) -> &ReadoutConfig {
        &self.config
    }

    /// The firmware's readout state (counters, compensation in force, measured dither).
    pub fn readout(&self) -> &Readout {
        &self.readout
    }

    /// The readout, between steps: staging compensation settings, resynchronising after a
    /// stall.
    pub fn readout_mut(&mut self) -> &mut Readout {
        &mut self.readout
    }
}

/// What the board produced in one half cycle, and what the firmware sees of it.
struct Fed<'a> {
    lissajous: &'a [(AdcCode, AdcCode)],
    pickoff: &'a [PickoffSample],
    latches: &'a [OutputLatch],
    sample: TurnaroundSample,
    feed: Feed,
    /// Status bits added to every output record.
    mark: OutputStatus,
}

/// The readout's interrupts for one half cycle, as `fed.feed` says: the conversions, the
/// pick-off stream with the output latches in time order (each latch after the stream up to
/// its tick, its record handed to `on_output`), then the turnaround latch. Returns the cycle
/// the latch closes.
fn feed_readout(
    readout: &mut Readout,
    config: &ReadoutConfig,
    fed: Fed<'_>,
    mut on_output: impl FnMut(&OutputLatch, OutputRecord),
) -> Option<CycleRecord> {
    if fed.feed == Feed::Stalled {
        return None;
    }
    for &(a_code, b_code) in fed.lissajous {
        readout.on_lissajous_sample(config, a_code, b_code);
    }
    let mut stream = fed.pickoff.iter().peekable();
    for latch in fed.latches {
        if !fed.mark.is_empty() {
            readout.mark_output(fed.mark);
        }
        // As the board's readout task: the latch with the model as the stream so far made it,
        // then the stream up to the latch (wrapping timer ticks: at or before it).
        on_output(latch, readout.on_output_latch(config, latch.sample));
        let at = latch.sample.timestamp_ticks;
        while let Some(s) = stream.next_if(|s| at.wrapping_sub(s.timestamp_ticks) < u32::MAX / 2) {
            readout.on_pickoff_sample(config, *s);
        }
    }
    for s in stream {
        readout.on_pickoff_sample(config, *s);
    }
    match fed.feed {
        Feed::Everything => readout.on_turnaround(config, fed.sample),
        Feed::MissTurnaround | Feed::Stalled => None,
    }
}

#[cfg(test)]
mod tests;
