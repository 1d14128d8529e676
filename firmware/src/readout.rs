//! The readout: the whole signal chain behind the interrupts that feed it.
//!
//! - The photodiode ADC stream (regular conversions at arbitrary instants, DMA blocks on the
//!   board) goes to [`Readout::on_lissajous_sample`]: the Heydemann fit learns the offsets, gains
//!   and quadrature error of the channels from the signal itself.
//! - The turnaround interrupt latches a [`TurnaroundSample`] and calls
//!   [`Readout::on_turnaround`]: count extension (stage 1, `signal::count`) -> normalisation and
//!   fringe phase, count plus fractional fringe (stage 3, `signal::fringe`) -> cycle assembly,
//!   P1/P2 and the latch split (stage 4, `signal::lockin`) -> compensation of the closed cycle
//!   (stage 5, `signal::compensation`). A completed dither cycle comes back as a
//!   [`CycleRecord`]. The stages know nothing of each other's state: this is the one place
//!   that wires them (stage 2, the turnaround schedule, runs in the pick-off interrupt;
//!   stage 6's averaged rate in the cycle task).
//! - The pick-off stream (the drive tick's conversion, 40 kHz on the board) goes to
//!   [`Readout::on_pickoff_sample`]: stage 6's model of the dither, seeded with the dither
//!   frequency the cycle assembly measures.
//! - The output latch (a sync edge, or the internal output rate) latches an [`OutputSample`]
//!   and calls [`Readout::on_output_latch`]: stages 1 and 3 as for a turnaround, less the
//!   lock-in corrections of the cycles closed so far, then stage 6's dither stripping with the
//!   modelled dither at the latch and the fixed-rate [`OutputRecord`]. The model is the one
//!   the stream handed over so far made (the board's readout task takes each output latch
//!   before the pick-off samples queued behind it, so a record waits for no backlog; the model
//!   evaluates its sine at the latch's own instant, and a fit a millisecond older is the same
//!   sine).
//!
//! Coefficients (immutable, `Copy`) live in [`ReadoutConfig`]; the state in [`Readout`]. New
//! compensation settings are staged with [`Readout::stage_compensation`] and take effect whole
//! at the next cycle boundary. Everything here is plain data in, data out: the host simulator
//! calls exactly these functions.

use crate::sample::{AdcCode, OutputSample, TurnaroundSample};
use crate::signal::compensation::{CompensationSettings, Compensator};
use crate::signal::count::{CountUpdate, CounterWidth, FringeCountConfig, FringeCounter};
use crate::signal::fringe::{
    FringePhaseConfig, FringeResolver, LissajousCoefficients, LissajousConfig, LissajousTracker,
};
use crate::signal::lockin::{
    CycleAssembler, CycleConfig, CycleFlags, CycleRecord, LevelPair, TurnaroundReading,
};
use crate::signal::output::dither_model::{DitherModel, DitherModelStatus, PickoffSample};
use crate::signal::output::record::{OutputConfig, OutputRecord, OutputRecorder, OutputStatus};
use crate::signal::output::strip::{DitherStripper, StripStatus};
use crate::units::PhaseDelta;

/// Highest x4 edge rate the count extension accepts between reads, edges/s: above the
/// 2.4 M edges/s of the docs/physics.md parameter set with margin.
pub const MAX_EDGE_RATE_HZ: u32 = 4_000_000;

/// The largest pick-off lag the turnaround schedule takes from the stripping, s: a lag beyond
/// it is a wiring fault, not a phase the schedule should follow (20 us is 2.8 degrees at
/// 389 Hz; the pick-off of docs/board.md lags by under 5 us).
pub const MAX_PICKOFF_LAG_S: f32 = 20e-6;

/// Every setting of the signal chain (immutable).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ReadoutConfig {
    /// Stage 1: the encoder register's width and the step bound.
    pub counter: FringeCountConfig,
    /// Stage 3: the Lissajous fit's windows and acceptance limits.
    pub lissajous: LissajousConfig,
    /// Stage 3: the board's wiring convention and the signal-lost bounds.
    pub fringe_phase: FringePhaseConfig,
    /// Stage 4: the timer clock and the plausible half-period range.
    pub cycle: CycleConfig,
    /// Stage 6a/6b: dither stripping and the fixed-rate output records.
    pub output: OutputConfig,
}

