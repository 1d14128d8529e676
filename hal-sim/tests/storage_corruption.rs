//! Damaged and unusual flash contents: bit flips in every bit of a record, stray bits in erased
//! flash, a fresh board, both sectors garbage, records of the older format version 1 and of an
//! unknown newer one, reset to
//! defaults, refused records and a flash that programs wrongly.
//!
//! Every case ends with a store that loads: the store always recovers to a known state.
//! Tolerances: the store and the flash model are deterministic (seeded), so records, sequence
//! numbers, outcomes and bytes are compared exactly; the one floating check states its bound.

mod storage_support;

use embedded_storage::nor_flash::{ErrorType, NorFlash, ReadNorFlash};
use firmware::calibration::fit::FitResult;
use firmware::storage::record::{self, offset, RECORD_BYTES};
use firmware::storage::{
    CalibrationRecord, CalibrationStore, DefaultsReason, FitSummary, LoadOutcome, RecordError,
    SkippedFrame, StoreError,
};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use storage_support::*;

/// Stores records 0..n; returns their sequence numbers.
fn store_n(flash: &mut SmallFlash, store: &CalibrationStore, n: u64) -> Vec<u32> {
    (0..n)
        .map(|i| {
            store
                .store_while_paused(flash, &paused(), &record(i))
                .unwrap()
        })
        .collect()
}

fn defaults_because(reason: DefaultsReason) -> LoadOutcome {
    LoadOutcome::Defaults { reason }
}

#[test]
fn fresh_board_loads_defaults_with_flag() {
    let (mut flash, store) = small_flash(10);
    let (loaded, report) = store.load(&mut flash);
    assert_eq!(loaded, CalibrationRecord::DEFAULTS);
    assert_eq!(report.outcome, defaults_because(DefaultsReason::Erased));
    assert_eq!((report.damaged_bytes, report.newer_format), (0, None));
    // The real geometry too.
    let (mut flash, store) = full_flash(10);
    assert_eq!(
        store.load(&mut flash).1.outcome,
        defaults_because(DefaultsReason::Erased)
    );
    // First store: no erase needed on a blank board.
    let sequence = store
        .store_while_paused(&mut flash, &paused(), &record(0))
        .unwrap();
    assert_eq!(sequence, 1);
    assert_eq!(flash.stats().erases_per_sector, vec![0, 0]);
    assert_is(&store.load(&mut flash), 1, &record(0), "first store");
}

/// While the power is off every read fails: load reports it instead of guessing; after the
/// reboot the same flash loads normally.
#[test]
fn unreadable_flash_gives_defaults_read_failed() {
    let (mut flash, store) = small_flash(23);
    store_n(&mut flash, &store, 2);
    flash.power_off();
    let (loaded, report) = store.load(&mut flash);
    assert_eq!(loaded, CalibrationRecord::DEFAULTS);
    assert_eq!(report.outcome, defaults_because(DefaultsReason::ReadFailed));
    flash.power_on();
    assert_is(&store.load(&mut flash), 2, &record(1), "after power on");
}

/// Flips each of the 512 bits of the newest record (third in sector 0: header, body, CRC and
/// commit marker alike): the one before it loads, nothing else is touched, and the next store
/// (reusing the damaged record's sequence number, which never became valid) loads.
#[test]
fn every_bit_flip_in_newest_record_falls_back_to_previous() {
    let (mut flash, store) = small_flash(11);
    let sequences = store_n(&mut flash, &store, 3);
    let newest_at = 2 * RECORD_BYTES;
    let image = flash.snapshot();
    for bit in 0..RECORD_BYTES * 8 {
        flash.restore(&image);
        flash.corrupt(newest_at + bit / 8, 1 << (bit % 8));
        let context = format!("bit {bit}");
        let loaded = store.load(&mut flash);
        assert_is(&loaded, sequences[1], &record(1), &context);
        assert!(loaded.1.damaged_bytes > 0, "{context}");

        let damaged = flash.snapshot();
        let sequence = store
            .store_while_paused(&mut flash, &paused(), &record(50))
            .unwrap();
        assert_eq!(sequence, sequences[2], "{context}");
        assert_is(&store.load(&mut flash), sequence, &record(50), &context);
        let after = flash.snapshot();
        let new_at = newest_at + RECORD_BYTES;
        assert_eq!(
            after[..new_at],
            damaged[..new_at],
            "{context}: older bytes changed"
        );
    }
}

