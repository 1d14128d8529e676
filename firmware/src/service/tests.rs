//! The service against plain-memory ports and a RAM flash: what the board and the simulator both
//! rely on (one answer per line, settings staged into the readout, an erasing store inside the
//! pause and no pause without an erase, dropped frames counted, status folding).
//!
//! Size (over 600 lines): every test runs on the plain-memory ports (`TestPorts`) and RAM flash
//! defined at the top of this file.

use super::ports::{Clock, DitherAccess, ReadoutAccess, Secrets, SerialTx};
use super::*;
use crate::dither::{DitherConfig, DitherController};
use crate::protocol::commands::testing::MemDrive;
use crate::protocol::key::Key;
use crate::protocol::link::KeyWriteError;
use crate::readout::Readout;
use crate::signal::lockin::LockinTerms;
use crate::signal::lockin::{CycleFlags, CycleOutput};
use crate::storage::ram_flash::RamFlash;
use crate::units::{PhaseDelta, TotalPhase};
use std::string::String as StdString;
use std::vec::Vec;

type Flash = RamFlash<2, 8192>;
const KEY: &str = "1234abcd1234abcd1234abcd1234abcd";

struct TestPorts {
    readout: Readout,
    now_ms: u64,
    out: Vec<u8>,
    frame_room: bool,
    missed_below: u32,
    /// 's' stop, 'r' restart, 'w' a byte of flash traffic seen while stopped.
    log: StdString,
    drive: MemDrive,
    /// The board's backup RAM: the wrong-key count, and how often it was written.
    backup_wrong_keys: u32,
    backup_writes: u32,
}

impl TestPorts {
    fn new(readout: Readout) -> Self {
        Self {
            readout,
            now_ms: 0,
            out: Vec::new(),
            frame_room: true,
            missed_below: 0,
            log: StdString::new(),
            drive: MemDrive::default(),
            backup_wrong_keys: 0,
            backup_writes: 0,
        }
    }
}

impl DitherAccess for TestPorts {
    fn with_dither<R>(&mut self, f: impl FnOnce(&mut DitherController, &DitherConfig) -> R) -> R {
        f(&mut self.drive.controller, &self.drive.config)
    }
}

impl Secrets for TestPorts {
    fn program_key(&mut self, _key: &Key) -> Result<(), KeyWriteError> {
        Err(KeyWriteError::NotBlank)
    }
    fn save_wrong_keys(&mut self, count: u32) {
        self.backup_wrong_keys = count;
        self.backup_writes += 1;
    }
}

impl Clock for TestPorts {
    fn now_ms(&self) -> u64 {
        self.now_ms
    }
}

impl SerialTx for TestPorts {
    fn send(&mut self, bytes: &[u8]) {
        self.out.extend_from_slice(bytes);
    }
    fn try_send_frame(&mut self, frame: &[u8]) -> bool {
        if self.frame_room {
            self.out.extend_from_slice(frame);
        }
        self.frame_room
    }
}

impl ReadoutAccess for TestPorts {
    fn with_readout<R>(&mut self, f: impl FnOnce(&mut Readout) -> R) -> R {
        f(&mut self.readout)
    }
    fn stop_readout(&mut self) {
        self.log.push('s');
    }
    fn restart_readout(&mut self) {
        self.log.push('r');
        self.readout.resynchronise();
    }
    fn missed_below_readout(&self) -> u32 {
        self.missed_below
    }
}

fn config() -> ServiceConfig {
    let identity = Identity {
        firmware_version: "test",
        build: "test",
        board: "test",
        serial_number: 7,
        key: Key::parse_hex(KEY),
        scale_factor_arcsec: 1.8655,
        capture_timer_hz: 84_000_000,
    };
    let geometry = Geometry {
        base_offset: 0,
        sector_bytes: 8192,
    };
    ServiceConfig::for_profile(&BoardProfile::F405, 389.0, identity, geometry)
}

fn boot(flash: Flash) -> (Service<Flash>, TestPorts) {
    let booted = Service::boot(config(), flash, None).unwrap();
    let ports = TestPorts::new(Readout::new(
        &booted.service.config().readout,
        booted.settings,
    ));
    (booted.service, ports)
}

