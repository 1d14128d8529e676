//! The board's protections on the simulated board: the over-amplitude trip that does not rely
//! on the pick-off, the stored drive setpoints at power-up, the power-up self-test and the rate
//! monitors against injected faults (`hal_sim::board::BoardFault`), all through the firmware's
//! own code (`firmware::dither`, `firmware::board_timing`) as the board runs it.

mod device_support;

use device_support::{boot_with_key, exchange, field, KEY};
use firmware::board_timing::monitor::{Event, TimingFaults};
use firmware::dither::{DitherState, FaultKind};
use firmware::protocol::execute::Identity;
use firmware::protocol::key::Key;
use firmware::protocol::output_frame::decode_output_frame;
use firmware::protocol::parse::crc16;
use firmware::signal::output::record::{OutputRecord, OutputStatus};
use firmware::storage::{
    CalibrationRecord, CalibrationStore, DitherSetpoints, Geometry, ReadoutPaused,
};
use hal_sim::board::{BoardConfig, BoardFault, Trigger};
use hal_sim::device::{SimDevice, SIM_IDENTITY};
use hal_sim::dither::resonator::ResonatorParams;
use hal_sim::flash::CalibrationFlash;
use hal_sim::harness::{DriveSource, HarnessOptions};
use hal_sim::input::InputProfile;
use hal_sim::params::GyroParams;

/// A gyro whose dither is the driven resonator at its nominal frequency.
fn driven() -> GyroParams {
    let base = GyroParams::default();
    base.with_steady_driven_dither(ResonatorParams {
        f0_hz: base.dither_hz,
        ..ResonatorParams::default()
    })
}

/// The pick-off reads 45 % low (a gain error the drive cannot see): holding 450 arcsec on the
/// pick-off would take the true dither to 818 arcsec, past the mechanical limit of 753 arcsec
/// (the pick-off's range). The fringe count's amplitude, which the readout measures every
/// cycle, trips the drive: it goes off (`AmplitudeOutOfRange`) and the true amplitude gets at
/// most 8 arcsec past the limit: the amplitude is a whole cycle's and the trip acts at the next
/// tick, and the ring-up at the full drive adds about 4 arcsec per cycle (measured 3.9 past
/// the limit, printed).
#[test]
fn a_pickoff_reading_low_cannot_drive_the_dither_past_its_range() {
    let params = driven();
    let mut board = BoardConfig::for_gyro(&params);
    board.pickoff.gain_error = -0.45;
    let mut h = HarnessOptions {
        board,
        drive: DriveSource::firmware(&params).unwrap(),
        ..HarnessOptions::new(params, InputProfile::constant(10.0))
    }
    .build()
    .unwrap();
    let limit = 753.3;
    let (mut peak, mut tripped_s) = (0.0f64, None);
    h.run_until(8.0, |h, half| {
        let w = std::f64::consts::TAU * h.gyro().params().dither_hz;
        if let Some(s) = h.gyro().dither_state(half.latch_s()) {
            let a = (s.angle_arcsec.powi(2) + (s.rate_arcsec_per_s / w).powi(2)).sqrt();
            peak = peak.max(a);
        }
        let state = h.firmware_drive().unwrap().controller().state();
        if tripped_s.is_none() && state == DitherState::Fault(FaultKind::AmplitudeOutOfRange) {
            tripped_s = Some(half.latch_s());
        }
    });
    println!("tripped at {tripped_s:?} s, peak {peak:.1} arcsec (limit {limit})");
    assert!(tripped_s.is_some(), "no trip; peak {peak:.1} arcsec");
    assert!(peak < limit + 8.0, "{peak}");
}

/// Powers up a board with `faults` from the start, the fixture key, 10 deg/h.
fn boot(faults: &[BoardFault]) -> SimDevice {
    let params = GyroParams {
        seed: 2501,
        ..GyroParams::default()
    };
    if faults.is_empty() {
        return boot_with_key(params, 10.0, CalibrationFlash::default(), 0);
    }
    SimDevice::boot_with_faults(
        params,
        InputProfile::constant(10.0),
        Identity {
            key: Key::parse_hex(KEY),
            ..SIM_IDENTITY
        },
        CalibrationFlash::default(),
        0,
        faults,
    )
    .unwrap()
}

/// One line with its CRC (a state-changing command runs at once), its answer without the
/// suffix.
fn ask(dev: &mut SimDevice, line: &str) -> String {
    let text = exchange(
        dev,
        format!("{line}*{:04X}\n", crc16(line.as_bytes())).as_bytes(),
    );
    let line = text.trim_end();
    line.rsplit_once('*')
        .map_or(line, |(body, _)| body)
        .to_owned()
}

