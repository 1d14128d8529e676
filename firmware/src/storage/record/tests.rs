//! The record's tests: round trips of the four format versions, the documented layout, every
//! single bit flip refused, the plausibility checks.

use super::*;

fn sample() -> CalibrationRecord {
    CalibrationRecord {
        serial_number: 0x1234_5678,
        boot_count: 42,
        settings: CompensationSettings {
            coefficients: Coefficients {
                a_q16: 12_345_678,
                b_q16: -7_654_321,
            },
            enabled: true,
        },
        fit: Some(FitSummary {
            cycles: 1_000_000,
            runs: 4,
            a_std_rad_per_s: 1.5e-3,
            b_std_rad_per_s: 2.5e-3,
            residual_std_rad: 3e-4,
            variance_reduction: 0.93,
            condition_number: 1.7,
            mean_rate_rad_per_s: -12.5,
        }),
        reset_to_defaults: false,
        dither: Some(DitherSetpoints {
            enabled: true,
            amplitude_arcsec: 450.0,
            noise_percent: 12.5,
        }),
        strip: StripCoefficients::from_fringes_per_code(0.2144199, -0.0012),
        thermal: Some(ThermalCalibration {
            model: thermal_model(),
            enabled: true,
        }),
    }
}

fn thermal_model() -> ThermalModel {
    ThermalModel {
        reference_c: 25.0,
        min_c: -20.0,
        max_c: 60.0,
        bias_deg_h: [0.001, 0.002, 2e-5, -1.25e-7],
        bias_deg_h_per_c_per_min: 0.002,
        scale_ppm: [0.1, 0.5, 0.005],
    }
}

/// The version-3 bytes of a record without a thermal model (what the firmware before the
/// thermal model wrote).
fn encode_v3(record: &CalibrationRecord, sequence: u32) -> [u8; V3_RECORD_BYTES] {
    assert!(record.thermal.is_none());
    let v4 = encode(record, sequence);
    let mut bytes = [0u8; V3_RECORD_BYTES];
    bytes[..offset::V3_CRC].copy_from_slice(&v4[..offset::V3_CRC]);
    bytes[offset::VERSION] = V3_FORMAT_VERSION;
    bytes[offset::LENGTH_WORDS] = (V3_RECORD_BYTES / 4) as u8;
    seal(&mut bytes);
    bytes
}

/// The version-2 bytes of a record without stripping coefficients (what the firmware of issue
/// 12 wrote).
fn encode_v2(record: &CalibrationRecord, sequence: u32) -> [u8; V2_RECORD_BYTES] {
    assert!(record.strip.is_none() && record.thermal.is_none());
    let v3 = encode(record, sequence);
    let mut bytes = [0u8; V2_RECORD_BYTES];
    bytes[..offset::V2_CRC].copy_from_slice(&v3[..offset::V2_CRC]);
    bytes[offset::VERSION] = V2_FORMAT_VERSION;
    bytes[offset::LENGTH_WORDS] = (V2_RECORD_BYTES / 4) as u8;
    seal(&mut bytes);
    bytes
}

/// The version-1 bytes of a record without dither setpoints (what older firmware wrote).
fn encode_v1(record: &CalibrationRecord, sequence: u32) -> [u8; V1_RECORD_BYTES] {
    assert!(record.dither.is_none() && record.strip.is_none() && record.thermal.is_none());
    let v2 = encode(record, sequence);
    let mut bytes = [0u8; V1_RECORD_BYTES];
    bytes[..offset::V1_CRC].copy_from_slice(&v2[..offset::V1_CRC]);
    bytes[offset::VERSION] = V1_FORMAT_VERSION;
    bytes[offset::LENGTH_WORDS] = (V1_RECORD_BYTES / 4) as u8;
    seal(&mut bytes);
    bytes
}

#[test]
fn round_trip() {
    for record in [
        sample(),
        CalibrationRecord::DEFAULTS,
        CalibrationRecord::reset(7, 9),
    ] {
        let bytes = encode(&record, 99);
        assert_eq!(decode(&bytes), Ok((99, record)));
    }
}

