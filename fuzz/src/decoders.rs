//! The `decoders` target: arbitrary bytes to everything that decodes what arrives from outside
//! or from flash: the COBS envelope, the cycle and output frame decoders, the calibration
//! record decoder, and the store's log scan over a flash holding the bytes.
//!
//! Checked, besides no panic:
//! - `cobs::decode` for every payload length it serves, and the three frame decoders (cycle,
//!   output record, thermal): what decodes
//!   encodes back to exactly the bytes given (the encoding is canonical, so nothing else can
//!   pass for a frame);
//! - `record::decode`: a record it accepts passes its own checks and survives
//!   `encode`/`decode` unchanged;
//! - the log scan over two small sectors holding the bytes (and one holding them at an offset):
//!   loading never panics, and a store that succeeds after it is what the next load returns
//!   (a calibration survives whatever the flash held before).

use embedded_storage::nor_flash::NorFlash;
use firmware::protocol::cobs;
use firmware::protocol::output_frame::{
    decode_output_frame, encode_output_frame, MAX_OUTPUT_FRAME,
};
use firmware::protocol::stream::{decode_frame, encode_frame, MAX_FRAME};
use firmware::protocol::thermal_frame::{
    decode_thermal_frame, encode_thermal_frame, THERMAL_FRAME,
};
use firmware::signal::compensation::{Coefficients, CompensationSettings};
use firmware::storage::ram_flash::RamFlash;
use firmware::storage::record::{self, CalibrationRecord};
use firmware::storage::{CalibrationStore, Geometry, LoadOutcome, ReadoutPaused};

/// The payload lengths the protocol's frames use, and the envelope's limits.
const PAYLOAD_LENGTHS: [usize; 7] = [0, 1, 12, 38, 41, 248, 249];

fn check_envelope(data: &[u8]) {
    for len in PAYLOAD_LENGTHS {
        let mut payload = vec![0u8; len];
        if cobs::decode(data, &mut payload).is_ok() {
            let mut again = vec![0u8; len + 6];
            let n = cobs::encode(&payload, &mut again);
            assert_eq!(&again[..n - 1], data, "COBS is canonical");
        }
    }
    if let Ok(record) = decode_frame(data) {
        let mut again = [0u8; MAX_FRAME];
        let n = encode_frame(&record, &mut again);
        assert_eq!(&again[..n - 1], data, "a cycle frame re-encodes to itself");
    }
    if let Ok(record) = decode_output_frame(data) {
        let mut again = [0u8; MAX_OUTPUT_FRAME];
        let n = encode_output_frame(&record, &mut again);
        assert_eq!(
            &again[..n - 1],
            data,
            "an output frame re-encodes to itself"
        );
    }
    if let Ok(frame) = decode_thermal_frame(data) {
        let mut again = [0u8; THERMAL_FRAME];
        let n = encode_thermal_frame(&frame, &mut again);
        assert_eq!(
            &again[..n - 1],
            data,
            "a thermal frame re-encodes to itself"
        );
    }
}

fn check_record(data: &[u8]) {
    if let Ok((sequence, decoded)) = record::decode(data) {
        assert!(decoded.check().is_ok(), "{decoded:?}");
        let again = record::encode(&decoded, sequence);
        assert_eq!(record::decode(&again), Ok((sequence, decoded)));
    }
}

const SECTOR: usize = 512;

/// Two sectors holding `data` from `offset` on (the rest erased), scanned, then one store.
fn check_scan(data: &[u8], offset: usize) {
    let mut flash = RamFlash::<2, SECTOR>::new();
    let room = 2 * SECTOR - offset;
    // Whole words only (the NOR model programs words); programming ANDs into 0xFF: the bytes.
    let len = data.len().min(room) & !3;
    if len > 0 {
        flash.write(offset as u32, &data[..len]).expect("in bounds");
    }
    let geometry = Geometry {
        base_offset: 0,
        sector_bytes: SECTOR as u32,
    };
    let store = CalibrationStore::new(&flash, geometry).expect("the geometry fits");
    let _ = store.load(&mut flash);
    let _ = store.load_for_serial(&mut flash, 7);
    let record = CalibrationRecord {
        serial_number: 7,
        boot_count: 3,
        settings: CompensationSettings {
            coefficients: Coefficients {
                a_q16: 12 << 16,
                b_q16: -(5 << 16),
            },
            enabled: true,
        },
        ..CalibrationRecord::DEFAULTS
    };
    let paused = ReadoutPaused::assume_paused();
    if let Ok(sequence) = store.store_while_paused(&mut flash, &paused, &record) {
        let (loaded, report) = store.load_for_serial(&mut flash, 7);
        assert_eq!(
            report.outcome,
            LoadOutcome::Loaded { sequence },
            "{report:?}"
        );
        assert_eq!(loaded.settings, record.settings);
    }
}

/// Runs the decoders over `data` (panics on a broken promise).
pub fn check(data: &[u8]) {
    check_envelope(data);
    check_record(data);
    check_scan(data, 0);
    check_scan(data, SECTOR - 48);
}