/// Bit flips in older records do not matter while the newest is intact.
#[test]
fn flips_in_older_records_are_ignored() {
    let (mut flash, store) = small_flash(12);
    let sequences = store_n(&mut flash, &store, 12); // 8 in sector 0, 4 in sector 1
    for record_index in [0, 3, 7, 8, 10] {
        flash.corrupt(record_index * RECORD_BYTES + 21, 0x10);
    }
    let loaded = store.load(&mut flash);
    assert_is(&loaded, sequences[11], &record(11), "older flips");
    assert_eq!(loaded.1.damaged_bytes, 5 * RECORD_BYTES as u32);
}

/// A stray programmed bit in erased flash (after the newest record): the next store goes past
/// it instead of programming over it.
#[test]
fn stray_bit_in_erased_flash_is_skipped() {
    let (mut flash, store) = small_flash(13);
    store_n(&mut flash, &store, 2);
    let stray_at = 2 * RECORD_BYTES + 5;
    flash.corrupt(stray_at, 0x04);
    let loaded = store.load(&mut flash);
    assert_eq!(loaded.1.outcome, LoadOutcome::Loaded { sequence: 2 });
    assert_eq!(loaded.1.damaged_bytes, 16);
    let sequence = store
        .store_while_paused(&mut flash, &paused(), &record(9))
        .unwrap();
    assert_is(
        &store.load(&mut flash),
        sequence,
        &record(9),
        "after stray bit",
    );
    assert_eq!(
        flash.contents()[stray_at],
        0xFF ^ 0x04,
        "stray byte reprogrammed"
    );
}

/// Every record in both sectors damaged: defaults with the flag; the next store erases a
/// sector if none has room, and loads.
#[test]
fn both_sectors_corrupted_gives_defaults_then_recovers() {
    let (mut flash, store) = small_flash(14);
    store_n(&mut flash, &store, 16); // both sectors full
    for record_index in 0..16 {
        flash.corrupt(record_index * RECORD_BYTES + offset::CRC, 0x01);
    }
    let (loaded, report) = store.load(&mut flash);
    assert_eq!(loaded, CalibrationRecord::DEFAULTS);
    assert_eq!(
        report.outcome,
        defaults_because(DefaultsReason::NoValidRecord)
    );
    assert_eq!(report.damaged_bytes, 2 * SMALL_SECTOR as u32);
    let sequence = store
        .store_while_paused(&mut flash, &paused(), &record(20))
        .unwrap();
    assert_eq!(sequence, 1, "no valid sequence number survived");
    assert_is(&store.load(&mut flash), 1, &record(20), "after recovery");
}

/// Random bytes everywhere (a board whose calibration sectors held something else).
#[test]
fn random_garbage_gives_defaults_then_recovers() {
    let (mut flash, store) = small_flash(15);
    let mut rng = ChaCha8Rng::seed_from_u64(16);
    let garbage: Vec<u8> = (0..2 * SMALL_SECTOR).map(|_| rng.random()).collect();
    flash.restore(&garbage);
    let (loaded, report) = store.load(&mut flash);
    assert_eq!(loaded, CalibrationRecord::DEFAULTS);
    assert_eq!(
        report.outcome,
        defaults_because(DefaultsReason::NoValidRecord)
    );
    let sequence = store
        .store_while_paused(&mut flash, &paused(), &record(3))
        .unwrap();
    assert_is(
        &store.load(&mut flash),
        sequence,
        &record(3),
        "after garbage",
    );
}

