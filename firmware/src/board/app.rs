//! The application: start-up ([`run`]) and the main loop ([`serve`]).
//!
//! The main loop is the lowest-priority context (thread mode). It owns the command service
//! (`crate::service::Service`, the same one hal-sim's simulated board runs) and the board's
//! ports for it ([`super::ports::BoardPorts`]), and does four things per pass: it hands the
//! service the received bytes and the dither cycles the readout task queued, bounded per pass
//! (at most one command line: `Service::pass`), refreshes the watchdog, logs the dither drive's status when its state changes, and logs the loss
//! counters when they change. It sleeps (`WFI`) when both queues
//! are empty; any interrupt wakes it, at the latest the 1 ms tick, which bounds the delay of a
//! byte that arrived between the check and the `WFI`. Who runs above it and what they share:
//! [`super::resources`].

use core::sync::atomic::{AtomicU32, Ordering};

use cortex_m::peripheral::NVIC;
use embedded_storage::nor_flash::NorFlash;

use super::ports::BoardPorts;
use super::resources::{
    self, init_core, DitherTask, ReadoutParts, ReadoutQueues, ReadoutTask, SCHEDULER,
};
use super::{
    adc, backup, clocks, dither, encoder, flash, otp, pac, selftest, sync, turnaround, usart,
    watchdog, Shared,
};
use crate::board_timing::selftest::SelfTestReport;
use crate::dither::{Coast, DitherConfig};
use crate::profile::BoardProfile;
use crate::protocol::execute::Identity;
use crate::service::power_up::power_up;
use crate::service::{Service, ServiceConfig};
use crate::signal::output::latch_plan::LatchPlan;
use crate::storage::{DitherSetpoints, Geometry};
use crate::thermal::sensor::{SensorConfig, SensorMonitor};
use crate::thermal::tmp117::{Tmp117, ADDRESS};

/// The gyro block's temperature sensor on I2C1 ([`super::i2c`]).
pub type BlockSensor = Tmp117<super::i2c::I2c1>;

/// Milliseconds between health logs (defmt, only when a counter changed).
const HEALTH_LOG_MS: u64 = 10_000;

/// The board-level loss counters the protocol's `status` does not carry, for the defmt log.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, defmt::Format)]
pub struct Health {
    /// Turnarounds skipped: the compare could not be armed in time (`turnaround::LATE`).
    pub turnarounds_late: u32,
    /// Pick-off edges outside the plausible half-period range (`turnaround::IMPLAUSIBLE`).
    pub pickoff_implausible: u32,
    /// Compare matches nobody armed, discarded (`turnaround::UNARMED`).
    pub latches_unarmed: u32,
    /// Turnaround latches overwritten before the latch handler read them.
    pub latches_overwritten: u32,
    /// Turnaround samples lost: the readout task fell 16 behind.
    pub turnarounds_dropped: u32,
    /// Cycle records the main loop did not take in time.
    pub records_dropped: u32,
    /// Output latches lost before the readout task (the next record restarts the chain).
    pub output_latches_dropped: u32,
    /// Output records the main loop did not take in time (sequence gaps).
    pub output_records_dropped: u32,
    /// Sync edges dropped because an output latch was still pending.
    pub sync_overruns: u32,
    /// Lissajous DMA halves completed again before the readout task processed them.
    pub lissajous_block_overruns: u32,
    /// DMA2 stream 0 transfer errors (each restarted the stream).
    pub dma_errors: u32,
    /// Photodiode regular-group overruns (each restarted the stream).
    pub adc_overruns: u32,
    /// Output latches whose pick-off conversion had not ended (the record flagged invalid).
    pub pickoff_not_converted: u32,
    /// Pick-off edges captured over an unread one (an edge lost).
    pub pickoff_overcaptures: u32,
    /// Internal output periods passed without their compare (a store's pause).
    pub sync_periods_missed: u32,
    /// Drive ticks whose pick-off conversion had not ended.
    pub drive_samples_missed: u32,
    /// USART1 receive overruns (bytes lost in hardware).
    pub usart_overruns: u32,
    /// USART1 framing or noise errors.
    pub usart_line_errors: u32,
    /// Received bytes dropped on a full RX queue.
    pub usart_rx_dropped: u32,
    /// Stream frames dropped on a full TX queue (the service's count).
    pub frames_dropped: u32,
}