/// One line as the host tool sends it (with its CRC, so state changes run at once); the
/// answer with its CRC suffix checked and removed.
fn ask(service: &mut Service<Flash>, ports: &mut TestPorts, line: &str) -> StdString {
    ports.out.clear();
    let crc = crate::protocol::parse::crc16(line.as_bytes());
    for &b in format!("{line}*{crc:04X}\n").as_bytes() {
        service.on_byte(b, ports);
    }
    let answer = StdString::from_utf8(ports.out.clone()).unwrap();
    let Some((body, suffix)) = answer
        .rsplit_once('*')
        .filter(|_| !answer.starts_with('\0'))
    else {
        return answer; // a framed stream answer or no answer
    };
    let suffix = suffix.trim_end();
    assert_eq!(
        suffix,
        format!("{:04X}", crate::protocol::parse::crc16(body.as_bytes())),
        "{answer:?}"
    );
    format!("{body}\r\n")
}

fn record(flags: CycleFlags) -> CycleRecord {
    CycleRecord {
        output: CycleOutput {
            increment: PhaseDelta::from_q32(3 << 32),
            correction: PhaseDelta::ZERO,
            duration_ticks: 215_938,
            flags,
        },
        raw_increment: PhaseDelta::from_q32(3 << 32),
        terms: LockinTerms {
            p1_s: 1e-5,
            p2_s: -1e-5,
        },
        end_phase: TotalPhase::from_q32(0),
        dither_amplitude_rad: 9.5,
        dither_hz: 389.0,
    }
}

#[test]
fn every_line_gets_exactly_one_answer_and_partial_lines_none() {
    let (mut s, mut p) = boot(Flash::new());
    let id = ask(&mut s, &mut p, "id");
    assert!(id.starts_with("OK ") && id.ends_with("\r\n"), "{id:?}");
    assert_eq!(id.matches("\r\n").count(), 1);
    let err = ask(&mut s, &mut p, "bogus");
    assert!(err.starts_with("ERR 1 "), "{err:?}");
    p.out.clear();
    for &b in b"stat" {
        s.on_byte(b, &mut p);
    }
    assert!(p.out.is_empty(), "no answer before the line ends");
}

/// A store without an erase leaves the readout running; the store that erases (the first after
/// a sector is full) runs inside one pause of the readout, and says so.
#[test]
fn set_stages_into_the_readout_and_only_an_erasing_store_pauses_it() {
    let (mut s, mut p) = boot(Flash::new());
    assert!(ask(&mut s, &mut p, "set a 1.5").starts_with("ERR 9 "));
    assert_eq!(
        p.readout
            .staged_or_active_compensation()
            .coefficients
            .a_rad_per_s(),
        0.0
    );
    assert!(ask(&mut s, &mut p, &format!("unlock {KEY}")).starts_with("OK unlocked"));
    assert!(ask(&mut s, &mut p, "set a 1.5").starts_with("OK a=1.5"));
    let staged = p.readout.staged_or_active_compensation();
    assert_eq!(staged.coefficients.a_rad_per_s(), 1.5);
    assert!(p.log.is_empty(), "nothing paused the readout yet");
    let stored = ask(&mut s, &mut p, "store");
    assert_eq!(stored, "OK stored seq=1 readout=continuous\r\n");
    assert!(
        p.log.is_empty(),
        "a store without an erase does not pause the readout"
    );
    // 8 KiB sectors: the first fills, the store after it erases the second (blank) sector.
    let per_sector = 8192 / crate::storage::record::RECORD_BYTES;
    for seq in 2..=per_sector {
        let stored = ask(&mut s, &mut p, "store");
        assert_eq!(
            stored,
            format!("OK stored seq={seq} readout=continuous\r\n")
        );
    }
    assert!(p.log.is_empty());
    let stored = ask(&mut s, &mut p, "store");
    assert_eq!(
        stored,
        format!(
            "OK stored seq={} readout=resynchronised\r\n",
            per_sector + 1
        )
    );
    assert_eq!(p.log, "sr", "stopped once, restarted once");
    // The record survives a power cycle and the next boot starts the readout with it.
    let (s2, _) = boot(s.into_flash());
    let booted = Service::boot(config(), s2.into_flash(), Some(9)).unwrap();
    assert_eq!(booted.settings.coefficients.a_rad_per_s(), 1.5);
}

#[test]
fn boot_refuses_a_flash_smaller_than_its_geometry() {
    let small = RamFlash::<1, 8192>::new();
    assert!(Service::boot(config(), small, None).is_err());
}