/// A frame of a newer format (version 5, 128 bytes, valid CRC and marker) between records of
/// this firmware's: skipped by its length and reported, the older record loads, and neither
/// load nor the next stores touch it; new records are numbered above it.
#[test]
fn unknown_format_version_is_skipped_not_destroyed() {
    let (mut flash, store) = small_flash(17);
    store_n(&mut flash, &store, 1);
    let v5_at = RECORD_BYTES;
    let v5 = version_5_frame(2);
    flash.write(v5_at as u32, &v5).unwrap();

    let (loaded, report) = store.load(&mut flash);
    assert_is(&(loaded, report), 1, &record(0), "v4 under v5");
    let skipped = Some(SkippedFrame {
        version: 5,
        sequence: 2,
    });
    assert_eq!(report.newer_format, skipped);
    assert_eq!((report.damaged_bytes, report.rejected_records), (0, 0));

    for i in 0..3 {
        let sequence = store
            .store_while_paused(&mut flash, &paused(), &record(10 + i))
            .unwrap();
        assert_eq!(sequence, 3 + i as u32, "numbered above the v5 frame");
        let loaded = store.load(&mut flash);
        assert_is(&loaded, sequence, &record(10 + i), "after v5");
        assert_eq!(loaded.1.newer_format, skipped);
    }
    assert_eq!(
        &flash.contents()[v5_at..v5_at + v5.len()],
        &v5[..],
        "v5 frame changed"
    );
}

/// A board updated from the firmware that wrote format version 1 (64 bytes, no dither
/// setpoints): its newest version-1 record loads (dither setpoints absent: the board's defaults
/// apply), the next store writes the current version (4) numbered above it, and the version-1
/// records stay untouched until their sector is erased for a wrap.
#[test]
fn version_1_records_load_and_the_next_store_writes_the_current_version() {
    let (mut flash, store) = small_flash(21);
    let mut old = record(30);
    old.dither = None;
    old.strip = None;
    old.thermal = None;
    let v1 = version_1_frame(&old, 5);
    flash.write(0, &v1).unwrap();
    flash
        .write(v1.len() as u32, &version_1_frame(&old, 4))
        .unwrap();
    let (loaded, report) = store.load(&mut flash);
    assert_eq!(loaded, old);
    assert_eq!(report.outcome, LoadOutcome::Loaded { sequence: 5 });
    assert_eq!((report.rejected_records, report.newer_format), (0, None));

    let mut new = record(31);
    new.dither = Some(firmware::storage::DitherSetpoints {
        enabled: true,
        amplitude_arcsec: 420.0,
        noise_percent: 10.0,
    });
    let sequence = store
        .store_while_paused(&mut flash, &paused(), &new)
        .unwrap();
    assert_eq!(sequence, 6, "numbered above the version-1 records");
    assert_is(&store.load(&mut flash), 6, &new, "v4 above v1");
    assert_eq!(&flash.contents()[..v1.len()], &v1[..], "v1 record changed");
    assert_eq!(
        flash.contents()[2 * v1.len() + offset::VERSION],
        record::FORMAT_VERSION
    );
}

/// A board updated from the firmware that wrote format version 3 (96 bytes, no thermal model):
/// its record loads with no thermal model, the next store (with one) writes version 4 above it
/// and leaves it untouched.
#[test]
fn version_3_records_load_and_the_next_store_writes_version_4() {
    let (mut flash, store) = small_flash(22);
    let mut old = record(40);
    old.thermal = None;
    let v4 = record::encode(&old, 9);
    let mut v3 = vec![0u8; record::V3_RECORD_BYTES];
    v3[..offset::V3_CRC].copy_from_slice(&v4[..offset::V3_CRC]);
    v3[offset::VERSION] = record::V3_FORMAT_VERSION;
    v3[offset::LENGTH_WORDS] = (record::V3_RECORD_BYTES / 4) as u8;
    record::seal(&mut v3);
    flash.write(0, &v3).unwrap();
    let (loaded, report) = store.load(&mut flash);
    assert_eq!(loaded, old);
    assert_eq!(report.outcome, LoadOutcome::Loaded { sequence: 9 });
    let mut new = record(41);
    new.thermal = record(42).thermal.or(record(43).thermal);
    assert!(new.thermal.is_some());
    let sequence = store
        .store_while_paused(&mut flash, &paused(), &new)
        .unwrap();
    assert_eq!(sequence, 10);
    assert_is(&store.load(&mut flash), 10, &new, "v4 above v3");
    assert_eq!(&flash.contents()[..v3.len()], &v3[..], "v3 record changed");
    assert_eq!(
        flash.contents()[v3.len() + offset::VERSION],
        record::FORMAT_VERSION
    );
}

