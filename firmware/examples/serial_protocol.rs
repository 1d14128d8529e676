//! The calibration protocol over USART1 on the emulated STM32F405 (QEMU `netduinoplus2`), through
//! the board's own code: `board::usart` (RXNE interrupt into the RX queue, software-pended TX
//! interrupt draining the TX queue), `board::service` (line assembly, parse, `Executor`,
//! `DeviceLink`, store with the readout paused and re-synchronised), `board::app` (priorities,
//! tick, readout task and its lock). What QEMU cannot model is replaced, nothing else:
//!
//! - flash programming: a RAM-backed `NorFlash` with NOR semantics (erase to 0xFF, program only
//!   clears bits) holds the calibration store, two 8 KiB "sectors";
//! - turnarounds: the readout is idle (no TIM2/TIM5/ADC/DMA set-up: QEMU's timers and ADC are
//!   not faithful); `status` reports zero turnarounds.
//!
//! Run by `.ci/qemu_serial.py`, which connects to USART1 over TCP, waits for the banner, checks
//! the exchanges and ends the run with the line `quit` (an example-only hook: the firmware
//! answers nothing and exits through semihosting with status 0).
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
mod app {
    use embedded_storage::nor_flash::{
        ErrorType, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash,
    };
    use firmware::board::app::{init_core, unmask_readout};
    use firmware::board::service::{Service, ServiceConfig};
    use firmware::board::{clocks, pac, usart, watchdog};
    use firmware::protocol::execute::Identity;
    use firmware::readout::ReadoutConfig;
    use firmware::storage::Geometry;

    firmware::bind_board_interrupts!();

    const SECTOR_BYTES: usize = 8 * 1024;

    /// NOR flash in RAM: two sectors, erase to 0xFF, programming ANDs (only clears bits).
    struct RamFlash {
        bytes: [u8; 2 * SECTOR_BYTES],
    }

    #[derive(Clone, Copy, Debug, defmt::Format)]
    enum RamFlashError {
        OutOfBounds,
        NotAligned,
    }

    impl NorFlashError for RamFlashError {
        fn kind(&self) -> NorFlashErrorKind {
            match self {
                Self::OutOfBounds => NorFlashErrorKind::OutOfBounds,
                Self::NotAligned => NorFlashErrorKind::NotAligned,
            }
        }
    }

    impl RamFlash {
        fn range(&self, offset: u32, len: usize) -> Result<core::ops::Range<usize>, RamFlashError> {
            let start = offset as usize;
            let end = start.checked_add(len).ok_or(RamFlashError::OutOfBounds)?;
            if end > self.bytes.len() {
                return Err(RamFlashError::OutOfBounds);
            }
            Ok(start..end)
        }
    }

    impl ErrorType for RamFlash {
        type Error = RamFlashError;
    }

    impl ReadNorFlash for RamFlash {
        const READ_SIZE: usize = 1;
        fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), RamFlashError> {
            let range = self.range(offset, bytes.len())?;
            bytes.copy_from_slice(&self.bytes[range]);
            Ok(())
        }
        fn capacity(&self) -> usize {
            self.bytes.len()
        }
    }

    impl NorFlash for RamFlash {
        const WRITE_SIZE: usize = 4;
        const ERASE_SIZE: usize = SECTOR_BYTES;
        fn erase(&mut self, from: u32, to: u32) -> Result<(), RamFlashError> {
            if !(from as usize).is_multiple_of(SECTOR_BYTES)
                || !(to as usize).is_multiple_of(SECTOR_BYTES)
                || to < from
            {
                return Err(RamFlashError::NotAligned);
            }
            let range = self.range(from, (to - from) as usize)?;
            self.bytes[range].fill(0xFF);
            Ok(())
        }
        fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), RamFlashError> {
            if !offset.is_multiple_of(4) || !bytes.len().is_multiple_of(4) {
                return Err(RamFlashError::NotAligned);
            }
            let range = self.range(offset, bytes.len())?;
            for (cell, &b) in self.bytes[range].iter_mut().zip(bytes) {
                *cell &= b;
            }
            Ok(())
        }
    }

    /// `quit`: the test is over (example only).
    fn quit(line: &str) -> bool {
        if line == "quit" {
            defmt::info!("serial_protocol: quit received, exiting");
            semihosting::process::exit(0);
        }
        false
    }

    #[cortex_m_rt::entry]
    fn main() -> ! {
        let mut cp = cortex_m::Peripherals::take().unwrap();
        let dp = pac::Peripherals::take().unwrap();
        let source = clocks::init(&dp.RCC, &dp.FLASH);
        clocks::enable(&dp.RCC, clocks::AHB1_GPIOA, 0, clocks::APB2_USART1);
        let watchdog = watchdog::Watchdog::start(dp.IWDG);
        init_core(&mut cp.SCB, &mut cp.NVIC, &mut cp.SYST);
        let serial = usart::init(dp.USART1);
        let flash = RamFlash {
            bytes: [0xFF; 2 * SECTOR_BYTES],
        };
        let config = ServiceConfig {
            identity: Identity {
                firmware_version: env!("CARGO_PKG_VERSION"),
                build: "qemu",
                board: "netduinoplus2",
                serial_number: 4242,
                key: 0xC0FF_EE42,
                scale_factor_arcsec: 1.8655,
                capture_timer_hz: 84_000_000,
            },
            geometry: Geometry {
                base_offset: 0,
                sector_bytes: SECTOR_BYTES as u32,
            },
            hardware: false,
            dither_hz: 389.0,
            scale_factor_arcsec: 1.8655,
            banner: Some("# rlg-readout ready"),
            intercept: Some(quit),
        };
        let readout_config = ReadoutConfig::for_board(
            84e6,
            389.0,
            firmware::profile::BoardProfile::F405.counter_width,
        );
        let service = Service::new(config, serial, flash, Some(watchdog), readout_config);
        defmt::info!(
            "serial_protocol: clocks {}, USART1 up, readout idle",
            source
        );
        unmask_readout(false);
        // SAFETY: the USART's queues are set up (usart::init).
        unsafe { cortex_m::peripheral::NVIC::unmask(pac::Interrupt::USART1) };
        service.run()
    }
}

#[cfg(not(target_os = "none"))]
fn main() {
    println!("serial_protocol: an MCU example; see .ci/qemu_serial.py");
}