impl ReadoutConfig {
    /// Settings for a board whose encoder register has `width`, with a capture timer at
    /// `timer_hz`, a dither near `dither_hz` (+-20 % accepted) and the output stage's
    /// `output` settings (pick-off, scale factor). A board's own settings come from its profile
    /// ([`crate::profile::BoardProfile::readout_config`]).
    pub fn for_board(
        timer_hz: f64,
        dither_hz: f64,
        width: CounterWidth,
        output: OutputConfig,
    ) -> Self {
        let half_period_ticks = (timer_hz / (2.0 * dither_hz)) as u32;
        Self {
            counter: FringeCountConfig {
                width,
                max_step_counts: FringeCountConfig::max_step_for(
                    MAX_EDGE_RATE_HZ,
                    half_period_ticks,
                    timer_hz as u32,
                ),
                resync_after: 3,
            },
            lissajous: LissajousConfig::DEFAULT,
            fringe_phase: FringePhaseConfig::DEFAULT,
            cycle: CycleConfig::for_dither(timer_hz as f32, dither_hz as f32, 0.2),
            output,
        }
    }
}

/// Counters the status command reports.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ReadoutCounters {
    /// Turnaround latches taken (wrapping).
    pub turnarounds: u32,
    /// Dither cycles closed (wrapping).
    pub cycles: u32,
    /// Encoder reads rejected or resynchronised (saturating).
    pub counter_glitches: u32,
    /// Readings whose count and fractional fringe disagreed by more than a quadrant.
    pub phase_glitches: u32,
    /// Readings with the normalised radius out of bounds (fringe contrast gone).
    pub signal_lost: u32,
    /// Lissajous windows accepted.
    pub lissajous_fits: u32,
    /// Lissajous windows rejected (the previous coefficients kept).
    pub lissajous_rejections: u32,
}

/// The state of the whole chain.
#[derive(Clone, Debug)]
pub struct Readout {
    counter: FringeCounter,
    lissajous: LissajousTracker,
    resolver: FringeResolver,
    cycles: CycleAssembler,
    compensator: Compensator,
    counters: ReadoutCounters,
    model: DitherModel,
    stripper: DitherStripper,
    recorder: OutputRecorder,
    /// Sum of the lock-in corrections of the cycles closed so far (wrapping): the output latch
    /// subtracts it from the counted phase.
    correction_total: PhaseDelta,
    /// Faults seen since the last output latch (at turnarounds or latches).
    output_faults: OutputStatus,
    /// Faults an output latch saw, for the cycle the next turnaround closes.
    cycle_faults: CycleFlags,
}

impl Readout {
    /// A chain at rest: nominal Lissajous coefficients, no count yet, `settings` in force.
    pub fn new(config: &ReadoutConfig, settings: CompensationSettings) -> Self {
        Self {
            counter: FringeCounter::new(),
            lissajous: LissajousTracker::new(LissajousCoefficients::NOMINAL),
            resolver: FringeResolver::new(),
            cycles: CycleAssembler::new(),
            compensator: Compensator::new(settings),
            counters: ReadoutCounters::default(),
            model: DitherModel::new(),
            stripper: DitherStripper::new(&config.output.strip),
            recorder: OutputRecorder::new(),
            correction_total: PhaseDelta::ZERO,
            output_faults: OutputStatus::empty(),
            cycle_faults: CycleFlags::empty(),
        }
    }

    /// One photodiode conversion pair taken at an arbitrary instant.
    pub fn on_lissajous_sample(
        &mut self,
        config: &ReadoutConfig,
        a_code: AdcCode,
        b_code: AdcCode,
    ) {
        match self.lissajous.add(&config.lissajous, a_code, b_code) {
            Some(Ok(_)) => {
                self.counters.lissajous_fits = self.counters.lissajous_fits.saturating_add(1)
            }
            Some(Err(_)) => {
                self.counters.lissajous_rejections =
                    self.counters.lissajous_rejections.saturating_add(1)
            }
            None => {}
        }
    }

    /// One conversion of the pick-off stream (every drive tick), in tick order.
    pub fn on_pickoff_sample(&mut self, config: &ReadoutConfig, sample: PickoffSample) {
        self.model.push(&config.output.model, sample);
    }

    /// One turnaround latch; returns the dither cycle it completes, if any.
    pub fn on_turnaround(
        &mut self,
        config: &ReadoutConfig,
        sample: TurnaroundSample,
    ) -> Option<CycleRecord> {
        self.counters.turnarounds = self.counters.turnarounds.wrapping_add(1);
        let mut flags = if sample.drive_locked {
            CycleFlags::empty()
        } else {
            CycleFlags::DRIVE_UNLOCKED
        };
        flags = flags.union(core::mem::replace(
            &mut self.cycle_faults,
            CycleFlags::empty(),
        ));
        let (reading, read_flags) = self.read_phase(
            config,
            sample.encoder_count,
            sample.adc_a_code,
            sample.adc_b_code,
        );
        flags = flags.union(read_flags);
        let turnaround = TurnaroundReading {
            kind: sample.kind,
            phase: reading.phase.total(),
            levels: (!reading.signal_lost).then(|| LevelPair {
                cos_psi_h: reading.levels.cos_f32(),
                sin_psi_h: reading.levels.sin_f32(),
            }),
            timestamp_ticks: sample.timestamp_ticks,
            flags,
        };
        let record = self.cycles.on_turnaround(&config.cycle, turnaround);
        // The dither model's oscillator starts at (and is checked against) the dither the
        // turnarounds measure.
        self.model
            .seed(&config.output.model, self.cycles.dither_hz());
        let record = record?;
        let record = self.compensator.compensate(record);
        self.counters.cycles = self.counters.cycles.wrapping_add(1);
        self.correction_total += record.output.correction;
        Some(record)
    }