/// A version-1 frame of `record` (no dither setpoints), as the firmware before format 2 wrote
/// it: the version-2 bytes up to the fit, then CRC and marker.
fn version_1_frame(record: &CalibrationRecord, sequence: u32) -> Vec<u8> {
    let v2 = record::encode(record, sequence);
    let mut frame = vec![0u8; record::V1_RECORD_BYTES];
    frame[..offset::V1_CRC].copy_from_slice(&v2[..offset::V1_CRC]);
    frame[offset::VERSION] = record::V1_FORMAT_VERSION;
    frame[offset::LENGTH_WORDS] = (record::V1_RECORD_BYTES / 4) as u8;
    record::seal(&mut frame);
    frame
}

/// Only an unknown-version frame: defaults, flagged, with the frame reported.
#[test]
fn only_unknown_format_gives_defaults() {
    let (mut flash, store) = small_flash(18);
    flash.write(0, &version_5_frame(7)).unwrap();
    let (loaded, report) = store.load(&mut flash);
    assert_eq!(loaded, CalibrationRecord::DEFAULTS);
    assert_eq!(
        report.outcome,
        defaults_because(DefaultsReason::NoValidRecord)
    );
    assert_eq!(report.newer_format.map(|f| f.sequence), Some(7));
}

/// A frame of format version 5 (unknown to this firmware), 128 bytes: the
/// version-independent frame with some body.
fn version_5_frame(sequence: u32) -> Vec<u8> {
    let mut frame = vec![0x42u8; 128];
    frame[offset::MAGIC..offset::MAGIC + 2].copy_from_slice(&record::MAGIC.to_le_bytes());
    frame[offset::VERSION] = 5;
    frame[offset::LENGTH_WORDS] = 32;
    frame[offset::SEQUENCE..offset::SEQUENCE + 4].copy_from_slice(&sequence.to_le_bytes());
    record::seal(&mut frame);
    frame
}

/// reset_to_defaults writes a record like any other: load reports it as defaults with its
/// sequence number; a later calibration store wins again.
#[test]
fn reset_to_defaults_then_store_again() {
    let (mut flash, store) = small_flash(19);
    store_n(&mut flash, &store, 2);
    let sequence = store
        .reset_to_defaults(&mut flash, &paused(), 1000, 77)
        .unwrap();
    let (loaded, report) = store.load(&mut flash);
    assert_eq!(
        report.outcome,
        defaults_because(DefaultsReason::Reset { sequence })
    );
    assert_eq!(loaded.settings, CalibrationRecord::DEFAULTS.settings);
    assert_eq!((loaded.serial_number, loaded.boot_count), (1000, 77));
    let sequence = store
        .store_while_paused(&mut flash, &paused(), &record(5))
        .unwrap();
    assert_is(&store.load(&mut flash), sequence, &record(5), "after reset");
}

/// A record that fails its checks is refused before anything is written.
#[test]
fn implausible_record_is_refused_without_writing() {
    let (mut flash, store) = small_flash(20);
    store_n(&mut flash, &store, 1);
    let image = flash.snapshot();
    let mut bad = record(1);
    bad.fit = Some(FitSummary {
        condition_number: f32::NAN,
        ..FitSummary::default()
    });
    let result = store.store_while_paused(&mut flash, &paused(), &bad);
    assert_eq!(result, Err(StoreError::Record(RecordError::ImplausibleFit)));
    assert_eq!(flash.snapshot(), image);
}