#[test]
fn layout_is_little_endian_at_documented_offsets() {
    let bytes = encode(&sample(), 0x0102_0304);
    assert_eq!(&bytes[..4], &[0x1B, 0xCA, 4, 36]);
    assert_eq!(&bytes[4..8], &[4, 3, 2, 1]);
    assert_eq!(&bytes[8..12], &[0x78, 0x56, 0x34, 0x12]);
    assert_eq!(&bytes[56..60], &450.0f32.to_le_bytes());
    assert_eq!(&bytes[60..64], &12.5f32.to_le_bytes());
    assert_eq!(
        bytes[25], 0b11_1101,
        "fit, dither, stripping present, quadrature tap, thermal model"
    );
    assert_eq!(&bytes[64..72], &[1, 0, 0, 0, 0, 0, 0, 0]);
    // K = 0.2144199 in Q8.24: round(0.2144199 * 2^24) = 3597369.
    assert_eq!(get_u32(&bytes, offset::STRIP_K) as i32, 3_597_369);
    assert_eq!(get_u32(&bytes, offset::STRIP_K_QUADRATURE) as i32, -20_133);
    assert_eq!(&bytes[80..88], &[0; 8]);
    assert_eq!(&bytes[88..92], &[1, 0, 0, 0], "thermal model applied");
    assert_eq!(&bytes[92..96], &25.0f32.to_le_bytes(), "t_ref");
    assert_eq!(&bytes[104..108], &0.001f32.to_le_bytes(), "b0");
    assert_eq!(&bytes[116..120], &(-1.25e-7f32).to_le_bytes(), "b3");
    assert_eq!(&bytes[132..136], &0.005f32.to_le_bytes(), "s2");
    assert_eq!(get_u32(&bytes, offset::CRC), crc32(&bytes[..136]));
    assert_eq!(get_u32(&bytes, offset::COMMIT), COMMIT_MARKER);
}

/// A version-3 record (no thermal model) still loads, with `thermal: None`; it cannot claim
/// the version-4 flag; every bit flip of it is refused.
#[test]
fn version_3_records_still_load_without_a_thermal_model() {
    let mut record = sample();
    record.thermal = None;
    let v3 = encode_v3(&record, 11);
    assert_eq!(&v3[..4], &[0x1B, 0xCA, 3, 24]);
    assert_eq!(decode(&v3), Ok((11, record)));
    let mut bad = v3;
    bad[offset::FLAGS] |= FLAG_THERMAL_PRESENT;
    seal(&mut bad);
    assert_eq!(decode(&bad), Err(RecordError::BadFlags));
    for bit in 0..V3_RECORD_BYTES * 8 {
        let mut flipped = v3;
        flipped[bit / 8] ^= 1 << (bit % 8);
        assert!(decode(&flipped).is_err(), "v3 bit {bit}");
    }
}

/// The thermal model: one that fails its own checks is refused before storing and at load;
/// bytes without the flag, an enabled byte other than 0 or 1 and non-zero reserved bytes are
/// refused; a model switched off round-trips off.
#[test]
fn the_thermal_model_is_checked() {
    let mut record = sample();
    let bad_models = [
        ThermalModel {
            reference_c: f32::NAN,
            ..thermal_model()
        },
        ThermalModel {
            min_c: 70.0,
            ..thermal_model()
        },
        ThermalModel {
            bias_deg_h: [200.0, 0.0, 0.0, 0.0],
            ..thermal_model()
        },
    ];
    for model in bad_models {
        record.thermal = Some(ThermalCalibration {
            model,
            enabled: true,
        });
        assert_eq!(record.check(), Err(RecordError::ImplausibleThermal));
        assert_eq!(
            decode(&encode(&record, 1)),
            Err(RecordError::ImplausibleThermal)
        );
    }
    record.thermal = Some(ThermalCalibration {
        model: thermal_model(),
        enabled: false,
    });
    assert_eq!(decode(&encode(&record, 2)), Ok((2, record)));
    let mut bytes = encode(&record, 2);
    bytes[offset::THERMAL_ENABLED] = 2;
    seal(&mut bytes);
    assert_eq!(decode(&bytes), Err(RecordError::ImplausibleThermal));
    let mut bytes = encode(&record, 2);
    bytes[offset::RESERVED_3 + 1] = 1;
    seal(&mut bytes);
    assert_eq!(decode(&bytes), Err(RecordError::ImplausibleThermal));
    record.thermal = None;
    let mut bytes = encode(&record, 3);
    bytes[offset::THERMAL_MODEL + 7] = 1; // bytes without the flag
    seal(&mut bytes);
    assert_eq!(decode(&bytes), Err(RecordError::ImplausibleThermal));
    let mut reset = CalibrationRecord::reset(1, 1);
    reset.thermal = sample().thermal;
    assert_eq!(reset.check(), Err(RecordError::ImplausibleReset));
}

