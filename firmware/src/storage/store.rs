//! The two-sector log: where a record goes, how the newest is found again, and what a store
//! may erase (see the module docs of [`crate::storage`] for the power-fail argument).
//!
//! Size (over 600 lines): the scan, the append and the erase decision share one walk over the
//! sectors; the record format is in `record/`.

use embedded_storage::nor_flash::{NorFlash, ReadNorFlash};

use super::crc::Crc32;
use super::record::{
    self, get_u32, readable_length, CalibrationRecord, FrameHeader, RecordError, ALIGN_BYTES,
    COMMIT_MARKER, RECORD_BYTES,
};
use super::ReadoutPaused;

/// The log has exactly two sectors: one keeps the newest record while the other is erased.
const SECTORS: usize = 2;
/// Flash is read in these units: a frame's first unit holds its whole header.
type Unit = [u8; ALIGN_BYTES];
const ERASED_UNIT: Unit = [0xFF; ALIGN_BYTES];

/// Where the two sectors are, in the offsets of the `NorFlash` driver.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Geometry {
    /// Offset of the first sector; the second follows it directly.
    pub base_offset: u32,
    /// Size of each sector: a multiple of the flash's erase size.
    pub sector_bytes: u32,
}

impl Geometry {
    /// Sectors 10 and 11 of the STM32F405 (0x080C_0000 and 0x080E_0000, 128 KiB each, reserved
    /// in `memory.x`) for a driver whose offset 0 is 0x0800_0000.
    pub const F405_SECTORS_10_11: Self = Self {
        base_offset: 0x000C_0000,
        sector_bytes: 128 * 1024,
    };
    /// The same two sectors for a driver that addresses only the calibration area, from 0
    /// (hal-sim's `CalibrationFlash`).
    pub const F405_CALIBRATION_AREA: Self = Self {
        base_offset: 0,
        sector_bytes: 128 * 1024,
    };

    /// Offset of `sector` (0 or 1): inside the flash, `CalibrationStore::new` checked
    /// base + 2 sectors against its capacity.
    fn sector_start(&self, sector: usize) -> u32 {
        let sectors_before = if sector == 0 { 0 } else { self.sector_bytes };
        self.base_offset.saturating_add(sectors_before)
    }
}

/// Why a geometry does not fit a flash.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum GeometryError {
    /// Base or sector size not a multiple of the erase size or of [`ALIGN_BYTES`].
    Unaligned,
    /// A sector cannot hold one record.
    TooSmall,
    /// The two sectors do not lie inside the flash.
    OutOfBounds,
    /// The driver's write size does not divide 4 (the commit marker is one word written alone)
    /// or its read size does not divide [`ALIGN_BYTES`].
    UnsupportedFlash,
}

/// What a store did: the record's sequence number, and whether a sector was erased for it
/// (the readout was then paused and re-synchronised: [`CalibrationStore::store`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Stored {
    /// The record's sequence number.
    pub sequence: u32,
    /// A sector was erased first.
    pub erased: bool,
}

/// Why a store failed. Whatever the error, `load` returns the record that loaded before, or the
/// new one if its commit marker was programmed before the failure (a power cut in the last
/// word, or a read-back mismatch after the marker): never anything else.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum StoreError<E> {
    /// The record fails its plausibility checks; nothing was written.
    Record(RecordError),
    /// The flash driver failed (erase, program or read); in the simulator also a power cut.
    Flash(E),
    /// Read-back differs from what was programmed, at this driver offset. The marker is written
    /// only after the body verified, so a body mismatch leaves an uncommitted (ignored) record.
    /// The next store appends after it; retrying is the caller's choice.
    Verify {
        /// Driver offset of the first 16-byte unit that read back differently.
        offset: u32,
    },
    /// Flash that must be erased is not (at this offset): the erase did not complete.
    NotErased {
        /// Driver offset of the first 16-byte unit that is not all 0xFF.
        offset: u32,
    },
    /// The sequence number would overflow (2^32 stores: beyond the flash's endurance).
    SequenceExhausted,
}

/// A valid frame of a format version this firmware cannot read: skipped and left in flash.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SkippedFrame {
    /// Its format version (one this firmware cannot read: see `record::readable_length`).
    pub version: u8,
    /// Its sequence number: new records are numbered above it.
    pub sequence: u32,
}

