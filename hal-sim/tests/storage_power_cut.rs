//! Power cuts during stores: at every byte of every store, in every erase, and at random.
//!
//! The claim under test (see `firmware::storage`): after a cut and a reboot, `load` returns the
//! record that was newest before the store or the new one, exactly (record and sequence
//! number), never an older record, garbage or the defaults once something was stored; and the
//! next store works and loads.
//! Tolerances: none; everything is compared exactly (the store is deterministic and the flash
//! model's randomness is seeded). Assumption (the model's): words are programmed in address
//! order and a cut leaves at most one word partially programmed.
//!
//! Cut positions: `PowerCut::AfterBytes(n)` for n = 0..=RECORD_BYTES covers every byte of the
//! record (n = RECORD_BYTES dies right after the last word: the record is complete). A store that erases
//! is also cut inside the erase, in each way the flash model can leave an interrupted erase.

mod storage_support;

use firmware::storage::record::{offset, RECORD_BYTES};
use firmware::storage::{CalibrationRecord, CalibrationStore, DefaultsReason, LoadOutcome};
use hal_sim::flash::{EraseCut, FlashError, PowerCut, SimFlash};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use storage_support::*;

/// Every way an erase can be interrupted, for a sector of `sector_bytes`.
fn erase_cuts(sector_bytes: usize) -> Vec<PowerCut> {
    let cuts = [
        EraseCut::Prefix { erased_bytes: 0 },
        EraseCut::Prefix {
            erased_bytes: RECORD_BYTES,
        },
        EraseCut::Prefix {
            erased_bytes: sector_bytes / 2,
        },
        EraseCut::Prefix {
            erased_bytes: sector_bytes,
        },
        EraseCut::RandomPrefix,
        EraseCut::WeakBits,
    ];
    cuts.into_iter()
        .map(|cut| PowerCut::InErase {
            erases_before: 0,
            cut,
        })
        .collect()
}

/// Does this store erase a sector? (Dry run on a copy.)
fn store_erases<const S: usize>(
    flash: &SimFlash<S, false>,
    store: &CalibrationStore,
    record: &CalibrationRecord,
) -> bool {
    let mut dry = flash.clone();
    let before: u32 = dry.stats().erases_per_sector.iter().sum();
    store
        .store_while_paused(&mut dry, &paused(), record)
        .unwrap();
    dry.stats().erases_per_sector.iter().sum::<u32>() > before
}

/// Cuts the store of `new` at `cut`, reboots, loads, and checks the result against `previous`
/// (the newest record before the store); then stores `recovery` and checks that it loads.
fn cut_and_check<const S: usize>(
    flash: &mut SimFlash<S, false>,
    store: &CalibrationStore,
    previous: Option<(u32, CalibrationRecord)>,
    new: &CalibrationRecord,
    cut: PowerCut,
) {
    let context = format!("previous {:?}, cut {cut:?}", previous.map(|p| p.0));
    flash.arm_power_cut(cut);
    let result = store.store_while_paused(flash, &paused(), new);
    assert_eq!(
        result,
        Err(firmware::storage::StoreError::Flash(FlashError::PowerCut)),
        "{context}"
    );
    flash.power_on();

    let loaded = store.load(flash);
    let new_sequence = previous.map_or(1, |(seq, _)| seq + 1);
    let got_new = loaded.1.outcome == outcome_of(new_sequence, new);
    match (got_new, previous) {
        (true, _) => assert_is(&loaded, new_sequence, new, &context),
        (false, Some((seq, record))) => assert_is(&loaded, seq, &record, &context),
        (false, None) => {
            assert!(
                matches!(loaded.1.outcome, LoadOutcome::Defaults { .. }),
                "{context}"
            );
            assert_eq!(loaded.0, CalibrationRecord::DEFAULTS, "{context}");
        }
    }
    // Which one it must be, where the cut position decides it.
    if let PowerCut::AfterBytes(n) = cut {
        if n <= offset::COMMIT {
            assert!(
                !got_new,
                "body cut at byte {n} loaded the new record: {context}"
            );
        }
        if n == RECORD_BYTES {
            assert!(got_new, "complete record not loaded: {context}");
        }
    } else {
        assert!(!got_new, "erase cut loaded the new record: {context}");
    }

    // Recovery: the next store works and is the newest.
    let recovery = record(999_999);
    let sequence = store
        .store_while_paused(flash, &paused(), &recovery)
        .unwrap_or_else(|e| panic!("recovery store failed: {e:?}, {context}"));
    let expected = if got_new {
        new_sequence + 1
    } else {
        new_sequence
    };
    assert_eq!(sequence, expected, "{context}");
    assert_is(&store.load(flash), sequence, &recovery, &context);
}

