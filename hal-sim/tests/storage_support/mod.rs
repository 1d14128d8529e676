//! Shared by the `storage_*` tests: flash setups, distinct records, and the checks that a load
//! returned exactly a given record.
#![allow(dead_code)]

use firmware::signal::compensation::{Coefficients, CompensationSettings};
use firmware::storage::{
    CalibrationRecord, CalibrationStore, DitherSetpoints, FitSummary, Geometry, LoadOutcome,
    LoadReport, ReadoutPaused,
};
use hal_sim::flash::{CalibrationFlash, SimFlash};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// A small sector so that sector switches come every 8 records and exhaustive loops over many
/// switches stay fast. The scheme does not depend on the sector size.
pub const SMALL_SECTOR: usize = 8 * firmware::storage::record::RECORD_BYTES;
pub type SmallFlash = SimFlash<SMALL_SECTOR, false>;

pub fn small_flash(seed: u64) -> (SmallFlash, CalibrationStore) {
    let flash = SmallFlash::new(2, seed);
    let geometry = Geometry {
        base_offset: 0,
        sector_bytes: SMALL_SECTOR as u32,
    };
    let store = CalibrationStore::new(&flash, geometry).unwrap();
    (flash, store)
}

/// The real geometry: two 128 KiB sectors of the F405.
pub fn full_flash(seed: u64) -> (CalibrationFlash, CalibrationStore) {
    let flash = CalibrationFlash::new(2, seed);
    let store = CalibrationStore::new(&flash, Geometry::F405_CALIBRATION_AREA).unwrap();
    (flash, store)
}

pub fn paused() -> ReadoutPaused {
    ReadoutPaused::assume_paused()
}

/// A plausible record, different for every `i` (seeded: the same `i` gives the same record).
pub fn record(i: u64) -> CalibrationRecord {
    let mut rng = ChaCha8Rng::seed_from_u64(0x5EED_0000 + i);
    let fit = rng.random_bool(0.7).then(|| FitSummary {
        cycles: rng.random(),
        runs: rng.random_range(1..10),
        a_std_rad_per_s: rng.random_range(0.0..1e-2),
        b_std_rad_per_s: rng.random_range(0.0..1e-2),
        residual_std_rad: rng.random_range(0.0..1e-3),
        variance_reduction: rng.random_range(-0.5..1.0),
        condition_number: rng.random_range(1.0..100.0),
        mean_rate_rad_per_s: rng.random_range(-1e3..1e3),
    });
    let settings = CompensationSettings {
        coefficients: Coefficients {
            a_q16: rng.random_range(-(1 << 26)..(1 << 26)),
            b_q16: rng.random_range(-(1 << 26)..(1 << 26)),
        },
        enabled: rng.random_bool(0.8),
    };
    let dither = rng.random_bool(0.6).then(|| DitherSetpoints {
        enabled: rng.random_bool(0.9),
        amplitude_arcsec: rng.random_range(50.0..1000.0),
        noise_percent: rng.random_range(0.0..30.0),
    });
    let strip = rng.random_bool(0.6).then(|| {
        firmware::storage::StripCoefficients::from_fringes_per_code(
            rng.random_range(0.05..0.5),
            rng.random_range(-0.01..0.01),
        )
        .expect("in range")
    });
    let thermal = rng.random_bool(0.6).then(|| {
        let reference_c: f32 = rng.random_range(15.0..35.0);
        firmware::storage::ThermalCalibration {
            model: firmware::thermal::model::ThermalModel {
                reference_c,
                min_c: reference_c - rng.random_range(10.0..60.0),
                max_c: reference_c + rng.random_range(10.0..60.0),
                bias_deg_h: [
                    rng.random_range(-0.1..0.1),
                    rng.random_range(-0.01..0.01),
                    rng.random_range(-1e-4..1e-4),
                    rng.random_range(-1e-6..1e-6),
                ],
                bias_deg_h_per_c_per_min: rng.random_range(-0.01..0.01),
                scale_ppm: [
                    rng.random_range(-10.0..10.0),
                    rng.random_range(-2.0..2.0),
                    rng.random_range(-0.02..0.02),
                ],
            },
            enabled: rng.random_bool(0.8),
        }
    });
    CalibrationRecord {
        serial_number: 1000 + (i as u32 % 3),
        boot_count: i as u32,
        settings,
        fit,
        reset_to_defaults: false,
        dither,
        strip,
        thermal,
    }
}

/// The outcome a load of this (sequence, record) must report.
pub fn outcome_of(sequence: u32, record: &CalibrationRecord) -> LoadOutcome {
    if record.reset_to_defaults {
        let reason = firmware::storage::DefaultsReason::Reset { sequence };
        LoadOutcome::Defaults { reason }
    } else {
        LoadOutcome::Loaded { sequence }
    }
}

/// The sequence number a load reports, if it found a record.
pub fn loaded_sequence(report: &LoadReport) -> Option<u32> {
    match report.outcome {
        LoadOutcome::Loaded { sequence } => Some(sequence),
        LoadOutcome::Defaults {
            reason: firmware::storage::DefaultsReason::Reset { sequence },
        } => Some(sequence),
        LoadOutcome::Defaults { .. } => None,
    }
}

/// Asserts that `loaded` is exactly `(sequence, record)`.
pub fn assert_is(
    loaded: &(CalibrationRecord, LoadReport),
    sequence: u32,
    record: &CalibrationRecord,
    context: &str,
) {
    assert_eq!(loaded.1.outcome, outcome_of(sequence, record), "{context}");
    assert_eq!(&loaded.0, record, "{context}");
}