/// Why the defaults are in force.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum DefaultsReason {
    /// Both sectors are erased: a fresh board.
    Erased,
    /// Something is stored, but no valid record of this format version.
    NoValidRecord,
    /// The newest record was written by `reset_to_defaults` (with this sequence number).
    Reset {
        /// Sequence number of that reset record.
        sequence: u32,
    },
    /// The flash could not be read.
    ReadFailed,
    /// The newest record belongs to another gyro: its serial number (the record's existing
    /// `serial_number` field) is not this board's. Its coefficients are not loaded.
    OtherGyro {
        /// The serial number in the record.
        stored_serial: u32,
    },
}

/// What `load` found: the flag the host reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum LoadOutcome {
    /// The stored calibration with this sequence number is in force.
    Loaded {
        /// Sequence number of the record loaded.
        sequence: u32,
    },
    /// The defaults are in force.
    Defaults {
        /// Why: a fresh board, nothing valid, a reset record or a read error.
        reason: DefaultsReason,
    },
}

/// The outcome and the health of the store.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LoadReport {
    /// Which record is in force: a loaded one or the defaults.
    pub outcome: LoadOutcome,
    /// The newest valid frame of an unknown (newer) format version, if any: skipped, untouched.
    pub newer_format: Option<SkippedFrame>,
    /// Valid frames of this version whose contents failed the plausibility checks.
    pub rejected_records: u32,
    /// Bytes neither erased nor part of a valid frame: torn writes and corruption.
    pub damaged_bytes: u32,
}

impl LoadReport {
    fn defaults(reason: DefaultsReason) -> Self {
        Self {
            outcome: LoadOutcome::Defaults { reason },
            newer_format: None,
            rejected_records: 0,
            damaged_bytes: 0,
        }
    }
}

/// What one pass over a sector found.
#[derive(Clone, Copy, Debug, Default)]
struct SectorScan {
    /// The newest loadable record and its sequence number.
    newest: Option<(u32, CalibrationRecord)>,
    /// The highest sequence number of any valid frame, of any version.
    max_sequence: Option<u32>,
    newer_format: Option<SkippedFrame>,
    rejected_records: u32,
    damaged_bytes: u32,
    /// End of the last unit that is not erased: the next record goes here.
    used_bytes: u32,
}

/// Both sectors.
struct Scan([SectorScan; SECTORS]);

/// The other one of the two sectors.
fn other(sector: usize) -> usize {
    if sector == 0 {
        1
    } else {
        0
    }
}

impl Scan {
    /// The sector and contents of the newest loadable record.
    fn newest(&self) -> Option<(usize, u32, CalibrationRecord)> {
        self.0
            .iter()
            .enumerate()
            .filter_map(|(s, scan)| scan.newest.map(|(seq, record)| (s, seq, record)))
            .max_by_key(|&(_, seq, _)| seq)
    }

    /// The sector holding the highest sequence number of any valid frame: the one written last.
    fn head(&self) -> Option<usize> {
        self.0
            .iter()
            .enumerate()
            .filter(|(_, scan)| scan.max_sequence.is_some())
            .max_by_key(|(_, scan)| scan.max_sequence)
            .map(|(s, _)| s)
    }

    fn max_sequence(&self) -> Option<u32> {
        self.0.iter().filter_map(|s| s.max_sequence).max()
    }

    fn report(&self, outcome: LoadOutcome) -> LoadReport {
        LoadReport {
            outcome,
            newer_format: self
                .0
                .iter()
                .filter_map(|s| s.newer_format)
                .max_by_key(|f| f.sequence),
            rejected_records: self
                .0
                .iter()
                .fold(0, |n, s| n.saturating_add(s.rejected_records)),
            damaged_bytes: self
                .0
                .iter()
                .fold(0, |n, s| n.saturating_add(s.damaged_bytes)),
        }
    }
}

/// The calibration store over two sectors (stateless: every call scans the flash).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CalibrationStore {
    geometry: Geometry,
}

impl CalibrationStore {
    /// Checks `geometry` against `flash` (use the store with that flash only).
    pub fn new<F: NorFlash>(flash: &F, geometry: Geometry) -> Result<Self, GeometryError> {
        let unit = ALIGN_BYTES as u32;
        if !(4usize.is_multiple_of(F::WRITE_SIZE) && ALIGN_BYTES.is_multiple_of(F::READ_SIZE)) {
            return Err(GeometryError::UnsupportedFlash);
        }
        let erase = F::ERASE_SIZE as u32;
        let aligned = |value: u32| value.is_multiple_of(erase) && value.is_multiple_of(unit);
        if !(aligned(geometry.base_offset) && aligned(geometry.sector_bytes)) {
            return Err(GeometryError::Unaligned);
        }
        if (geometry.sector_bytes as usize) < RECORD_BYTES {
            return Err(GeometryError::TooSmall);
        }
        // In u64: two u32 terms and a factor 2 cannot overflow it.
        let end = u64::from(geometry.base_offset)
            .saturating_add((SECTORS as u64).saturating_mul(u64::from(geometry.sector_bytes)));
        if end > flash.capacity() as u64 {
            return Err(GeometryError::OutOfBounds);
        }
        Ok(Self { geometry })
    }

