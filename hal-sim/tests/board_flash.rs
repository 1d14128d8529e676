//! The simulated NOR flash: semantics, errors, and power cuts at every byte.
//!
//! Tolerances: the models are deterministic and discrete, so counts, codes, bytes and ticks are
//! compared exactly, marked "(exact)"; statistical and floating checks state bound and reason.

use embedded_storage::nor_flash::{NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash};
use hal_sim::flash::{CalibrationFlash, EraseCut, FlashError, PowerCut, SimFlash};

/// Small sectors keep the exhaustive tests fast; semantics do not depend on the size.
type SmallFlash = SimFlash<256>;

fn read_all<F: ReadNorFlash>(flash: &mut F) -> Vec<u8> {
    let mut buf = vec![0; flash.capacity()];
    flash.read(0, &mut buf).unwrap();
    buf
}

/// The default calibration area: 2 x 128 KiB, erased, word writes, sector erases. (exact)
#[test]
fn calibration_area_geometry() {
    let mut flash = CalibrationFlash::default();
    assert_eq!(flash.capacity(), 2 * 128 * 1024);
    assert_eq!(<CalibrationFlash as ReadNorFlash>::READ_SIZE, 1);
    assert_eq!(<CalibrationFlash as NorFlash>::WRITE_SIZE, 4);
    assert_eq!(<CalibrationFlash as NorFlash>::ERASE_SIZE, 128 * 1024);
    assert!(read_all(&mut flash).iter().all(|&b| b == 0xFF));
}

/// Write, read back at any byte offset, erase. (exact)
#[test]
fn write_read_erase() {
    let mut flash = SmallFlash::new(2, 0);
    flash.write(8, &[1, 2, 3, 4, 5, 6, 7, 8]).unwrap();
    let mut buf = [0; 5];
    flash.read(9, &mut buf).unwrap();
    assert_eq!(buf, [2, 3, 4, 5, 6]);
    flash.write(256, &[0xA5; 4]).unwrap();
    flash.erase(0, 256).unwrap();
    let all = read_all(&mut flash);
    assert!(all[..256].iter().all(|&b| b == 0xFF));
    assert_eq!(all[256..260], [0xA5; 4]);
    assert_eq!(flash.stats().erases_per_sector, vec![1, 0]);
    flash.erase(0, 512).unwrap();
    assert_eq!(flash.stats().erases_per_sector, vec![2, 1]);
    assert_eq!(flash.stats().bytes_programmed, 12);
}

/// Strict semantics: a 0 -> 1 transition fails at that word, earlier words stay programmed;
/// clearing further bits is allowed and counted as a rewrite. (exact)
#[test]
fn programming_can_only_clear_bits() {
    let mut flash = SmallFlash::new(1, 0);
    flash.write(0, &[0xF0; 12]).unwrap();
    flash.write(0, &[0x30; 4]).unwrap();
    assert_eq!(flash.stats().words_rewritten, 1);
    let err = flash
        .write(4, &[0x10, 0x10, 0x10, 0x10, 0x0F, 0, 0, 0])
        .unwrap_err();
    assert_eq!(err, FlashError::Programming { offset: 8 });
    assert_eq!(err.kind(), NorFlashErrorKind::Other);
    let err = flash.write(0, &[0xFF, 0x30, 0x30, 0x30]).unwrap_err();
    assert_eq!(err, FlashError::Programming { offset: 0 });
    let all = read_all(&mut flash);
    assert_eq!(
        all[..12],
        [0x30, 0x30, 0x30, 0x30, 0x10, 0x10, 0x10, 0x10, 0xF0, 0xF0, 0xF0, 0xF0]
    );
}

/// Multiwrite flash: the result is the AND of old and new data. (exact)
#[test]
fn multiwrite_is_and() {
    fn assert_multiwrite<F: embedded_storage::nor_flash::MultiwriteNorFlash>(_: &F) {}
    let mut flash = SimFlash::<256, true>::new(1, 0);
    assert_multiwrite(&flash);
    flash.write(0, &[0xF0, 0x0F, 0xFF, 0x00]).unwrap();
    flash.write(0, &[0x3C, 0x3C, 0x3C, 0x3C]).unwrap();
    let mut buf = [0; 4];
    flash.read(0, &mut buf).unwrap();
    assert_eq!(buf, [0x30, 0x0C, 0x3C, 0x00]);
}