/// A flash whose programming fails once `fail` is set (a worn or locked sector).
struct FailingFlash {
    inner: Flash,
    fail: bool,
}

impl embedded_storage::nor_flash::ErrorType for FailingFlash {
    type Error = crate::storage::ram_flash::RamFlashError;
}

impl embedded_storage::nor_flash::ReadNorFlash for FailingFlash {
    const READ_SIZE: usize = 1;
    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        self.inner.read(offset, bytes)
    }
    fn capacity(&self) -> usize {
        self.inner.capacity()
    }
}

impl NorFlash for FailingFlash {
    const WRITE_SIZE: usize = 4;
    const ERASE_SIZE: usize = 8192;
    fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        self.inner.erase(from, to)
    }
    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        if self.fail {
            return Err(crate::storage::ram_flash::RamFlashError::OutOfBounds);
        }
        self.inner.write(offset, bytes)
    }
}

/// A store that erases and then fails to program: `ERR 13`, and the pause still ends.
#[test]
fn a_failed_store_is_reported_and_still_restarts_the_readout() {
    use embedded_storage::nor_flash::ReadNorFlash;
    // Sector 0 full: the next store erases sector 1 first.
    let mut inner = Flash::new();
    let store = crate::storage::CalibrationStore::new(&inner, config().geometry).unwrap();
    let per_sector = 8192 / crate::storage::record::RECORD_BYTES;
    for _ in 0..per_sector {
        store
            .store(
                &mut inner,
                &crate::storage::CalibrationRecord::DEFAULTS,
                || (),
            )
            .unwrap();
    }
    let flash = FailingFlash { inner, fail: true };
    let booted = Service::boot(config(), flash, None).unwrap();
    let mut s = booted.service;
    let mut p = TestPorts::new(Readout::new(&s.config().readout, booted.settings));
    p.out.clear();
    let store_crc = crate::protocol::parse::crc16(b"store");
    for &b in format!("unlock {KEY}\nstore*{store_crc:04X}\n").as_bytes() {
        s.on_byte(b, &mut p);
    }
    let answers = StdString::from_utf8(p.out.clone()).unwrap();
    assert!(answers.contains("ERR 13 "), "{answers:?}");
    assert_eq!(p.log, "sr", "the pause ended with the failed store");
    let mut first = [0u8; 4];
    s.flash_mut().read(8192, &mut first).unwrap();
    assert_eq!(first, [0xFF; 4], "nothing programmed");
}

#[test]
fn frames_without_room_are_dropped_whole_and_counted() {
    let (mut s, mut p) = boot(Flash::new());
    assert!(ask(&mut s, &mut p, "stream on").starts_with("\0OK stream=on"));
    p.out.clear();
    s.on_cycle(&record(CycleFlags::empty()), &mut p);
    let frame = p.out.len();
    assert!(
        frame > 10 && p.out.last() == Some(&0),
        "one COBS frame: {frame} bytes"
    );
    p.frame_room = false;
    p.out.clear();
    for _ in 0..3 {
        s.on_cycle(&record(CycleFlags::empty()), &mut p);
    }
    assert!(p.out.is_empty());
    assert_eq!(s.frames_dropped(), 3);
    // While streaming, a text answer is wrapped in 0x00 so the host can tell it from a frame.
    let answer = ask(&mut s, &mut p, "stream off");
    assert!(
        answer.starts_with('\0') && answer.ends_with('\0'),
        "{answer:?}"
    );
}

#[test]
fn status_folds_cycles_and_losses_below_the_readout() {
    let (mut s, mut p) = boot(Flash::new());
    for _ in 0..5 {
        s.on_cycle(&record(CycleFlags::TURNAROUND_MISSED), &mut p);
    }
    let status = ask(&mut s, &mut p, "status");
    assert!(status.contains("missed=5"), "{status}");
    p.missed_below = 40;
    let status = ask(&mut s, &mut p, "status");
    assert!(status.contains("missed=40"), "{status}");
}

#[test]
fn the_intercept_hook_sees_lines_first() {
    let mut c = config();
    c.intercept = Some(|line| line == "quit");
    let booted = Service::boot(c, Flash::new(), None).unwrap();
    let mut s = booted.service;
    let mut p = TestPorts::new(Readout::new(&c.readout, booted.settings));
    for &b in b"quit\n" {
        s.on_byte(b, &mut p);
    }
    assert!(p.out.is_empty(), "consumed, no answer");
    assert!(ask(&mut s, &mut p, "id").starts_with("OK "));
}