/// A version-2 record (no stripping coefficients) still loads, with `strip: None`; it cannot
/// claim the version-3 flag.
#[test]
fn version_2_records_still_load_without_stripping_coefficients() {
    let mut record = sample();
    record.strip = None;
    record.thermal = None;
    let v2 = encode_v2(&record, 8);
    assert_eq!(&v2[..4], &[0x1B, 0xCA, 2, 20]);
    assert_eq!(decode(&v2), Ok((8, record)));
    let mut bad = v2;
    bad[offset::FLAGS] |= FLAG_STRIP_PRESENT;
    seal(&mut bad);
    assert_eq!(decode(&bad), Err(RecordError::BadFlags));
    for bit in 0..V2_RECORD_BYTES * 8 {
        let mut flipped = v2;
        flipped[bit / 8] ^= 1 << (bit % 8);
        assert!(decode(&flipped).is_err(), "v2 bit {bit}");
    }
}

/// Stripping coefficients: a zero K is refused, bytes without the flag are refused, the
/// reserved bytes after them must be zero; the Q8.24 round trip is exact to 6e-8.
#[test]
fn stripping_coefficients_are_checked() {
    let mut record = sample();
    record.strip = Some(StripCoefficients::default());
    assert_eq!(record.check(), Err(RecordError::ImplausibleStrip));
    record.strip = None;
    let mut bytes = encode(&record, 1);
    bytes[offset::STRIP_K] = 1;
    seal(&mut bytes);
    assert_eq!(decode(&bytes), Err(RecordError::ImplausibleStrip));
    let mut bytes = encode(&sample(), 1);
    bytes[offset::RESERVED_2 + 2] = 1;
    seal(&mut bytes);
    assert_eq!(decode(&bytes), Err(RecordError::ImplausibleStrip));
    let strip = StripCoefficients::from_fringes_per_code(0.2144199, -0.0012).unwrap();
    assert!((strip.k() - 0.2144199).abs() < 6e-8 && (strip.k_quadrature() + 0.0012).abs() < 6e-8);
    assert_eq!(
        StripCoefficients::from_fringes_per_code(f32::NAN, 0.0),
        None
    );
    assert_eq!(StripCoefficients::from_fringes_per_code(200.0, 0.0), None);
}

/// A version-3 record of an older firmware (flag bit 3 without bit 4) holds the tap on the
/// previous latch's code: it loads with its K and a zero quadrature tap. Bit 4 without bit 3
/// is refused; this firmware writes both.
#[test]
fn an_older_previous_latch_tap_loads_as_k_alone() {
    let mut record = sample();
    record.strip = StripCoefficients::from_fringes_per_code(0.2144199, -0.0012);
    let mut bytes = encode(&record, 1);
    assert_eq!(bytes[offset::FLAGS] & 0x18, 0x18);
    assert_eq!(decode(&bytes).unwrap().1.strip, record.strip);
    bytes[offset::FLAGS] &= !0x10;
    seal(&mut bytes);
    let loaded = decode(&bytes).unwrap().1.strip.unwrap();
    assert_eq!(loaded.k_q24, record.strip.unwrap().k_q24);
    assert_eq!(loaded.k_quadrature_q24, 0);
    bytes[offset::FLAGS] = (bytes[offset::FLAGS] & !0x08) | 0x10;
    seal(&mut bytes);
    assert_eq!(decode(&bytes), Err(RecordError::ImplausibleStrip));
}