/// Alignment and bounds errors, with the embedded-storage kinds; nothing changes. (exact)
#[test]
fn alignment_and_bounds_errors() {
    let mut flash = SmallFlash::new(2, 0);
    let kind = |r: Result<(), FlashError>| r.unwrap_err().kind();
    assert_eq!(kind(flash.write(2, &[0; 4])), NorFlashErrorKind::NotAligned);
    assert_eq!(kind(flash.write(0, &[0; 3])), NorFlashErrorKind::NotAligned);
    assert_eq!(
        kind(flash.write(510, &[0; 4])),
        NorFlashErrorKind::OutOfBounds
    );
    assert_eq!(
        kind(flash.write(512, &[0; 4])),
        NorFlashErrorKind::OutOfBounds
    );
    assert_eq!(kind(flash.erase(0, 100)), NorFlashErrorKind::NotAligned);
    assert_eq!(kind(flash.erase(256, 0)), NorFlashErrorKind::OutOfBounds);
    assert_eq!(kind(flash.erase(0, 768)), NorFlashErrorKind::OutOfBounds);
    let mut buf = [0; 2];
    assert_eq!(
        kind(flash.read(511, &mut buf)),
        NorFlashErrorKind::OutOfBounds
    );
    assert!(flash.read(510, &mut buf).is_ok());
    assert!(read_all(&mut flash).iter().all(|&b| b == 0xFF));
    assert_eq!(flash.stats().erases_per_sector, vec![0, 0]);
}

/// Power cut at every byte of a 24-byte write over a pre-programmed area: words wholly before the
/// cut hold the new data; the word containing the cut holds old data with a subset of the
/// intended clears (bits meant to stay 1 stay 1, bits already 0 stay 0); everything after is
/// unchanged. The write reports the cut; every operation fails until power_on (exact).
#[test]
fn power_cut_at_every_byte_of_a_write() {
    let old: Vec<u8> = (0..24u8).map(|i| 0xF0 | i).collect();
    let new: Vec<u8> = (0..24u8).map(|i| 0x30 | (i & 0x05)).collect();
    let offset = 40;
    for cut in 0..=24usize {
        let mut flash = SmallFlash::new(1, cut as u64);
        flash.write(offset as u32, &old).unwrap();
        let before = flash.snapshot();
        flash.arm_power_cut(PowerCut::AfterBytes(cut));
        assert_eq!(flash.write(offset as u32, &new), Err(FlashError::PowerCut));
        assert!(!flash.is_powered());
        let mut buf = [0; 4];
        assert_eq!(flash.read(0, &mut buf), Err(FlashError::PowerCut));
        assert_eq!(flash.erase(0, 256), Err(FlashError::PowerCut));
        assert_eq!(flash.write(0, &[0; 4]), Err(FlashError::PowerCut));
        flash.power_on();
        let after = read_all(&mut flash);
        let whole_words = cut / 4 * 4;
        let partial = if cut % 4 != 0 { 4 } else { 0 };
        for i in 0..256 {
            let j = i as isize - offset as isize;
            if (0..whole_words as isize).contains(&j) {
                assert_eq!(after[i], new[j as usize], "cut {cut} byte {j}");
            } else if (whole_words as isize..(whole_words + partial) as isize).contains(&j) {
                let (o, n, a) = (old[j as usize], new[j as usize], after[i]);
                assert_eq!(a & !o, 0, "cut {cut}: bit set that was 0");
                assert_eq!(!a & n, 0, "cut {cut}: bit cleared that should stay 1");
            } else {
                assert_eq!(after[i], before[i], "cut {cut} byte {j} changed");
            }
        }
        assert_eq!(flash.stats().bytes_programmed, 24 + whole_words as u64);
        assert_eq!(flash.stats().power_cuts, 1);
    }
}

/// The partial word is seeded: same seed same bits; over seeds it takes several values, neither
/// always none nor always all of the intended clears (probability of failure ~1e-9).
#[test]
fn partial_word_is_seeded_random() {
    let partial = |seed| {
        let mut flash = SmallFlash::new(1, seed);
        flash.arm_power_cut(PowerCut::AfterBytes(2));
        let _ = flash.write(0, &[0; 8]);
        flash.power_on();
        let mut buf = [0; 4];
        flash.read(0, &mut buf).unwrap();
        u32::from_le_bytes(buf)
    };
    assert_eq!(partial(17), partial(17));
    let values: std::collections::BTreeSet<u32> = (0..32).map(partial).collect();
    assert!(values.len() > 20);
    assert!(!values.contains(&0) && !values.contains(&u32::MAX));
}