    /// Where the two sectors are.
    pub fn geometry(&self) -> Geometry {
        self.geometry
    }

    /// The newest valid record, or the defaults and why. Reads both sectors once (256 KiB on
    /// the F405) and never writes: a torn or unknown record is left as it is.
    pub fn load<F: ReadNorFlash>(&self, flash: &mut F) -> (CalibrationRecord, LoadReport) {
        let Ok(scan) = self.scan(flash) else {
            let report = LoadReport::defaults(DefaultsReason::ReadFailed);
            return (CalibrationRecord::DEFAULTS, report);
        };
        let (record, outcome) = match scan.newest() {
            Some((_, sequence, record)) if record.reset_to_defaults => {
                let reason = DefaultsReason::Reset { sequence };
                (record, LoadOutcome::Defaults { reason })
            }
            Some((_, sequence, record)) => (record, LoadOutcome::Loaded { sequence }),
            None => {
                let erased = scan.0.iter().all(|s| s.used_bytes == 0);
                let reason = if erased {
                    DefaultsReason::Erased
                } else {
                    DefaultsReason::NoValidRecord
                };
                (
                    CalibrationRecord::DEFAULTS,
                    LoadOutcome::Defaults { reason },
                )
            }
        };
        (record, scan.report(outcome))
    }

    /// [`Self::load`], for the board whose gyro has `serial_number`: a newest record written
    /// for another serial number gives the defaults ([`DefaultsReason::OtherGyro`]), so the
    /// coefficients of another gyro never load silently (a board moved to another gyro, or a
    /// flash image copied between boards). The record stays in flash, untouched.
    pub fn load_for_serial<F: ReadNorFlash>(
        &self,
        flash: &mut F,
        serial_number: u32,
    ) -> (CalibrationRecord, LoadReport) {
        let (record, mut report) = self.load(flash);
        match report.outcome {
            LoadOutcome::Loaded { .. } if record.serial_number != serial_number => {
                report.outcome = LoadOutcome::Defaults {
                    reason: DefaultsReason::OtherGyro {
                        stored_serial: record.serial_number,
                    },
                };
                (CalibrationRecord::DEFAULTS, report)
            }
            _ => (record, report),
        }
    }

    /// Appends `record` and returns its sequence number, after reading it back, with the
    /// readout paused for the whole store ([`ReadoutPaused`]): [`Self::store`] pausing
    /// whether it erases or not.
    pub fn store_while_paused<F: NorFlash>(
        &self,
        flash: &mut F,
        _paused: &ReadoutPaused,
        record: &CalibrationRecord,
    ) -> Result<u32, StoreError<F::Error>> {
        self.store(flash, record, || ())
            .map(|stored| stored.sequence)
    }

    /// Appends `record` after reading it back; returns its sequence number and whether a
    /// sector was erased for it.
    ///
    /// Stalls the CPU's fetches from flash: each of the record's words
    /// ([`record::RECORD_BYTES`] / 4) for 16 us typical (100 us at most), and, when the written sector is full, the other one's erase first, 1 s
    /// typical ([`super::SECTOR_ERASE_MAX_MS`] at most) on the single-bank F405. What runs from
    /// RAM goes on meanwhile (on the board: the dither drive, `board::ram`). A word's stall
    /// only delays the rest; an erase's would make the readout miss turnarounds for a second,
    /// so `pause_for_erase` is called right before an erase, and the pause it returns (a guard
    /// that restarts and re-synchronises the readout when dropped) is held until the record is
    /// programmed. A store without an erase never calls it.
    pub fn store<F: NorFlash, P>(
        &self,
        flash: &mut F,
        record: &CalibrationRecord,
        pause_for_erase: impl FnOnce() -> P,
    ) -> Result<Stored, StoreError<F::Error>> {
        record.check().map_err(StoreError::Record)?;
        let scan = self.scan(flash).map_err(StoreError::Flash)?;
        let sequence = match scan.max_sequence() {
            None => 1,
            Some(last) => last.checked_add(1).ok_or(StoreError::SequenceExhausted)?,
        };
        let (sector, at, pause) = match self.append_position(&scan) {
            Some((sector, at)) => (sector, at, None),
            None => {
                let pause = pause_for_erase();
                let sector = Self::sector_to_erase(&scan);
                self.erase(flash, sector)?;
                (sector, 0, Some(pause))
            }
        };
        let address = self.geometry.sector_start(sector).saturating_add(at);
        program(flash, address, &record::encode(record, sequence))?;
        let erased = pause.is_some();
        drop(pause);
        Ok(Stored { sequence, erased })
    }