/// The wrong-key count survives a reset: three wrong keys (the free ones), a reset, and the
/// right key is refused until the first window, one period (10 s) after boot; then it is in.
/// The count is written only when it changes.
#[test]
fn a_reset_does_not_give_the_free_attempts_back() {
    let (mut s, mut p) = boot(Flash::new());
    for i in 0..3 {
        let answer = ask(&mut s, &mut p, &format!("unlock {}", "12".repeat(16)));
        assert!(answer.starts_with("ERR 15 "), "{i}: {answer}");
        p.now_ms += 3_000;
    }
    assert_eq!((p.backup_wrong_keys, p.backup_writes), (3, 3));
    assert!(ask(&mut s, &mut p, "status").contains("locked=yes"));
    assert_eq!(p.backup_writes, 3, "reads write nothing");
    // Reset: a new service on the same flash, the clock from 0, the backup RAM kept.
    let backup = p.backup_wrong_keys;
    let (mut s, mut p) = boot(s.into_flash());
    s.restore_wrong_keys(backup, 0);
    p.now_ms = 1_000;
    let answer = ask(&mut s, &mut p, &format!("unlock {KEY}"));
    assert_eq!(
        answer.trim_end(),
        "ERR 14 too many attempts, wait wait_ms=9000"
    );
    p.now_ms = 10_000;
    assert!(ask(&mut s, &mut p, &format!("unlock {KEY}")).starts_with("OK unlocked"));
    assert_eq!(
        (p.backup_wrong_keys, p.backup_writes),
        (0, 1),
        "the right key resets it"
    );
}

/// Cycles the board's record queue dropped are counted in `status` and show in the stream as
/// a sequence gap of exactly the frames they were due.
#[test]
fn cycles_lost_before_the_service_show_as_a_gap_and_a_count() {
    let (mut s, mut p) = boot(Flash::new());
    ask(&mut s, &mut p, "stream on 1");
    let mut sequences = Vec::new();
    for i in 0..10 {
        if i == 5 {
            s.on_cycles_lost(3);
        }
        p.out.clear();
        s.on_cycle(&record(CycleFlags::empty()), &mut p);
        let frame = p.out.split(|&b| b == 0).find(|c| !c.is_empty()).unwrap();
        sequences.push(
            crate::protocol::stream::decode_frame(frame)
                .unwrap()
                .sequence,
        );
    }
    let gaps: Vec<u32> = sequences.windows(2).map(|w| w[1] - w[0] - 1).collect();
    assert_eq!(gaps, [0, 0, 0, 0, 3, 0, 0, 0, 0]);
    ask(&mut s, &mut p, "stream off");
    let status = ask(&mut s, &mut p, "status");
    assert!(status.contains(" dropped=3 "), "{status}");
}

/// A record stored for one gyro does not load on a board of another serial number: the
/// defaults are in force, `status` says why, and `reload` refuses it the same way; the board
/// it was stored for still loads it.
#[test]
fn the_calibration_of_another_gyro_does_not_load() {
    let (mut s, mut p) = boot(Flash::new());
    ask(&mut s, &mut p, &format!("unlock {KEY}"));
    assert_eq!(ask(&mut s, &mut p, "set a 12.5").trim_end(), "OK a=12.5");
    assert!(ask(&mut s, &mut p, "store").starts_with("OK stored seq=1"));
    let flash = s.into_flash();
    let mut other = config();
    other.identity.serial_number = 8;
    let booted = Service::boot(other, flash, None).unwrap();
    assert_eq!(booted.settings, CalibrationRecord::DEFAULTS.settings);
    let (mut s, mut p) = (
        booted.service,
        TestPorts::new(Readout::new(&other.readout, booted.settings)),
    );
    let status = ask(&mut s, &mut p, "status");
    assert!(
        status.contains(" coeffs=defaults:other_gyro:7 "),
        "{status}"
    );
    ask(&mut s, &mut p, &format!("unlock {KEY}"));
    assert!(ask(&mut s, &mut p, "reload").starts_with("OK coeffs=defaults:other_gyro:7"));
    assert_eq!(ask(&mut s, &mut p, "get a").trim_end(), "OK a=0");
    let (s, _) = boot(s.into_flash());
    assert_eq!(s.config().identity.serial_number, 7);
    let (mut s, mut p) = (
        s,
        TestPorts::new(Readout::new(&config().readout, Default::default())),
    );
    assert!(ask(&mut s, &mut p, "status").contains(" coeffs=flash:1 "));
}