/// Runs `stores` stores; before each one is committed, tries a cut at every byte of it and in
/// its erase (from the same flash image), each followed by reboot, load and a recovery store.
fn cut_every_byte_of_every_store<const S: usize>(
    mut flash: SimFlash<S, false>,
    store: CalibrationStore,
    stores: u64,
) -> usize {
    let mut previous: Option<(u32, CalibrationRecord)> = None;
    let mut trials = 0;
    for i in 0..stores {
        let new = record(i);
        let image = flash.snapshot();
        let mut cuts: Vec<PowerCut> = (0..=RECORD_BYTES).map(PowerCut::AfterBytes).collect();
        if store_erases(&flash, &store, &new) {
            cuts.extend(erase_cuts(S));
        }
        for cut in cuts {
            flash.restore(&image);
            cut_and_check(&mut flash, &store, previous, &new, cut);
            trials += 1;
        }
        flash.restore(&image);
        let sequence = store
            .store_while_paused(&mut flash, &paused(), &new)
            .unwrap();
        assert_is(&store.load(&mut flash), sequence, &new, "uncut store");
        previous = Some((sequence, new));
    }
    trials
}

/// 8 records per sector, 60 stores: 7 sector switches (erases from the 17th store on), every
/// byte of every store cut, 6 kinds of erase cut at each switch.
#[test]
fn cut_at_every_byte_of_every_store_small_sectors() {
    let (flash, store) = small_flash(1);
    let trials = cut_every_byte_of_every_store(flash, store, 60);
    assert!(trials >= 60 * 65);
}

/// The real 128 KiB sectors: every byte of the first store, of a store in the middle, of the
/// last one that fits in sector 0 and of the one that switches to sector 1 (with its erase
/// cuts: an empty sector beside a used one is erased before use), then of the first store that must erase
/// sector 0 (2 x 2048 + 1).
#[test]
fn cut_at_every_byte_full_size_sectors() {
    let (mut flash, store) = full_flash(2);
    let per_sector = 128 * 1024 / RECORD_BYTES as u64;
    let checkpoints = [0, 1000, per_sector - 1, per_sector, 2 * per_sector];
    let mut previous: Option<(u32, CalibrationRecord)> = None;
    for i in 0..=2 * per_sector {
        let new = record(i);
        if checkpoints.contains(&i) {
            let image = flash.snapshot();
            let mut cuts: Vec<PowerCut> = (0..=RECORD_BYTES).map(PowerCut::AfterBytes).collect();
            if store_erases(&flash, &store, &new) {
                assert!(
                    i == per_sector || i == 2 * per_sector,
                    "only the move into blank sector 1 (an empty sector beside a used one is \
                     erased before use) and the wrap into sector 0 erase: {i}"
                );
                cuts.extend(erase_cuts(128 * 1024));
            }
            for cut in cuts {
                flash.restore(&image);
                cut_and_check(&mut flash, &store, previous, &new, cut);
            }
            flash.restore(&image);
        }
        let sequence = store
            .store_while_paused(&mut flash, &paused(), &new)
            .unwrap();
        previous = Some((sequence, new));
    }
    let (loaded, report) = store.load(&mut flash);
    assert_eq!(
        report.outcome,
        LoadOutcome::Loaded {
            sequence: 2 * per_sector as u32 + 1
        }
    );
    assert_eq!(loaded, previous.unwrap().1);
    assert_eq!(
        flash.stats().words_rewritten,
        0,
        "a word was programmed twice"
    );
}

