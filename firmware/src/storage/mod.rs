//! Calibration storage: the compensation settings and their metadata in the two reserved flash
//! sectors (10 and 11 of the STM32F405, 128 KiB each), surviving a power cut at any moment.
//!
//! Rooms: [`crc`] (CRC-32/ISO-HDLC), [`record`] (the record, [`record::RECORD_BYTES`] long,
//! its byte layout and checks), [`store`] (the two-sector log), [`ram_flash`] (NOR flash in
//! RAM, for QEMU and host tests). Flash access goes only through
//! `embedded_storage::nor_flash::NorFlash`; everything else is plain logic, tested on the host
//! against hal-sim's NOR flash model with power cuts at every byte.
//!
//! # Scheme: an append-only log over two sectors
//! Each store appends one record, with a sequence number one above the highest valid one in
//! either sector, to the sector written last, at the end of its used part. When that sector is
//! full (910 records of 144 bytes per 128 KiB sector) the other sector is erased and the record
//! goes to its start. `load` scans both sectors and takes the valid record with the highest
//! sequence number. Erases alternate between the sectors, so they wear evenly: one erase per
//! 910 stores, against the F405's 10 000 cycles.
//!
//! A record is *valid* when its magic, length, CRC-32 and commit marker check, its format
//! version is this firmware's and its contents are plausible. Anything else in the sectors is
//! skipped unit by unit (16 bytes) and counted as damage; a valid frame of an unknown format
//! version (written by newer firmware before a downgrade) is skipped by its length, reported,
//! and left untouched; new records are numbered above it. Like any old record it disappears
//! only when its sector is erased for a wrap, which never happens to the sector holding the
//! newest record this firmware can read.
//!
//! # Why a power cut cannot lose the newest record
//! Let R be the newest valid record when a store starts, in sector K.
//! - A store programs only erased flash after the used part of a sector: R's bytes are never
//!   programmed again (the flash model enforces write-once).
//! - A store erases a sector only when both are full, and never K: it erases the other one,
//!   whose loadable records are all older than R. A cut during that erase leaves R in K; the next
//!   store erases the same sector again, even when the cut came so late that the sector already
//!   reads all 0xFF (weakly erased cells read as erased): an empty sector beside a used one is
//!   always erased before its first record (`store::CalibrationStore`, `append_position`).
//!   This also erases the factory-blank second sector once, when the log first moves into it.
//! - The new record's body is programmed and read back before its commit marker, the last word
//!   programmed. Until the marker is complete the new record is not valid (a torn marker word
//!   holds only a subset of its bit clears, never the marker value; a torn body fails the CRC),
//!   so `load` returns R; once complete, the new record, whose sequence number is the highest.
//!
//! So `load` after a cut returns R or the new record, never an older one, garbage or the
//! defaults. The tests check this at every byte of every store and in every erase, against
//! hal-sim's flash model, whose assumptions are those of this argument: words are programmed
//! in address order, and a cut leaves at most one word partially programmed.
//!
//! Not covered: a cell that a cut leaves marginally programmed, reading 0 at the read-back
//! and 1 later, or any later decay (the F4 has no ECC). Such a record fails its CRC and is
//! ignored, so bit rot in R brings back the record before it, the nearest survivor.
//!
//! # Stalls: an erase pauses the readout
//! The F405 has a single flash bank: while a sector is erased (up to [`SECTOR_ERASE_MAX_MS`]
//! for a 128 KiB sector) or a word programmed (up to [`WORD_PROGRAM_MAX_US`]), any instruction
//! fetch or data read from flash waits, so everything in flash stalls; the board keeps its
//! dither drive, serial link and millisecond clock in RAM (`board::ram`). A word's stall only
//! delays the readout's handlers. An erase would make them miss turnarounds and the fringe
//! count lose track for a second, so [`CalibrationStore::store`] pauses the readout for a store
//! that erases (its caller's pause, re-synchronising the readout after), and only for one: the
//! first store after a sector is full, once per sector's worth of records. (The calibration is stored on an explicit command only,
//! never from the signal chain.) `load` only reads: it runs at boot, before the readout
//! starts, and reads both sectors once.

// Input from outside the board passes here: integer arithmetic is checked, wrapping or
// saturating where an input could overflow it (the crate denies the panicking calls,
// `lib.rs`; each exception is allowed where it stands, with its reason).
#![cfg_attr(not(test), deny(clippy::arithmetic_side_effects))]

pub mod crc;
pub mod ram_flash;
pub mod record;
pub mod store;

pub use record::{
    CalibrationRecord, DitherSetpoints, FitSummary, RecordError, StripCoefficients,
    ThermalCalibration,
};
pub use store::{
    CalibrationStore, DefaultsReason, Geometry, GeometryError, LoadOutcome, LoadReport,
    SkippedFrame, StoreError, Stored,
};

/// Worst-case erase time of one 128 KiB sector, ms (STM32F405 datasheet, x32 parallelism at
/// 2.7 to 3.6 V: 1 s typical, 2 s maximum; x8 parallelism would double it).
pub const SECTOR_ERASE_MAX_MS: u32 = 2000;
/// Worst-case programming time of one 32-bit word, us (datasheet: 16 us typical).
pub const WORD_PROGRAM_MAX_US: u32 = 100;
/// Longest the CPU can stall in one store: one sector erase plus programming a record (16
/// words), rounded up to whole ms. Not included: the scan of both sectors that every `load`
/// and `store` starts with, CPU time rather than a stall (interrupts are served): about
/// 2 000 instructions per stored record, so some 8 M (~50 ms at 168 MHz, estimated from QEMU
/// instruction counts, not measured on a board) when both 128 KiB sectors are full.
pub const STORE_STALL_MAX_MS: u32 =
    SECTOR_ERASE_MAX_MS + (record::RECORD_BYTES as u32 / 4 * WORD_PROGRAM_MAX_US).div_ceil(1000);

/// The caller's word that the readout is paused, required to store (see the module docs).
///
/// Nothing checks it: it makes the stall visible at every call site. On the product path the
/// only source is the command service's pause guard (`service::ports::pause`), which stops the
/// readout and restarts it when dropped; tests of the store alone create it directly.
#[derive(Debug)]
pub struct ReadoutPaused {
    _private: (),
}

impl ReadoutPaused {
    /// Declares that the readout interrupts are stopped and may miss up to
    /// [`STORE_STALL_MAX_MS`] of turnarounds without harm (they are re-synchronised after).
    pub fn assume_paused() -> Self {
        Self { _private: () }
    }
}