/// A flood of `reload` (each a scan of both flash sectors): one pass executes one line and
/// returns, so the main loop refreshes its watchdog between any two commands; the rest waits
/// for the next passes, each answered in order.
#[test]
fn a_pass_executes_at_most_one_line() {
    let (mut s, mut p) = boot(Flash::new());
    ask(&mut s, &mut p, &format!("unlock {KEY}"));
    p.out.clear();
    let mut flood: std::collections::VecDeque<u8> = "reload\n".repeat(200).bytes().collect();
    let mut passes = 0;
    while s.pass(&mut p, |_| flood.pop_front(), || None, || None) {
        passes += 1;
        let answers = StdString::from_utf8(p.out.clone()).unwrap();
        assert_eq!(
            answers.matches("\r\n").count(),
            passes.min(200),
            "pass {passes}"
        );
    }
    assert_eq!(passes, 200);
}

/// The board's boot (`power_up`) restores the wrong-key count the backup domain kept: past the
/// free attempts the right key waits for the first window, one period after the boot; after a
/// cold start (count 0) it unlocks at once.
#[test]
fn power_up_restores_the_kept_wrong_key_count() {
    use super::power_up::power_up;
    let boot_ms = 5_000;
    let up = power_up(config(), Flash::new(), 3, boot_ms).unwrap();
    assert_eq!(up.wrong_keys, 3);
    let (mut s, mut p) = (up.service, TestPorts::new(up.readout));
    p.now_ms = boot_ms + 1_000;
    let answer = ask(&mut s, &mut p, &format!("unlock {KEY}"));
    assert_eq!(
        answer.trim_end(),
        "ERR 14 too many attempts, wait wait_ms=9000"
    );
    p.now_ms = boot_ms + 10_000;
    assert!(ask(&mut s, &mut p, &format!("unlock {KEY}")).starts_with("OK unlocked"));
    let cold = power_up(config(), Flash::new(), 0, boot_ms).unwrap();
    let (mut s, mut p) = (cold.service, TestPorts::new(cold.readout));
    p.now_ms = boot_ms;
    assert!(ask(&mut s, &mut p, &format!("unlock {KEY}")).starts_with("OK unlocked"));
}

/// Blank OTP words are serial 0 and no key: the board powers up unprovisioned and no key
/// unlocks it (there is no default key); programmed words give the serial and the key.
#[test]
fn a_board_with_blank_otp_powers_up_without_a_key() {
    use super::power_up::{otp_identity, power_up};
    use crate::otp_record::{self, OtpCells, OtpWriteError, BLANK};
    /// OTP cells in RAM: blocks of 8 words.
    struct Cells([[u32; 8]; 4]);
    impl OtpCells for Cells {
        fn read(&self, block: u32, word: u32) -> u32 {
            self.0[block as usize][word as usize]
        }
        fn locked(&self, _: u32) -> bool {
            false
        }
        fn program(&mut self, block: u32, word: u32, value: u32) -> Result<(), OtpWriteError> {
            self.0[block as usize][word as usize] &= value;
            Ok(())
        }
        fn lock(&mut self, _: u32) -> Result<(), OtpWriteError> {
            Ok(())
        }
    }
    let blank_cells = Cells([[BLANK; 8]; 4]);
    assert_eq!(otp_identity(&blank_cells), (0, None));
    let key = Key::parse_hex(KEY).unwrap();
    let mut cells = Cells([[BLANK; 8]; 4]);
    cells.0[0][0] = 42;
    otp_record::provision(&mut cells, &key).unwrap();
    assert_eq!(otp_identity(&cells), (42, Some(key)));
    let mut blank = config();
    (blank.identity.serial_number, blank.identity.key) = otp_identity(&blank_cells);
    let up = power_up(blank, Flash::new(), 0, 0).unwrap();
    let (mut s, mut p) = (up.service, TestPorts::new(up.readout));
    assert!(ask(&mut s, &mut p, "status").contains(" key=unprovisioned"));
    for given in [KEY, "00000000000000000000000000000000"] {
        let answer = ask(&mut s, &mut p, &format!("unlock {given}"));
        assert!(answer.starts_with("ERR 16 "), "{answer}");
    }
    assert!(ask(&mut s, &mut p, "set a 1").starts_with("ERR 9 "));
}