/// Runs until the drive is locked (within 4 s of power-up: the self-test's sweep, then the
/// start-up), then `extra_s`.
fn run_locked(dev: &mut SimDevice, extra_s: f64) {
    while field(&ask(dev, "status"), "drive") != "locked" {
        assert!(dev.time_s() < 4.0, "the drive did not lock");
        dev.run_for(0.05);
    }
    dev.run_for(extra_s);
}

/// The output records of `seconds` of `stream output`.
fn stream_output(dev: &mut SimDevice, seconds: f64) -> Vec<OutputRecord> {
    assert!(ask(dev, "stream output").starts_with("OK stream=output"));
    dev.run_for(seconds);
    dev.receive(b"stream off\n");
    let bytes = dev.take_output();
    bytes
        .split(|&b| b == 0)
        .filter_map(|chunk| decode_output_frame(chunk).ok())
        .collect()
}

/// A healthy board: the clock, timer and trigger checks pass at power-up, the pick-off check
/// runs (`board=testing`) and passes, the drive locks; over 5 s no timing fault and every
/// output record valid (`board=ok`, `watch=ok`).
#[test]
fn a_healthy_board_passes_its_self_test_and_watches_nothing_wrong() {
    let mut dev = boot(&[]);
    let first = ask(&mut dev, "selftest");
    assert_eq!(
        first,
        "OK clock=pass timers=pass timer_clock=pass triggers=pass pickoff=running watch=ok \
drive=starting"
    );
    assert_eq!(field(&ask(&mut dev, "status"), "board"), "testing");
    run_locked(&mut dev, 1.0);
    let locked_s = dev.time_s();
    assert_eq!(
        ask(&mut dev, "selftest"),
        "OK clock=pass timers=pass timer_clock=pass triggers=pass pickoff=pass watch=ok \
drive=locked"
    );
    let records = stream_output(&mut dev, 4.0);
    assert!(records.len() > 3900, "{}", records.len());
    assert!(records.iter().all(|r| r.is_valid()));
    let status = ask(&mut dev, "status");
    assert_eq!(field(&status, "board"), "ok", "{status}");
    println!("locked {locked_s:.2} s after power-up");
}

/// Each trigger stopped while the board runs: the rate monitors name what stops within their
/// hold plus two windows (printed), `status` names the first, and every output record made
/// while a fault is raised is invalid and says so (`TIMING_FAULT`); a stopped latch trigger or
/// sync makes no record at all. A stopped drive tick also takes the drive off.
#[test]
fn a_trigger_stopped_at_run_time_is_named_and_no_output_is_wrong() {
    let cases: [(Trigger, &[Event]); 4] = [
        (Trigger::Lissajous, &[Event::Lissajous]),
        (
            Trigger::LatchCompare,
            &[Event::Turnaround, Event::OutputLatch],
        ),
        (Trigger::DriveTick, &[Event::DriveTick]),
        (Trigger::Sync, &[Event::OutputLatch, Event::SyncEdge]),
    ];
    for (trigger, named) in cases {
        let mut dev = boot(&[]);
        run_locked(&mut dev, 1.0);
        assert_eq!(field(&ask(&mut dev, "selftest"), "watch"), "ok");
        let injected_s = dev.time_s();
        dev.inject(BoardFault::StoppedTrigger(trigger));
        // Until the slowest of the expected monitors has raised its fault.
        let latest = named
            .iter()
            .map(|e| e.spec().hold_ms + 2 * e.spec().window_ms)
            .max()
            .unwrap();
        let mut raised_s = None;
        while dev.time_s() - injected_s < f64::from(latest) / 1000.0 + 0.1 {
            dev.run_for(0.02);
            let health = dev.board_health();
            if raised_s.is_none()
                && named
                    .iter()
                    .all(|&e| health.timing.contains(TimingFaults::of(e)))
            {
                raised_s = Some(dev.time_s() - injected_s);
            }
        }
        let raised_s = raised_s.unwrap_or_else(|| panic!("{trigger:?}: {:?}", dev.board_health()));
        let watch = field(&ask(&mut dev, "selftest"), "watch").to_owned();
        println!("{trigger:?}: watch={watch} after {raised_s:.3} s");
        for event in named {
            assert!(
                watch.split(',').any(|w| w == event.word()),
                "{trigger:?}: {watch}"
            );
        }
        let status = ask(&mut dev, "status");
        assert_eq!(field(&status, "board"), named[0].word(), "{status}");
        let records = stream_output(&mut dev, 0.5);
        match trigger {
            Trigger::LatchCompare | Trigger::Sync => assert!(records.is_empty(), "{trigger:?}"),
            _ => {
                assert!(records.len() > 450, "{trigger:?}: {}", records.len());
                assert!(
                    records
                        .iter()
                        .all(|r| !r.is_valid() && r.status.contains(OutputStatus::TIMING_FAULT)),
                    "{trigger:?}"
                );
            }
        }
        if trigger == Trigger::DriveTick {
            assert_eq!(field(&ask(&mut dev, "dither status"), "state"), "inhibited");
        }
    }
}