    /// Stores a record that marks the defaults as chosen (compensation off, a = b = 0), like
    /// any other store: the previous calibration stays loadable until it is committed, and
    /// `load` then reports [`DefaultsReason::Reset`]. (Erasing both sectors instead would not
    /// be power-fail safe: a cut between the two erases could bring back an older record.)
    pub fn reset_to_defaults<F: NorFlash>(
        &self,
        flash: &mut F,
        paused: &ReadoutPaused,
        serial_number: u32,
        boot_count: u32,
    ) -> Result<u32, StoreError<F::Error>> {
        let record = CalibrationRecord::reset(serial_number, boot_count);
        self.store_while_paused(flash, paused, &record)
    }

    /// Room without erasing: first in the sector written last, else in the other one.
    ///
    /// An empty sector beside a used one is never appended to: in this log a sector becomes
    /// empty only by an erase that no record followed, i.e. one cut by a power loss, possibly
    /// at its very end, where the cells read 0xFF but are only weakly erased (a record
    /// programmed there may not keep). Reading cannot tell, so such a sector is erased again
    /// (`store_while_paused` erases what this refuses). The price: one extra erase when the log
    /// first moves into the factory-blank second sector. On a blank flash (both sectors empty)
    /// the first sector is used as it is.
    fn append_position(&self, scan: &Scan) -> Option<(usize, u32)> {
        let first = scan.head().unwrap_or(0);
        let used = |sector: usize| scan.0.get(sector).map_or(0, |s| s.used_bytes);
        [first, other(first)].into_iter().find_map(|sector| {
            let used_here = used(sector);
            let fits = (used_here as usize).saturating_add(RECORD_BYTES)
                <= self.geometry.sector_bytes as usize;
            let suspect = used_here == 0 && used(other(sector)) > 0;
            (fits && !suspect).then_some((sector, used_here))
        })
    }

    /// Both sectors are full: erase the one without the newest loadable record (without a
    /// loadable record, the one not written last).
    fn sector_to_erase(scan: &Scan) -> usize {
        let keep = match scan.newest() {
            Some((sector, _, _)) => sector,
            None => scan.head().unwrap_or(0),
        };
        other(keep)
    }

    fn erase<F: NorFlash>(&self, flash: &mut F, sector: usize) -> Result<(), StoreError<F::Error>> {
        let start = self.geometry.sector_start(sector);
        let end = start.saturating_add(self.geometry.sector_bytes);
        flash.erase(start, end).map_err(StoreError::Flash)?;
        expect_erased(flash, start, end)
    }

    fn scan<F: ReadNorFlash>(&self, flash: &mut F) -> Result<Scan, F::Error> {
        Ok(Scan([
            self.scan_sector(flash, 0)?,
            self.scan_sector(flash, 1)?,
        ]))
    }

    /// Walks a sector in units: a valid frame is taken whole, anything else not erased is
    /// damage, skipped one unit at a time (so damage never hides the frames after it).
    fn scan_sector<F: ReadNorFlash>(
        &self,
        flash: &mut F,
        sector: usize,
    ) -> Result<SectorScan, F::Error> {
        let start = self.geometry.sector_start(sector);
        let sector_bytes = self.geometry.sector_bytes;
        let mut scan = SectorScan::default();
        // `at` stays below the sector's size (a frame is taken only when it ends inside the
        // sector), and every address below the geometry's end: the additions cannot saturate.
        let unit_bytes = ALIGN_BYTES as u32;
        let mut at: u32 = 0;
        while at < sector_bytes {
            let address = start.saturating_add(at);
            let unit = read_unit(flash, address)?;
            if unit == ERASED_UNIT {
                at = at.saturating_add(unit_bytes);
                continue;
            }
            let header = record::parse_header(&unit)
                .filter(|h| (at as usize).saturating_add(h.length_bytes) <= sector_bytes as usize);
            let frame = match header {
                Some(header) if frame_is_valid(flash, address, &header, &unit)? => Some(header),
                _ => None,
            };
            match frame {
                Some(header) => {
                    take_frame(flash, address, &header, &mut scan)?;
                    at = at.saturating_add(header.length_bytes as u32);
                }
                None => {
                    scan.damaged_bytes = scan.damaged_bytes.saturating_add(unit_bytes);
                    at = at.saturating_add(unit_bytes);
                }
            }
            scan.used_bytes = at;
        }
        Ok(scan)
    }
}

