//! The calibration protocol over USART1 on the emulated STM32F405 (QEMU `netduinoplus2`), through
//! the board's own code: `board::usart` (RXNE interrupt into the RX queue, software-pended TX
//! interrupt draining the TX queue), `board::app` (the main loop running the command service,
//! `crate::service`: line assembly, parse, `Executor`, store with the readout paused and
//! re-synchronised), `board::ports` and `board::resources` (priorities, tick, readout task and
//! its lock). What QEMU cannot model is replaced, nothing else:
//!
//! - flash programming: `storage::ram_flash::RamFlash` (NOR semantics: erase to 0xFF, program
//!   only clears bits) holds the calibration store, two 8 KiB "sectors";
//! - turnarounds: the readout is idle (no TIM2/TIM5/ADC/DMA set-up: QEMU's timers and ADC are
//!   not faithful); `status` reports zero turnarounds;
//! - the dither drive: its controller exists (the `dither` commands work), switched off, and
//!   its tick never runs (no TIM4/DAC/ADC3 set-up).
//!
//! Run by `.ci/qemu_serial.py`, which connects to USART1 over TCP, waits for the banner, checks
//! the exchanges and ends the run with the line `quit` (an example-only hook: the firmware
//! answers nothing and exits through semihosting with status 0).
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
mod app {
    use firmware::board::app::{boot, serve};
    use firmware::board::ports::BoardPorts;
    use firmware::board::resources::{init_core, start_dither, unmask_readout};
    use firmware::board::{clocks, pac, usart, watchdog};
    use firmware::dither::DitherConfig;
    use firmware::profile::BoardProfile;
    use firmware::protocol::execute::Identity;
    use firmware::service::ServiceConfig;
    use firmware::storage::ram_flash::RamFlash;
    use firmware::storage::{DitherSetpoints, Geometry};

    firmware::bind_board_interrupts!();

    const SECTOR_BYTES: usize = 8 * 1024;

    /// The stack pointer when the stack was painted (start of `main`).
    static PAINTED_SP: core::sync::atomic::AtomicU32 = core::sync::atomic::AtomicU32::new(0);

    /// `quit`: the test is over (example only). Logs the deepest stack of the whole run: the
    /// main loop serving every command of `.ci/qemu_serial.py` (store and reload included),
    /// with the USART1 and SysTick interrupts nested on it.
    fn quit(line: &str) -> bool {
        if line == "quit" {
            let sp = PAINTED_SP.load(core::sync::atomic::Ordering::Relaxed);
            defmt::info!(
                "stack: main loop with USART1 and SysTick nested, deepest {=u32} bytes below main's frame",
                sp - firmware::stack::deepest()
            );
            defmt::info!("serial_protocol: quit received, exiting");
            semihosting::process::exit(0);
        }
        false
    }

    #[cortex_m_rt::entry]
    fn main() -> ! {
        PAINTED_SP.store(
            firmware::stack::paint(),
            core::sync::atomic::Ordering::Relaxed,
        );
        let mut cp = cortex_m::Peripherals::take().unwrap();
        let dp = pac::Peripherals::take().unwrap();
        let source = clocks::init(&dp.RCC, &dp.FLASH);
        clocks::enable(&dp.RCC, clocks::AHB1_GPIOA, 0, clocks::APB2_USART1);
        let watchdog = watchdog::Watchdog::start(dp.IWDG);
        init_core(&mut cp.SCB, &mut cp.NVIC, &mut cp.SYST);
        let serial = usart::init(dp.USART1);
        let profile = BoardProfile::F405;
        let identity = Identity {
            firmware_version: env!("CARGO_PKG_VERSION"),
            build: "qemu",
            board: "netduinoplus2",
            serial_number: 4242,
            // Unprovisioned, as QEMU's blank OTP model: the host provisions a key first.
            key: firmware::board::otp::read().1,
            scale_factor_arcsec: profile.scale_factor_arcsec as f32,
            capture_timer_hz: profile.timer_hz,
        };
        let geometry = Geometry {
            base_offset: 0,
            sector_bytes: SECTOR_BYTES as u32,
        };
        let mut config =
            ServiceConfig::for_profile(&profile, profile.nominal_dither_hz, identity, geometry);
        config.intercept = Some(quit);
        // The store lives in RAM: a static, so the 16 KiB are not on the stack.
        let flash = cortex_m::singleton!(: RamFlash<2, SECTOR_BYTES> = RamFlash::new()).unwrap();
        let (service, records, _stored) = boot(config, flash);
        // No drive hardware in QEMU (TIM4/DAC/ADC3 are not modelled faithfully): the controller
        // exists for the protocol, switched off; its tick never runs.
        let dither = DitherConfig::for_profile(&profile);
        let off = DitherSetpoints {
            enabled: false,
            amplitude_arcsec: dither.default_setpoint_arcsec,
            noise_percent: 0.0,
        };
        start_dither(dither, Some(off), None);
        defmt::info!(
            "serial_protocol: clocks {}, USART1 up, readout idle",
            source
        );
        unmask_readout(false);
        // SAFETY: the USART's queues are set up (usart::init).
        unsafe { cortex_m::peripheral::NVIC::unmask(pac::Interrupt::USART1) };
        let ports = BoardPorts::new(
            serial,
            Some(watchdog),
            false,
            firmware::board_timing::selftest::SelfTestReport::NOT_RUN,
        );
        // The block's TMP117 on I2C1: QEMU does not model the I2C peripheral, so every transfer
        // times out and `thermal` answers `sensor=bus` after two polls (0.1 s).
        let sensor = firmware::thermal::tmp117::Tmp117::new(
            firmware::board::i2c::I2c1::init(dp.I2C1, &dp.RCC),
            firmware::thermal::tmp117::ADDRESS,
        );
        serve(
            service,
            records,
            ports,
            Some(sensor),
            Some("# rlg-readout ready"),
        )
    }
}

#[cfg(not(target_os = "none"))]
fn main() {
    println!("serial_protocol: an MCU example; see .ci/qemu_serial.py");
}