#[test]
fn version_1_records_still_load_without_dither_setpoints() {
    let mut record = sample();
    record.dither = None;
    record.strip = None;
    record.thermal = None;
    let v1 = encode_v1(&record, 7);
    assert_eq!(&v1[..4], &[0x1B, 0xCA, 1, 16]);
    assert_eq!(decode(&v1), Ok((7, record)));
    // A version-1 frame cannot claim the version-2 dither flag.
    let mut bad = v1;
    bad[offset::FLAGS] |= FLAG_DITHER_PRESENT;
    seal(&mut bad);
    assert_eq!(decode(&bad), Err(RecordError::BadFlags));
    // A frame whose length does not match its version is not read as that version.
    let mut short = encode(&record, 7);
    short[offset::VERSION] = V1_FORMAT_VERSION;
    seal(&mut short);
    assert_eq!(
        decode(&short),
        Err(RecordError::UnknownVersion { version: 1 })
    );
}

#[test]
fn dither_setpoints_are_range_checked_and_absent_means_zero_bytes() {
    let mut record = sample();
    for (amplitude, noise) in [
        (0.0, 0.0),
        (-1.0, 0.0),
        (f32::NAN, 0.0),
        (MAX_DITHER_AMPLITUDE_ARCSEC * 1.01, 0.0),
        (450.0, -0.1),
        (450.0, 100.5),
        (450.0, f32::INFINITY),
    ] {
        record.dither = Some(DitherSetpoints {
            enabled: true,
            amplitude_arcsec: amplitude,
            noise_percent: noise,
        });
        assert_eq!(record.check(), Err(RecordError::ImplausibleDither));
        // Bytes holding them are refused at load as well.
        assert_eq!(
            decode(&encode(&record, 1)),
            Err(RecordError::ImplausibleDither)
        );
    }
    record.dither = None;
    let mut bytes = encode(&record, 1);
    bytes[offset::DITHER_AMPLITUDE] = 1; // bytes without the flag
    seal(&mut bytes);
    assert_eq!(decode(&bytes), Err(RecordError::ImplausibleDither));
    let mut bytes = encode(&sample(), 1);
    bytes[offset::RESERVED + 3] = 1;
    seal(&mut bytes);
    assert_eq!(decode(&bytes), Err(RecordError::ImplausibleDither));
    let mut reset = CalibrationRecord::reset(1, 1);
    reset.dither = sample().dither;
    assert_eq!(reset.check(), Err(RecordError::ImplausibleReset));
}

#[test]
fn every_single_bit_flip_is_refused() {
    let bytes = encode(&sample(), 5);
    for bit in 0..RECORD_BYTES * 8 {
        let mut flipped = bytes;
        flipped[bit / 8] ^= 1 << (bit % 8);
        assert!(decode(&flipped).is_err(), "bit {bit}");
    }
    let mut record = sample();
    record.dither = None;
    record.strip = None;
    record.thermal = None;
    let v1 = encode_v1(&record, 5);
    for bit in 0..V1_RECORD_BYTES * 8 {
        let mut flipped = v1;
        flipped[bit / 8] ^= 1 << (bit % 8);
        assert!(decode(&flipped).is_err(), "v1 bit {bit}");
    }
}

#[test]
fn implausible_records_are_refused() {
    let mut record = sample();
    record.fit.as_mut().unwrap().condition_number = 0.5;
    assert_eq!(record.check(), Err(RecordError::ImplausibleFit));
    record.fit.as_mut().unwrap().condition_number = f32::NAN;
    assert_eq!(record.check(), Err(RecordError::ImplausibleFit));
    let mut reset = CalibrationRecord::reset(1, 1);
    reset.settings.enabled = true;
    assert_eq!(reset.check(), Err(RecordError::ImplausibleReset));
}