/// Random stores and resets with random cuts (about half the operations), including cuts in
/// the recovery from an earlier cut, against an oracle: the last record known committed.
/// 4 records per sector, so erases (and erase cuts) are frequent. Seeded: reproducible.
#[test]
fn random_cuts_against_oracle() {
    const SECTOR: usize = 256;
    let mut flash = SimFlash::<SECTOR, false>::new(2, 3);
    let geometry = firmware::storage::Geometry {
        base_offset: 0,
        sector_bytes: SECTOR as u32,
    };
    let store = CalibrationStore::new(&flash, geometry).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    let mut committed: Option<(u32, CalibrationRecord)> = None;
    let mut cuts = 0;
    for i in 0..5000u64 {
        let new = if rng.random_bool(0.1) {
            CalibrationRecord::reset(1000, i as u32)
        } else {
            record(i)
        };
        if rng.random_bool(0.5) {
            let cut = if rng.random_bool(0.5) {
                PowerCut::AfterBytes(rng.random_range(0..=RECORD_BYTES))
            } else {
                erase_cuts(SECTOR)[rng.random_range(0..6)]
            };
            flash.arm_power_cut(cut);
        }
        let result = store.store_while_paused(&mut flash, &paused(), &new);
        flash.disarm_power_cut();
        flash.power_on();
        let loaded = store.load(&mut flash);
        let context = format!("operation {i}: {result:?}");
        match result {
            Ok(sequence) => {
                assert_is(&loaded, sequence, &new, &context);
                committed = Some((sequence, new));
            }
            Err(error) => {
                assert_eq!(
                    error,
                    firmware::storage::StoreError::Flash(FlashError::PowerCut)
                );
                cuts += 1;
                let sequence = loaded_sequence(&loaded.1);
                match committed {
                    Some((seq, record)) if sequence == Some(seq) => {
                        assert_is(&loaded, seq, &record, &context)
                    }
                    _ => {
                        // Not the old one: must be the new one, numbered above it.
                        let expected = committed.map_or(1, |(seq, _)| seq + 1);
                        if committed.is_some() || sequence.is_some() {
                            assert_is(&loaded, expected, &new, &context);
                            committed = Some((expected, new));
                        } else {
                            assert_eq!(loaded.0, CalibrationRecord::DEFAULTS, "{context}");
                            assert_ne!(
                                loaded.1.outcome,
                                LoadOutcome::Defaults {
                                    reason: DefaultsReason::ReadFailed
                                }
                            );
                        }
                    }
                }
            }
        }
    }
    assert!(cuts > 1000, "only {cuts} cuts happened");
    // Ends in a known state: one more clean store loads.
    let last = record(77);
    let sequence = store
        .store_while_paused(&mut flash, &paused(), &last)
        .unwrap();
    assert_is(&store.load(&mut flash), sequence, &last, "final store");
    assert_eq!(
        flash.stats().words_rewritten,
        0,
        "a word was programmed twice"
    );
}

/// An erase cut at its very end leaves a sector that reads all 0xFF, but whose cells may be
/// only weakly erased: the next store must not program into it as it is, but erase it again
/// first (an empty sector beside a used one is always the remains of an erase). Then the record
/// loads, and the store after it appends without another erase.
#[test]
fn a_sector_left_by_a_late_cut_erase_is_erased_again_before_reuse() {
    let (mut flash, store) = small_flash(9);
    // Fill both sectors (8 records each): the 17th store must erase.
    for i in 0..16 {
        store
            .store_while_paused(&mut flash, &paused(), &record(i))
            .unwrap();
    }
    let erases = |f: &SmallFlash| f.stats().erases_per_sector.clone();
    flash.arm_power_cut(PowerCut::InErase {
        erases_before: 0,
        cut: EraseCut::Prefix {
            erased_bytes: SMALL_SECTOR,
        },
    });
    assert!(store
        .store_while_paused(&mut flash, &paused(), &record(16))
        .is_err());
    flash.power_on();
    let before = erases(&flash);
    let sequence = store
        .store_while_paused(&mut flash, &paused(), &record(17))
        .unwrap();
    let after = erases(&flash);
    assert_eq!(
        after.iter().sum::<u32>(),
        before.iter().sum::<u32>() + 1,
        "the all-0xFF sector left by the cut erase is erased again before its first record"
    );
    assert_is(
        &store.load(&mut flash),
        sequence,
        &record(17),
        "after re-erase",
    );
    store
        .store_while_paused(&mut flash, &paused(), &record(18))
        .unwrap();
    assert_eq!(erases(&flash), after, "the next record appends");
}
