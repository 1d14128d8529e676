//! Many stores: wrap-around through both sectors, the newest always loads, erases alternate
//! between the sectors (wear levelling), no word is ever programmed twice, and the CPU stall
//! the flash model books stays within the documented worst case.
//! Tolerances: counts, sequence numbers and records are exact; the stall is bounded by the
//! documented worst case (the model books typical datasheet times).

mod storage_support;

use firmware::storage::record::RECORD_BYTES;
use firmware::storage::{CalibrationStore, Geometry, GeometryError, STORE_STALL_MAX_MS};
use storage_support::*;

/// 1000 stores at 8 records per sector: 124 erases (the move into blank sector 1 included: an
/// empty sector beside a used one is erased before use), split evenly (difference at most 1); every
/// store loads right after, and a reboot at any point loads the newest.
#[test]
fn wrap_around_small_sectors() {
    let (mut flash, store) = small_flash(30);
    let per_sector = (SMALL_SECTOR / RECORD_BYTES) as u64;
    for i in 0..1000u64 {
        let sequence = store
            .store_while_paused(&mut flash, &paused(), &record(i))
            .unwrap();
        assert_eq!(sequence as u64, i + 1);
        assert_is(&store.load(&mut flash), sequence, &record(i), "wrap");
    }
    let erases = &flash.stats().erases_per_sector;
    // The first 2 x 8 stores fill both sectors (sector 1 erased before its first record);
    // each 8 after that erase one sector.
    assert_eq!(
        erases.iter().sum::<u32>() as u64,
        1 + (1000 - 2 * per_sector).div_ceil(per_sector)
    );
    assert!(
        erases[0].abs_diff(erases[1]) <= 1,
        "uneven wear: {erases:?}"
    );
    assert_eq!(flash.stats().words_rewritten, 0);
}

/// The real sectors, 3600 stores of 144 bytes (910 per 128 KiB sector): 1820 fill both blank
/// sectors (store 911 erases blank sector 1 before its first record), store 1821 erases
/// sector 0, store 2731 erases sector 1 again: one erase for sector 0, two for sector 1.
/// The stall the model books per store (typical 1 s per erase, 16 us per word) stays within the
/// documented worst case.
#[test]
fn wrap_around_full_size_sectors() {
    let (mut flash, store) = full_flash(31);
    let mut worst_stall_s: f64 = 0.0;
    for i in 0..3600u64 {
        let busy_before = flash.stats().busy_s;
        let sequence = store
            .store_while_paused(&mut flash, &paused(), &record(i))
            .unwrap();
        worst_stall_s = worst_stall_s.max(flash.stats().busy_s - busy_before);
        let per_sector = (128 * 1024 / RECORD_BYTES) as u64;
        let near_wrap = |k: u64| (k * per_sector - 5..k * per_sector + 5).contains(&i);
        if i % 97 == 0 || near_wrap(2) || near_wrap(3) || i >= 3540 {
            assert_is(
                &store.load(&mut flash),
                sequence,
                &record(i),
                "full-size wrap",
            );
        }
    }
    assert_eq!(flash.stats().erases_per_sector, vec![1, 2]);
    assert!(worst_stall_s <= STORE_STALL_MAX_MS as f64 * 1e-3);
    assert!(worst_stall_s >= 1.0, "no store erased");
    assert_eq!(flash.stats().words_rewritten, 0);
}

#[test]
fn geometry_is_checked() {
    let (flash, _) = small_flash(32);
    let geometry = |base_offset, sector_bytes| Geometry {
        base_offset,
        sector_bytes,
    };
    let new = |g| CalibrationStore::new(&flash, g).map(|_| ());
    let sector = SMALL_SECTOR as u32;
    assert_eq!(new(geometry(0, sector)), Ok(()));
    assert_eq!(
        new(geometry(sector / 2, sector)),
        Err(GeometryError::Unaligned)
    );
    assert_eq!(
        new(geometry(sector, sector)),
        Err(GeometryError::OutOfBounds)
    );
    assert_eq!(
        new(geometry(0, 2 * sector)),
        Err(GeometryError::OutOfBounds)
    );
}