/// Faults present at power-up: a stopped trigger fails `triggers` (naming the first flag it
/// did not set), a PLL that never locks fails `clock`, a dead pick-off fails `pickoff` after
/// the half-drive sweep; each time the drive stays off (`inhibited`), `status` names the check
/// and `dither on` is refused.
#[test]
fn a_fault_at_power_up_fails_its_check_and_keeps_the_drive_off() {
    let cases = [
        (
            BoardFault::StoppedTrigger(Trigger::LatchCompare),
            "triggers",
            "fail:adc1_injected",
        ),
        (
            BoardFault::StoppedTrigger(Trigger::DriveTick),
            "triggers",
            "fail:adc3_injected",
        ),
        (
            BoardFault::StoppedTrigger(Trigger::Lissajous),
            "triggers",
            "fail:lissajous_dma",
        ),
        (BoardFault::PllUnlocked, "clock", "fail:pll"),
        (BoardFault::DeadPickoff, "pickoff", "fail:no_response"),
    ];
    for (fault, check, outcome) in cases {
        let mut dev = boot(&[fault]);
        // The pick-off check's sweep up and down the range: 2.3 s.
        dev.run_for(2.6);
        let answer = ask(&mut dev, "selftest");
        println!("{fault:?}: {answer}");
        assert_eq!(field(&answer, check), outcome, "{answer}");
        assert_eq!(field(&answer, "drive"), "inhibited", "{answer}");
        let status = ask(&mut dev, "status");
        assert_eq!(field(&status, "board"), check, "{status}");
        assert_eq!(field(&status, "drive"), "inhibited", "{status}");
        assert!(ask(&mut dev, &format!("unlock {KEY}")).starts_with("OK unlocked"));
        assert!(
            ask(&mut dev, "dither on").starts_with("ERR 11 "),
            "{fault:?}"
        );
        let amplitude: f64 = field(&ask(&mut dev, "dither status"), "amp_arcsec")
            .parse()
            .unwrap();
        assert!(
            amplitude < 5.0,
            "{fault:?}: the dither at {amplitude} arcsec"
        );
    }
}

/// The crystal stops while the board runs: the clock security system's report is named at
/// once (`clock_lost`), the drive is taken off and inhibited, and the output is invalid.
#[test]
fn a_clock_lost_at_run_time_takes_the_drive_off() {
    let mut dev = boot(&[]);
    run_locked(&mut dev, 0.5);
    dev.inject(BoardFault::ClockLost);
    dev.run_for(0.01);
    assert_eq!(field(&ask(&mut dev, "status"), "board"), "clock_lost");
    assert_eq!(field(&ask(&mut dev, "selftest"), "drive"), "inhibited");
    let records = stream_output(&mut dev, 0.3);
    assert!(records.len() > 250);
    assert!(records.iter().all(|r| !r.is_valid()));
}

/// A stored record whose drive setpoints the firmware refuses (another firmware's wider range:
/// 5000 arcsec) but that says the drive is off: at power-up the drive stays off (the default
/// setpoints apply, not the default "on").
#[test]
fn a_refused_stored_record_that_says_off_keeps_the_drive_off() {
    let mut flash = CalibrationFlash::default();
    let store = CalibrationStore::new(&flash, Geometry::F405_CALIBRATION_AREA).unwrap();
    let record = CalibrationRecord {
        serial_number: SIM_IDENTITY.serial_number,
        dither: Some(DitherSetpoints {
            enabled: false,
            amplitude_arcsec: 5000.0,
            noise_percent: 0.0,
        }),
        ..CalibrationRecord::DEFAULTS
    };
    store
        .store_while_paused(&mut flash, &ReadoutPaused::assume_paused(), &record)
        .unwrap();
    let mut dev = SimDevice::boot(
        GyroParams::default(),
        InputProfile::constant(10.0),
        Identity {
            key: Key::parse_hex(KEY),
            ..SIM_IDENTITY
        },
        flash,
        1,
    )
    .unwrap();
    dev.run_for(3.0);
    let dither = ask(&mut dev, "dither status");
    assert_eq!(field(&dither, "state"), "off", "{dither}");
    assert_eq!(field(&dither, "setpoint_arcsec"), "450.00", "{dither}");
    assert_eq!(field(&ask(&mut dev, "selftest"), "pickoff"), "pass");
}