/// The readout starts with the stored calibration: the compensation in force after power-up
/// is the stored one, and the stored dither setpoints are handed on.
#[test]
fn power_up_starts_the_readout_with_the_stored_calibration() {
    use super::power_up::power_up;
    let (mut s, mut p) = boot(Flash::new());
    ask(&mut s, &mut p, &format!("unlock {KEY}"));
    ask(&mut s, &mut p, "set a 12.5");
    ask(&mut s, &mut p, "comp on");
    assert!(ask(&mut s, &mut p, "store").starts_with("OK stored seq=1"));
    let stored = p.readout.staged_or_active_compensation();
    let up = power_up(config(), s.into_flash(), 0, 0).unwrap();
    assert_eq!(up.readout.staged_or_active_compensation(), stored);
    assert!(stored.enabled);
    assert!(up.dither.is_some());
    assert!(matches!(
        up.report.outcome,
        crate::storage::LoadOutcome::Loaded { sequence: 1 }
    ));
}

/// The board's record queue (32 records) fills while the main loop is busy: the readout task
/// closes 40 cycles, the last 8 are dropped. The main loop's passes then stream the 32 queued
/// cycles with consecutive sequence numbers, and the gap of 8 comes after them, before the
/// next cycle closed: every frame keeps the number of the cycle it carries (a host dates it
/// by that number), and the count is right.
#[test]
fn cycles_dropped_on_a_full_queue_leave_their_gap_after_the_older_records() {
    use super::record_queue::{LossyProducer, Tagged};
    let (mut s, mut p) = boot(Flash::new());
    ask(&mut s, &mut p, "stream on 1");
    p.out.clear();
    let mut queue: heapless::spsc::Queue<Tagged<CycleRecord>, 33> = heapless::spsc::Queue::new();
    let (producer, mut consumer) = queue.split();
    let mut producer = LossyProducer::new(producer);
    let cycle = |i: i64| CycleRecord {
        end_phase: TotalPhase::from_q32(i),
        ..record(CycleFlags::empty())
    };
    let queued = (0..40).filter(|&i| producer.push(cycle(i))).count();
    assert_eq!(queued, 32);
    while s.pass(&mut p, |_| None, || consumer.dequeue(), || None) {}
    assert!(producer.push(cycle(40)));
    while s.pass(&mut p, |_| None, || consumer.dequeue(), || None) {}
    let frames: Vec<(u32, i64)> = p
        .out
        .split(|&b| b == 0)
        .filter(|c| !c.is_empty())
        .map(|c| crate::protocol::stream::decode_frame(c).unwrap())
        .map(|f| (f.sequence, f.end_phase_q32))
        .collect();
    let expected: Vec<(u32, i64)> = (0..32).chain([40]).map(|i| (i as u32, i)).collect();
    assert_eq!(frames, expected);
    ask(&mut s, &mut p, "stream off");
    assert!(ask(&mut s, &mut p, "status").contains(" dropped=8 "));
}

/// The boot count read from the newest record goes up by one per boot and stops at u32::MAX:
/// a record stored at the last count boots into the same count, never 0.
#[test]
fn the_boot_count_saturates() {
    let booted = Service::boot(config(), Flash::new(), Some(u32::MAX)).unwrap();
    let mut s = booted.service;
    let mut p = TestPorts::new(Readout::new(&config().readout, booted.settings));
    ask(&mut s, &mut p, &format!("unlock {KEY}"));
    assert!(ask(&mut s, &mut p, "store").starts_with("OK stored seq=1"));
    let (mut s, mut p) = boot(s.into_flash());
    ask(&mut s, &mut p, &format!("unlock {KEY}"));
    assert!(ask(&mut s, &mut p, "store").starts_with("OK stored seq=2"));
    let mut flash = s.into_flash();
    let store = CalibrationStore::new(&flash, config().geometry).unwrap();
    let (record, _) = store.load_for_serial(&mut flash, 7);
    assert_eq!(record.boot_count, u32::MAX);
}