impl Health {
    /// The counters now; `frames_dropped` is the service's, `sync_overruns` the latch plan's.
    pub fn now(frames_dropped: u32, sync_overruns: u32) -> Self {
        let get = |c: &AtomicU32| c.load(Ordering::Relaxed);
        Self {
            turnarounds_late: get(&turnaround::LATE),
            pickoff_implausible: get(&turnaround::IMPLAUSIBLE),
            latches_unarmed: get(&turnaround::UNARMED),
            latches_overwritten: get(&turnaround::LATCH_OVERWRITTEN),
            turnarounds_dropped: get(&resources::TURNAROUNDS_DROPPED),
            records_dropped: get(&resources::RECORDS_DROPPED),
            output_latches_dropped: get(&resources::OUTPUT_LATCHES_DROPPED),
            output_records_dropped: get(&resources::OUTPUT_RECORDS_DROPPED),
            sync_overruns,
            lissajous_block_overruns: get(&adc::BLOCK_OVERRUNS),
            dma_errors: get(&adc::DMA_ERRORS),
            adc_overruns: get(&adc::OVERRUNS),
            pickoff_not_converted: get(&turnaround::PICKOFF_NOT_CONVERTED),
            pickoff_overcaptures: get(&turnaround::PICKOFF_OVERCAPTURES),
            sync_periods_missed: get(&sync::PERIODS_MISSED),
            drive_samples_missed: get(&dither::SAMPLES_MISSED),
            usart_overruns: get(&usart::OVERRUNS),
            usart_line_errors: get(&usart::LINE_ERRORS),
            usart_rx_dropped: get(&usart::RX_DROPPED),
            frames_dropped,
        }
    }
}

/// The board's identity: serial number and unlock key from OTP block 0 ([`otp`]). Unprogrammed
/// OTP gives serial 0 and no key: the board refuses every protected command until `key
/// provision` (there is no default key).
fn identity(profile: &BoardProfile) -> Identity {
    let (serial_number, key) = otp::read();
    Identity {
        firmware_version: env!("CARGO_PKG_VERSION"),
        build: env!("FW_BUILD_PROFILE"),
        board: profile.name,
        serial_number,
        key,
        scale_factor_arcsec: profile.scale_factor_arcsec as f32,
        capture_timer_hz: profile.timer_hz,
    }
}

/// Boots the service on `flash` and creates the readout with the settings it loaded
/// (`crate::service::power_up`, host-tested: calibration, the wrong-key count from backup RAM
/// ([`backup`]), the readout); returns the service, the main loop's ends of the cycle and
/// output record queues and the dither drive's stored setpoints (for [`start_dither`]). The
/// readout's interrupts are the caller's to unmask.
pub fn boot<F: NorFlash>(
    config: ServiceConfig,
    flash: F,
) -> (Service<F>, ReadoutQueues, Option<DitherSetpoints>) {
    let (service, readout, dither) = boot_parts(config, flash);
    (service, resources::install_readout(readout), dither)
}

/// [`boot`], the readout's parts handed back instead of put into their statics.
pub fn boot_parts<F: NorFlash>(
    config: ServiceConfig,
    flash: F,
) -> (Service<F>, ReadoutParts, Option<DitherSetpoints>) {
    let up = power_up(
        config,
        flash,
        backup::load_wrong_keys(),
        resources::now_ms(),
    )
    .unwrap_or_else(|e| defmt::panic!("calibration store geometry: {}", e));
    if up.wrong_keys > 0 {
        defmt::warn!("wrong keys before the reset: {}", up.wrong_keys);
    }
    defmt::info!("calibration: {}", up.report);
    let readout = resources::readout_parts(config.readout, up.readout);
    (up.service, readout, up.dither)
}

/// What start-up hands the contexts: [`run`] puts it into the statics of [`resources`],
/// `examples/rtic_board.rs` into RTIC's resources.
pub struct Board {
    /// The command service (the main loop's).
    pub service: Service<flash::InternalFlash>,
    /// The readout task's state and the queue ends of the latch, the tick and the main loop.
    pub readout: ReadoutParts,
    /// The drive tick's controller, and the coast state it hands over to.
    pub dither: (DitherTask, Coast),
    /// The pick-off handler's prediction state.
    pub scheduler: turnaround::Scheduler,
    /// The main loop's side of the serial link.
    pub serial: usart::SerialPort,
    /// The USART1 handler's side.
    pub serial_isr: usart::IsrSide,
    /// The running watchdog (the main loop refreshes it).
    pub watchdog: watchdog::Watchdog,
    /// The power-up self-test's clock, timer and trigger checks.
    pub selftest: SelfTestReport,
    /// The gyro block's temperature sensor (the main loop polls it).
    pub sensor: BlockSensor,
}