/// Files a valid frame: a record of a readable version (checked), or an unknown version
/// (noted).
fn take_frame<F: ReadNorFlash>(
    flash: &mut F,
    address: u32,
    header: &FrameHeader,
    scan: &mut SectorScan,
) -> Result<(), F::Error> {
    scan.max_sequence = scan.max_sequence.max(Some(header.sequence));
    let Some(length) = readable_length(header.version) else {
        let skipped = SkippedFrame {
            version: header.version,
            sequence: header.sequence,
        };
        if scan
            .newer_format
            .is_none_or(|f| f.sequence < skipped.sequence)
        {
            scan.newer_format = Some(skipped);
        }
        return Ok(());
    };
    let mut buffer = [0u8; RECORD_BYTES];
    let Some(bytes) = buffer
        .get_mut(..length)
        .filter(|_| header.length_bytes == length)
    else {
        scan.rejected_records = scan.rejected_records.saturating_add(1);
        return Ok(());
    };
    flash.read(address, bytes)?;
    match record::decode(bytes) {
        Ok((sequence, record)) if scan.newest.is_none_or(|(seq, _)| seq < sequence) => {
            scan.newest = Some((sequence, record));
        }
        Ok(_) => {}
        Err(_) => scan.rejected_records = scan.rejected_records.saturating_add(1),
    }
    Ok(())
}

/// CRC and commit marker of the frame at `address` (of any version), streaming its units.
fn frame_is_valid<F: ReadNorFlash>(
    flash: &mut F,
    address: u32,
    header: &FrameHeader,
    first: &Unit,
) -> Result<bool, F::Error> {
    // The frame lies inside its sector (checked by the caller): no address saturates.
    let last = address.saturating_add(header.length_bytes.saturating_sub(ALIGN_BYTES) as u32);
    let mut crc = Crc32::new();
    let mut unit = *first;
    let mut at = address;
    while at < last {
        crc.update(&unit);
        at = at.saturating_add(ALIGN_BYTES as u32);
        unit = read_unit(flash, at)?;
    }
    let (body, closing) = unit.split_last_chunk::<8>().unwrap_or((&[], &[0; 8]));
    crc.update(body);
    let committed = get_u32(closing, 4) == COMMIT_MARKER;
    Ok(committed && get_u32(closing, 0) == crc.finish())
}

/// Programs a record: blank check, body, read-back, then the commit marker, read-back again.
fn program<F: NorFlash>(
    flash: &mut F,
    address: u32,
    bytes: &[u8; RECORD_BYTES],
) -> Result<(), StoreError<F::Error>> {
    expect_erased(flash, address, address.saturating_add(RECORD_BYTES as u32))?;
    let (body, marker) = bytes.split_at(record::offset::COMMIT);
    flash.write(address, body).map_err(StoreError::Flash)?;
    verify(flash, address, body)?;
    let marker_address = address.saturating_add(body.len() as u32);
    flash
        .write(marker_address, marker)
        .map_err(StoreError::Flash)?;
    verify(flash, address, bytes)
}

/// Compares flash from `address` with `expected`, in units (the tail may be shorter).
fn verify<F: ReadNorFlash>(
    flash: &mut F,
    address: u32,
    expected: &[u8],
) -> Result<(), StoreError<F::Error>> {
    let mut at = address;
    for chunk in expected.chunks(ALIGN_BYTES) {
        let mut buffer = [0u8; ALIGN_BYTES];
        let actual = buffer.get_mut(..chunk.len()).unwrap_or_default();
        flash.read(at, actual).map_err(StoreError::Flash)?;
        if actual != chunk {
            return Err(StoreError::Verify { offset: at });
        }
        at = at.saturating_add(chunk.len() as u32);
    }
    Ok(())
}

fn expect_erased<F: ReadNorFlash>(
    flash: &mut F,
    start: u32,
    end: u32,
) -> Result<(), StoreError<F::Error>> {
    for at in (start..end).step_by(ALIGN_BYTES) {
        if read_unit(flash, at).map_err(StoreError::Flash)? != ERASED_UNIT {
            return Err(StoreError::NotErased { offset: at });
        }
    }
    Ok(())
}

fn read_unit<F: ReadNorFlash>(flash: &mut F, address: u32) -> Result<Unit, F::Error> {
    let mut unit = ERASED_UNIT;
    flash.read(address, &mut unit)?;
    Ok(unit)
}