/// The thermal model set through the protocol (`thermal range|bias|sf`, `thermal apply`), stored
/// with the calibration, is in force again after a power-up, with its switch: applied from the
/// sensor's first result on (the model uses no rate), and the records say so. A model switched
/// off and stored comes back off.
#[test]
fn the_thermal_model_is_stored_and_in_force_after_power_up() {
    use super::power_up::power_up;
    use crate::thermal::sensor::{Reading, SensorState, SensorUpdate};
    use crate::thermal::state::ModelState;
    let (mut s, mut p) = boot(Flash::new());
    ask(&mut s, &mut p, &format!("unlock {KEY}"));
    for line in [
        "thermal set t_ref 25",
        "thermal set t_min -20",
        "thermal set t_max 60",
        "thermal set b0 0.01",
        "thermal set b1 0.002",
        "thermal set b2 2e-5",
        "thermal set s1 0.5",
        "thermal set s2 0.005",
    ] {
        assert!(ask(&mut s, &mut p, line).starts_with("OK "), "{line}");
    }
    let applied = ask(&mut s, &mut p, "thermal apply");
    assert!(applied.starts_with("OK thermal=on t_ref=25 "), "{applied}");
    assert!(ask(&mut s, &mut p, "status").contains(" coeffs=unsaved"));
    let model = s.thermal().model().unwrap();
    assert!(ask(&mut s, &mut p, "store").starts_with("OK stored seq=1"));

    let up = power_up(config(), s.into_flash(), 0, 0).unwrap();
    let (mut s, mut p) = (up.service, TestPorts::new(up.readout));
    assert_eq!(s.thermal().model(), Some(model));
    assert!(s.thermal().enabled());
    assert_eq!(s.thermal().model_state(), ModelState::NoSensor);
    let reading = Reading {
        raw: 45 * 128,
        at_ms: 100,
    };
    s.on_sensor(
        SensorUpdate {
            state: SensorState::Ok,
            reading: Some(reading),
        },
        &mut p,
    );
    assert_eq!(s.thermal().model_state(), ModelState::Applied);
    let answer = ask(&mut s, &mut p, "thermal");
    // x = 20 °C: 0.01 + 0.04 + 0.008 deg/h, 10 + 2 ppm.
    assert!(
        answer.contains(" model=applied bias_deg_h=0.05800 sf_ppm=12.000"),
        "{answer}"
    );

    ask(&mut s, &mut p, &format!("unlock {KEY}"));
    assert!(ask(&mut s, &mut p, "thermal off").starts_with("OK thermal=off"));
    assert!(ask(&mut s, &mut p, "store").starts_with("OK stored seq=2"));
    let up = power_up(config(), s.into_flash(), 0, 0).unwrap();
    assert_eq!(up.service.thermal().model(), Some(model));
    assert!(!up.service.thermal().enabled());
}

/// The thermal edits are protected (locked: `ERR 9`, nothing changes) and, typed without a CRC,
/// wait for `yes`; the reads are neither.
#[test]
fn thermal_edits_are_protected_and_confirmed() {
    let (mut s, mut p) = boot(Flash::new());
    assert!(ask(&mut s, &mut p, "thermal set t_ref 25").starts_with("ERR 9 "));
    assert!(ask(&mut s, &mut p, "thermal model").starts_with("OK thermal=none model=none"));
    let typed = |s: &mut Service<Flash>, p: &mut TestPorts, line: &str| {
        p.out.clear();
        for &b in format!("{line}\n").as_bytes() {
            s.on_byte(b, p);
        }
        StdString::from_utf8(p.out.clone()).unwrap()
    };
    assert!(typed(&mut s, &mut p, "thermal").starts_with("OK temp_c=none"));
    ask(&mut s, &mut p, &format!("unlock {KEY}"));
    let echo = typed(&mut s, &mut p, "thermal set S1 2.5e-1");
    assert!(
        echo.starts_with("ERR 18 confirm (send yes) cmd=thermal set s1 0.25"),
        "{echo}"
    );
    assert!(typed(&mut s, &mut p, "yes").starts_with("OK s1=0.25 model=edited"));
    assert!(ask(&mut s, &mut p, "thermal set t_max 151").starts_with("ERR 5 "));
    assert!(ask(&mut s, &mut p, "thermal set x 1").starts_with("ERR 2 "));
}