/// Brings the board up and runs it: [`bring_up`] (with [`init_core`]: the RAM vector table, the
/// priorities, the 1 ms tick), its state into the handlers' statics, the drive tick unmasked
/// (its pick-off check first, then, enabled, it finds the resonance and locks by itself;
/// inhibited if a check failed), the readout's and the serial link's interrupts, then the main
/// loop. Needs [`crate::bind_board_interrupts`] in the binary.
#[allow(clippy::unwrap_used)] // at reset, once: the peripherals are taken for the first time
pub fn run() -> ! {
    let mut cp = cortex_m::Peripherals::take().unwrap();
    let dp = pac::Peripherals::take().unwrap();
    let board = bring_up(&mut cp, dp, |cp| {
        init_core(&mut cp.SCB, &mut cp.NVIC, &mut cp.SYST)
    });
    let queues = resources::install_readout(board.readout);
    SCHEDULER.init(board.scheduler);
    usart::install(board.serial_isr);
    resources::install_dither(board.dither);
    resources::unmask_readout(true);
    // SAFETY: the USART's handler side is in place (`usart::install`).
    unsafe { NVIC::unmask(pac::Interrupt::USART1) };
    let ports = BoardPorts::new(board.serial, Some(board.watchdog), true, board.selftest);
    serve(
        board.service,
        queues,
        ports,
        Some(board.sensor),
        Some("# rlg-readout ready"),
    )
}

/// Brings the board up: clocks, watchdog, `start_core` (the caller's: vector table, priorities,
/// the 1 ms tick), serial link, calibration from flash, encoder, turnaround timer, ADCs, the
/// drive's peripherals, the power-up self-test (its clock, timer and trigger checks,
/// [`super::selftest`]) and the dither controller it decides on. No interrupt is unmasked:
/// the returned state goes to its contexts first.
pub fn bring_up(
    cp: &mut cortex_m::Peripherals,
    dp: pac::Peripherals,
    start_core: impl FnOnce(&mut cortex_m::Peripherals),
) -> Board {
    let profile = BoardProfile::F405;
    let source = clocks::init(&dp.RCC, &dp.FLASH);
    let watchdog = watchdog::Watchdog::start(dp.IWDG);
    clocks::enable(
        &dp.RCC,
        clocks::AHB1_GPIOA
            | clocks::AHB1_GPIOB
            | clocks::AHB1_GPIOC
            | clocks::AHB1_DMA2
            | clocks::AHB1_BKPSRAM,
        clocks::APB1_PWR
            | clocks::APB1_TIM2
            | clocks::APB1_TIM3
            | clocks::APB1_TIM4
            | clocks::APB1_TIM5
            | clocks::APB1_DAC,
        clocks::APB2_USART1 | clocks::APB2_ADC1 | clocks::APB2_ADC2 | clocks::APB2_ADC3,
    );
    let clock = clocks::flags(&dp.RCC);
    defmt::info!(
        "clocks: SYSCLK {} Hz, crystal {}, PLL locked {}",
        clocks::sysclk_hz(clock),
        source,
        clock.pll_locked
    );
    if !backup::init(&dp.PWR) {
        defmt::warn!("backup regulator not ready: the wrong-key count does not survive power loss");
    }
    start_core(cp);
    let (serial, serial_isr) = usart::configure(dp.USART1);
    let config = ServiceConfig::for_profile(
        &profile,
        profile.nominal_dither_hz,
        identity(&profile),
        Geometry::F405_SECTORS_10_11,
    );
    let (service, readout, dither_setpoints) =
        boot_parts(config, flash::InternalFlash::new(dp.FLASH));
    let _encoder = encoder::Encoder::new(dp.TIM5);
    adc::init(&dp.ADC_COMMON, &dp.ADC1, &dp.ADC2, &dp.TIM3, &dp.DMA2);
    turnaround::init(&dp.TIM2);
    sync::init(&dp.TIM2);
    let dither_config = DitherConfig::for_profile(&profile);
    dither::init(&dp.TIM4, &dp.DAC, &dp.ADC3, dither_config.dac_mid_code);
    let selftest = selftest::run(
        &selftest::Under {
            rcc: &dp.RCC,
            tim2: &dp.TIM2,
            tim3: &dp.TIM3,
            tim4: &dp.TIM4,
            adc1: &dp.ADC1,
            adc2: &dp.ADC2,
            adc3: &dp.ADC3,
            dac: &dp.DAC,
            dma: &dp.DMA2,
        },
        dither_config.dac_mid_code,
    );
    match selftest.first_failure() {
        Some((check, why)) => {
            defmt::error!("self-test: {} failed ({}): drive inhibited", check, why)
        }
        None => defmt::info!("self-test: clock, timers, triggers pass"),
    }
    let sensor = Tmp117::new(super::i2c::I2c1::init(dp.I2C1, &dp.RCC), ADDRESS);
    Board {
        service,
        readout,
        dither: resources::dither_task(dither_config, dither_setpoints, Some(&selftest)),
        scheduler: turnaround::Scheduler::new(),
        serial,
        serial_isr,
        watchdog,
        selftest,
        sensor,
    }
}