    /// Stages 1 and 3 for one latch (turnaround or output): the count extended, the fractional
    /// fringe resolved; the flags of what went wrong (also kept for the output period).
    fn read_phase(
        &mut self,
        config: &ReadoutConfig,
        encoder_count: u32,
        adc_a_code: AdcCode,
        adc_b_code: AdcCode,
    ) -> (crate::signal::fringe::FringeReading, CycleFlags) {
        let mut flags = CycleFlags::empty();
        match self.counter.update(&config.counter, encoder_count) {
            CountUpdate::Glitch(_) => flags = flags.union(CycleFlags::COUNTER_GLITCH),
            CountUpdate::Resynced(_) => {
                flags = flags.union(CycleFlags::COUNTER_GLITCH);
                // The register moved under us: the count-to-phase relation must be learned anew.
                self.resolver.realign();
            }
            CountUpdate::Initialised | CountUpdate::Step(_) => {}
        }
        if flags.contains(CycleFlags::COUNTER_GLITCH) {
            self.counters.counter_glitches = self.counters.counter_glitches.saturating_add(1);
        }
        let levels = self.lissajous.normalise(adc_a_code, adc_b_code);
        let reading = self
            .resolver
            .resolve(&config.fringe_phase, self.counter.count(), levels);
        if reading.glitch {
            flags = flags.union(CycleFlags::COUNTER_GLITCH);
            self.counters.phase_glitches = self.counters.phase_glitches.saturating_add(1);
        }
        if flags.contains(CycleFlags::COUNTER_GLITCH) {
            self.output_faults = self.output_faults.union(OutputStatus::COUNTER_GLITCH);
        }
        if reading.signal_lost {
            self.counters.signal_lost = self.counters.signal_lost.saturating_add(1);
            self.output_faults = self.output_faults.union(OutputStatus::SIGNAL_LOST);
        }
        (reading, flags)
    }

    /// One output latch (the sync input's edge, or the internal output timer): the counted
    /// phase, less the lock-in corrections of the cycles closed so far (a cycle's correction
    /// enters the output at the first latch after the cycle closes), stripped of the dither
    /// (stage 6a), becomes the record of the period that ends here (stage 6b). A fault seen
    /// here also flags the cycle the next turnaround closes.
    pub fn on_output_latch(
        &mut self,
        config: &ReadoutConfig,
        sample: OutputSample,
    ) -> OutputRecord {
        let (reading, read_flags) = self.read_phase(
            config,
            sample.encoder_count,
            sample.adc_a_code,
            sample.adc_b_code,
        );
        self.cycle_faults = self.cycle_faults.union(read_flags);
        let mut status = core::mem::replace(&mut self.output_faults, OutputStatus::empty());
        if config.output.strip.at_rail(sample.pickoff_code) {
            status = status.union(OutputStatus::PICKOFF_FAULT);
        }
        if sample.drive_locked {
            status = status.union(OutputStatus::DITHER_LOCKED);
        }
        if self.compensator.active().enabled {
            status = status.union(OutputStatus::COMPENSATION_ON);
        }
        let model = &config.output.model;
        let dither = self.model.estimate(model, sample.timestamp_ticks);
        match &dither {
            None => status = status.union(OutputStatus::NO_DITHER_MODEL),
            Some(d) => {
                if self.model.disagrees(model, d, sample.pickoff_code) {
                    status = status.union(OutputStatus::PICKOFF_FAULT);
                }
            }
        }
        let usable = sample.drive_locked && !status.intersects(OutputStatus::FAULTS);
        let phase = reading.phase.total() - self.correction_total;
        let stripped = self
            .stripper
            .strip(&config.output.strip, phase, dither.as_ref(), usable);
        if stripped.implausible {
            status = status.union(OutputStatus::PICKOFF_FAULT);
        }
        if self.stripper.status(&config.output.strip).converged {
            status = status.union(OutputStatus::K_CONVERGED);
        }
        self.recorder.record(
            &config.output,
            sample.timestamp_ticks,
            stripped.phase,
            status,
        )
    }