/// The byte budget runs across writes; a cut exactly at the end of a write still reports the cut.
#[test]
fn power_cut_budget_spans_writes() {
    let mut flash = SmallFlash::new(1, 0);
    flash.arm_power_cut(PowerCut::AfterBytes(8));
    flash.write(0, &[0x11; 4]).unwrap();
    assert_eq!(flash.write(4, &[0x22; 4]), Err(FlashError::PowerCut));
    flash.power_on();
    flash.write(8, &[0x33; 4]).unwrap();
    let all = read_all(&mut flash);
    assert_eq!(
        all[..12],
        [0x11, 0x11, 0x11, 0x11, 0x22, 0x22, 0x22, 0x22, 0x33, 0x33, 0x33, 0x33]
    );
}

/// Erase cuts: a deterministic prefix, a seeded random prefix, weak bits (exact checks).
#[test]
fn erase_cut_outcomes() {
    let programmed = |seed| {
        let mut flash = SmallFlash::new(2, seed);
        flash.write(0, &[0x00; 512]).unwrap();
        flash
    };
    let mut flash = programmed(0);
    flash.arm_power_cut(PowerCut::InErase {
        erases_before: 1,
        cut: EraseCut::Prefix { erased_bytes: 100 },
    });
    assert_eq!(flash.erase(0, 512), Err(FlashError::PowerCut));
    flash.power_on();
    let all = read_all(&mut flash);
    assert!(all[..356].iter().all(|&b| b == 0xFF));
    assert!(all[356..].iter().all(|&b| b == 0x00));
    assert_eq!(flash.stats().erases_per_sector, vec![1, 1]);

    let random_prefix = |seed| {
        let mut flash = programmed(seed);
        flash.arm_power_cut(PowerCut::InErase {
            erases_before: 0,
            cut: EraseCut::RandomPrefix,
        });
        assert_eq!(flash.erase(256, 512), Err(FlashError::PowerCut));
        flash.power_on();
        let all = read_all(&mut flash);
        assert!(all[..256].iter().all(|&b| b == 0));
        let n = all[256..].iter().take_while(|&&b| b == 0xFF).count();
        assert!(all[256 + n..].iter().all(|&b| b == 0));
        n
    };
    assert_eq!(random_prefix(3), random_prefix(3));
    let lengths: std::collections::BTreeSet<usize> = (0..20).map(random_prefix).collect();
    assert!(lengths.len() > 10);

    let mut flash = programmed(5);
    flash.arm_power_cut(PowerCut::InErase {
        erases_before: 0,
        cut: EraseCut::WeakBits,
    });
    assert_eq!(flash.erase(0, 256), Err(FlashError::PowerCut));
    flash.power_on();
    let all = read_all(&mut flash);
    let ones: u32 = all[..256].iter().map(|b| b.count_ones()).sum();
    // 2048 bits, each set with probability 1/2: mean 1024, sigma 22.6; 6 sigma bounds.
    assert!((1024 - 136..=1024 + 136).contains(&ones), "{ones}");
    assert!(all[256..].iter().all(|&b| b == 0));
}

/// Snapshot/restore and corruption for tests (exact); busy time bookkeeping (1e-12 s: f64 sum).
#[test]
fn snapshot_restore_corrupt_and_busy_time() {
    let mut flash = SmallFlash::new(1, 0);
    flash.write(0, &[0x12, 0x34, 0x56, 0x78]).unwrap();
    let image = flash.snapshot();
    flash.corrupt(1, 0x0F);
    let mut buf = [0; 4];
    flash.read(0, &mut buf).unwrap();
    assert_eq!(buf, [0x12, 0x3B, 0x56, 0x78]);
    flash.restore(&image);
    flash.read(0, &mut buf).unwrap();
    assert_eq!(buf, [0x12, 0x34, 0x56, 0x78]);
    flash.erase(0, 256).unwrap();
    // One word at 16 us + one erase at 1 s (tolerance: f64 rounding of the sum).
    assert!((flash.stats().busy_s - (1.0 + 16e-6)).abs() < 1e-12);
    assert_eq!(flash.contents().len(), 256);
}

/// Works through the traits only (what firmware storage code will see). (exact)
#[test]
fn usable_through_generic_nor_flash() {
    fn store<F: NorFlash>(flash: &mut F, record: &[u8]) -> Result<(), F::Error> {
        flash.erase(0, F::ERASE_SIZE as u32)?;
        flash.write(0, record)?;
        let mut back = vec![0; record.len()];
        flash.read(0, &mut back)?;
        assert_eq!(back, record);
        Ok(())
    }
    let mut flash = CalibrationFlash::default();
    store(&mut flash, &[1, 2, 3, 4, 5, 6, 7, 8]).unwrap();
    store(&mut &mut flash, &[9; 16]).unwrap();
}