/// The main loop (see the module docs). `sensor`: the block's TMP117, polled here (never in
/// an interrupt: a poll is 95-190 us of I2C, `super::i2c`), its updates handed to the
/// service. `banner` is sent once at the start, so a host knows the receiver is on (QEMU drops
/// bytes sent before its serial socket is connected).
pub fn serve<F, R, D, P>(
    mut service: Service<F>,
    mut queues: ReadoutQueues,
    mut ports: BoardPorts<R, D, P>,
    mut sensor: Option<BlockSensor>,
    banner: Option<&str>,
) -> !
where
    F: NorFlash,
    R: Shared<Value = ReadoutTask>,
    D: Shared<Value = DitherTask>,
    P: Shared<Value = LatchPlan>,
{
    use crate::service::ports::SerialTx;
    if let Some(banner) = banner {
        ports.send(banner.as_bytes());
        ports.send(b"\r\n");
    }
    let mut health = Health::default();
    let mut health_logged_ms = resources::now_ms();
    let mut dither_state = None;
    let mut monitor = SensorMonitor::new();
    let mut sensor_state = None;
    loop {
        ports.refresh_watchdog();
        ports.watch_pass();
        if let Some(sensor) = sensor.as_mut() {
            let now = resources::now_ms();
            if let Some(update) = monitor.poll(&SensorConfig::DEFAULT, sensor, now) {
                if sensor_state != Some(update.state) {
                    defmt::info!("temperature sensor: {}", update.state);
                    sensor_state = Some(update.state);
                }
                service.on_sensor(update, &mut ports);
            }
        }
        // Bounded: one command line and one queue of records of each kind, then the watchdog
        // again.
        let ReadoutQueues { cycles, outputs } = &mut queues;
        let scale_factor = service.config().identity.scale_factor_arcsec;
        // Every closed cycle's count amplitude against the mechanical limit: the
        // over-amplitude trip that does not rely on the pick-off. The largest of the pass is
        // checked after it (the service holds the ports meanwhile).
        let mut largest_amplitude_arcsec: Option<f32> = None;
        let busy = service.pass(
            &mut ports,
            |p| p.serial.read_byte(),
            || {
                let record = cycles.dequeue();
                if let Some(r) = &record {
                    let arcsec = crate::dither::count_amplitude_arcsec(&r.record, scale_factor);
                    largest_amplitude_arcsec =
                        Some(largest_amplitude_arcsec.map_or(arcsec, |a| a.max(arcsec)));
                }
                record
            },
            || outputs.dequeue(),
        );
        let dither = &mut ports.locks.dither;
        if let Some(arcsec) = largest_amplitude_arcsec {
            dither.lock(|task| task.controller.check_count_amplitude(&task.config, arcsec));
        }
        let state = dither.lock(|task| task.controller.state());
        if state != dither_state {
            if let Some(status) = dither.lock(|task| task.controller.status(&task.config)) {
                defmt::info!("dither: {}", status);
            }
            dither_state = state;
        }
        let now = resources::now_ms();
        if now - health_logged_ms >= HEALTH_LOG_MS {
            health_logged_ms = now;
            let sync_overruns = turnaround::sync_overruns(&mut ports.locks.plan);
            let current = Health::now(service.frames_dropped(), sync_overruns);
            if current != health {
                defmt::warn!("board health: {}", current);
                health = current;
            }
        }
        if !busy {
            cortex_m::asm::wfi();
        }
    }
}