    /// The temperature, its rate and the thermal correction for the output records from the
    /// next latch on (`thermal::state::ThermalState`, in the main loop, hands it over whole).
    pub fn set_thermal(&mut self, thermal: crate::thermal::state::ThermalInput) {
        self.recorder.set_thermal(thermal);
    }

    /// Output latches were lost before they reached the readout: the next record is a restart
    /// (invalid, its period spanning the loss), so no angle is spliced across it.
    pub fn break_output_chain(&mut self) {
        self.recorder.restart();
        self.output_faults = self.output_faults.union(OutputStatus::RESTART);
    }

    /// Adds `bits` to the next output record's status (the board's timing watch marks every
    /// output latch while a fault is raised: `OutputStatus::TIMING_FAULT`, which invalidates
    /// the record and the chain after it).
    pub fn mark_output(&mut self, bits: OutputStatus) {
        self.output_faults = self.output_faults.union(bits);
    }

    /// Output records made so far (the next record's sequence number).
    pub fn output_records(&self) -> u64 {
        self.recorder.records()
    }

    /// The stripping coefficient K and the state of its fit.
    pub fn strip_status(&self, config: &ReadoutConfig) -> StripStatus {
        self.stripper.status(&config.output.strip)
    }

    /// Starts the stripping from the taps `k` and `k_quadrature` (fringes per pick-off code:
    /// the values stored with the calibration), forgetting the fit.
    pub fn restart_strip_from(&mut self, config: &ReadoutConfig, k: f32, k_quadrature: f32) {
        self.stripper
            .restart_from(&config.output.strip, k, k_quadrature);
    }

    /// The model of the pick-off stream (valid, frequency, amplitude, restarts).
    pub fn dither_model_status(&self, config: &ReadoutConfig) -> DitherModelStatus {
        self.model.status(&config.output.model)
    }

    /// How far the pick-off lags the dither, capture-timer ticks (rounded; negative: it
    /// leads), as the stripping's quadrature tap measures it against the count: the turnaround
    /// schedule subtracts it, since the pick-off comparator's edges lag by as much
    /// (`signal::turnaround`). `None` until the stripping has converged; clamped to
    /// +-[`MAX_PICKOFF_LAG_S`].
    pub fn pickoff_lag_ticks(&self, config: &ReadoutConfig) -> Option<i32> {
        let w = self.model.angular_frequency_rad_per_s(&config.output.model);
        let lag_s = self
            .stripper
            .status(&config.output.strip)
            .pickoff_lag_s(w)?
            .clamp(-MAX_PICKOFF_LAG_S, MAX_PICKOFF_LAG_S);
        Some(crate::math::round_f32_to_i32(
            lag_s * config.output.timer_hz as f32,
        ))
    }

    /// Picks up again after the readout was paused (a flash store stalls the CPU for up to
    /// 2 s: turnarounds were missed while the encoder counted on in hardware). The count runs
    /// on through the pause (one large step is accepted, `FringeCounter::expect_jump`), and the
    /// first cycle after it spans the gap from the last closed cycle's end, flagged
    /// `TURNAROUND_MISSED` (`CycleAssembler::gap`): the angle turned meanwhile is carried into
    /// the per-cycle output, not dropped. The Lissajous coefficients, the count-to-phase
    /// alignment, the compensation settings and the counters are kept. The fixed-rate output
    /// does not splice across the stall: its next record is a restart (invalid, its period
    /// spanning the stall), since the lock-in corrections of the cycles in the stall are
    /// missing from it.
    pub fn resynchronise(&mut self) {
        self.counter.expect_jump();
        self.cycles.gap();
        self.recorder.restart();
        self.output_faults = self.output_faults.union(OutputStatus::RESTART);
    }

    /// Stages compensation settings; they apply whole from the next cycle boundary.
    pub fn stage_compensation(&mut self, settings: CompensationSettings) {
        self.compensator.stage(settings);
    }

    /// The compensation settings in force.
    pub fn compensation(&self) -> CompensationSettings {
        self.compensator.active()
    }

    /// The settings most recently asked for (staged, or in force if none waits).
    pub fn staged_or_active_compensation(&self) -> CompensationSettings {
        self.compensator.staged_or_active()
    }

    /// The event counters (for `status`).
    pub fn counters(&self) -> ReadoutCounters {
        self.counters
    }

    /// The measured dither: amplitude (beat-phase rad) and frequency (Hz).
    pub fn dither(&self) -> (f32, f32) {
        (self.cycles.dither_amplitude_rad(), self.cycles.dither_hz())
    }

    /// The Lissajous tracker (fitted ellipse, rejections).
    pub fn lissajous(&self) -> &LissajousTracker {
        &self.lissajous
    }
}