/// A real fit result goes through the f32 summary and comes back as stored.
#[test]
fn fit_summary_round_trips_through_flash() {
    let fit = FitResult {
        a_rad_per_s: 3.1,
        b_rad_per_s: 2.9,
        a_std_rad_per_s: 1.25e-3,
        b_std_rad_per_s: 1.5e-3,
        lock_in_rad_per_s: 4.245,
        eps_rad: -0.0333,
        variance_reduction: 0.981,
        condition_number: 1.04,
        residual_std_rad: 2.2e-4,
        mean_rate_rad_per_s: 130.5,
        cycles: 5_000_000_000, // saturates at u32::MAX
        runs: 6,
    };
    let summary = FitSummary::from_fit(&fit);
    assert_eq!(summary.cycles, u32::MAX);
    let mut calibration = record(0);
    calibration.fit = Some(summary);
    calibration.settings.coefficients =
        firmware::signal::compensation::Coefficients::from_rad_per_s(
            fit.a_rad_per_s as f32,
            fit.b_rad_per_s as f32,
        )
        .unwrap();
    let (mut flash, store) = small_flash(21);
    let sequence = store
        .store_while_paused(&mut flash, &paused(), &calibration)
        .unwrap();
    let loaded = store.load(&mut flash);
    assert_is(&loaded, sequence, &calibration, "fit");
    // Omega_L and eps from the stored Q15.16 coefficients: within their rounding (2^-16 rad/s,
    // so a relative 1e-5 of 4.2 rad/s) and f32 evaluation.
    let lock_in = loaded.0.lock_in_rad_per_s() as f64;
    assert!((lock_in - fit.a_rad_per_s.hypot(fit.b_rad_per_s)).abs() < 1e-4);
    let eps = fit.b_rad_per_s.atan2(fit.a_rad_per_s) - std::f64::consts::FRAC_PI_4;
    assert!((loaded.0.eps_rad() as f64 - eps).abs() < 1e-5);
}

/// A flash with a bit that cannot be programmed at one offset (a worn cell): the store's
/// read-back catches it before the commit marker, the previous record still loads, and the
/// next store goes past the damaged record.
#[test]
fn verify_catches_a_cell_that_does_not_program() {
    let (flash, store) = small_flash(22);
    let mut flash = StuckBit {
        inner: flash,
        // The magic's high byte, 0xCA: its bit 0 must be programmed to 0.
        offset: 2 * RECORD_BYTES as u32 + 1,
    };
    for i in 0..2 {
        store
            .store_while_paused(&mut flash, &paused(), &record(i))
            .unwrap();
    }
    let result = store.store_while_paused(&mut flash, &paused(), &record(2));
    assert_eq!(
        result,
        Err(StoreError::Verify {
            offset: 2 * RECORD_BYTES as u32
        })
    );
    let loaded = store.load(&mut flash);
    assert_is(&loaded, 2, &record(1), "after failed verify");
    let committed = record::get_u32(flash.inner.contents(), 2 * RECORD_BYTES + offset::COMMIT);
    assert_eq!(
        committed,
        u32::MAX,
        "marker programmed after a failed verify"
    );
    let sequence = store
        .store_while_paused(&mut flash, &paused(), &record(3))
        .unwrap();
    assert_is(&store.load(&mut flash), sequence, &record(3), "next store");
}

/// Wraps the flash model; bit 0 of the byte at `offset` stays 1 whatever is programmed.
struct StuckBit {
    inner: SmallFlash,
    offset: u32,
}

impl ErrorType for StuckBit {
    type Error = <SmallFlash as ErrorType>::Error;
}

impl ReadNorFlash for StuckBit {
    const READ_SIZE: usize = SmallFlash::READ_SIZE;
    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        self.inner.read(offset, bytes)
    }
    fn capacity(&self) -> usize {
        self.inner.capacity()
    }
}

impl NorFlash for StuckBit {
    const WRITE_SIZE: usize = SmallFlash::WRITE_SIZE;
    const ERASE_SIZE: usize = SmallFlash::ERASE_SIZE;
    fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        self.inner.erase(from, to)
    }
    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        let mut bytes = bytes.to_vec();
        if (offset..offset + bytes.len() as u32).contains(&self.offset) {
            bytes[(self.offset - offset) as usize] |= 0x01;
        }
        self.inner.write(offset, &bytes)
    }
}