/// After a write cut: outside the write nothing changed; inside, whole words of new data, then at
/// most one partially programmed word (a subset of the intended clears), then old data.
fn check_cut_write(old: &[u8], actual: &[u8], offset: usize, data: &[u8]) {
    let end = offset + data.len();
    assert_eq!(old[..offset], actual[..offset]);
    assert_eq!(old[end..], actual[end..]);
    let mut phase = 0; // 0: new words, 1: after the partial word
    for (w, new) in data.chunks(4).enumerate() {
        let range = offset + 4 * w..offset + 4 * w + 4;
        let (o, a) = (&old[range.clone()], &actual[range]);
        if phase == 0 && a == new {
            continue;
        }
        if phase == 0 {
            for k in 0..4 {
                assert_eq!(a[k] & !o[k], 0, "partial word set a bit");
                assert_eq!(
                    !a[k] & o[k] & new[k],
                    0,
                    "partial word cleared a bit meant to stay"
                );
            }
            phase = 1;
        } else {
            assert_eq!(a, o, "word after the cut changed");
        }
    }
}

/// Random writes, erases and power cuts against an independent oracle of the NOR semantics
/// (in the spirit of sequential-storage's fuzzing): 20 000 operations, ~5 % with a cut armed.
/// Without a cut the contents equal the oracle's exactly and programming errors are predicted;
/// after a write cut [`check_cut_write`] holds; an erase cut only turns bits 0 -> 1.
#[test]
fn random_operations_against_an_oracle() {
    use rand::{Rng, SeedableRng};
    const SECTOR: usize = 64;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(2024);
    let mut flash = SimFlash::<SECTOR>::new(4, 1);
    let mut oracle = vec![0xFFu8; 4 * SECTOR];
    let (mut write_cuts, mut erase_cuts, mut programming_errors) = (0, 0, 0);
    for _ in 0..20_000 {
        if rng.random_bool(0.05) {
            let cut = if rng.random_bool(0.5) {
                PowerCut::AfterBytes(rng.random_range(0..40))
            } else {
                PowerCut::InErase {
                    erases_before: rng.random_range(0..2),
                    cut: EraseCut::WeakBits,
                }
            };
            flash.arm_power_cut(cut);
        }
        if rng.random_bool(0.1) {
            let first = rng.random_range(0..4);
            let last = rng.random_range(first..4) + 1;
            match flash.erase((first * SECTOR) as u32, (last * SECTOR) as u32) {
                Ok(()) => oracle[first * SECTOR..last * SECTOR].fill(0xFF),
                Err(FlashError::PowerCut) => {
                    let actual = flash.contents();
                    assert!(actual.iter().zip(&oracle).all(|(a, o)| !a & o == 0));
                    oracle.copy_from_slice(actual);
                    flash.power_on();
                    erase_cuts += 1;
                }
                Err(e) => panic!("{e:?}"),
            }
        } else {
            let offset = rng.random_range(0..SECTOR) * 4;
            let words = rng.random_range(1..=(4 * SECTOR - offset) / 4).min(6);
            let data: Vec<u8> = (0..words * 4)
                .map(|i| {
                    let r: u8 = rng.random();
                    if rng.random_bool(0.02) {
                        r
                    } else {
                        oracle[offset + i] & r
                    }
                })
                .collect();
            let result = flash.write(offset as u32, &data);
            if result == Err(FlashError::PowerCut) {
                check_cut_write(&oracle, flash.contents(), offset, &data);
                oracle.copy_from_slice(flash.contents());
                flash.power_on();
                write_cuts += 1;
            } else {
                let mut expected = Ok(());
                for (w, new) in data.chunks(4).enumerate() {
                    let at = offset + 4 * w;
                    if new
                        .iter()
                        .zip(&oracle[at..at + 4])
                        .any(|(n, o)| n & !o != 0)
                    {
                        expected = Err(FlashError::Programming { offset: at as u32 });
                        programming_errors += 1;
                        break;
                    }
                    oracle[at..at + 4].copy_from_slice(new);
                }
                assert_eq!(result, expected);
            }
        }
        assert_eq!(flash.contents(), &oracle[..]);
    }
    assert!(write_cuts > 100, "{write_cuts}");
    assert!(erase_cuts > 20, "{erase_cuts}");
    assert!(programming_errors > 50, "{programming_errors}");
}
