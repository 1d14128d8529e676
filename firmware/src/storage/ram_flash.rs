//! NOR flash in RAM: for the QEMU serial test (QEMU does not model the F405's flash controller)
//! and the host tests of code that stores through `NorFlash`.
//!
//! NOR semantics, as the real sectors behave: erased bytes read 0xFF, erases are whole sectors,
//! programming is word-aligned and can only clear bits (it ANDs). No timing and no power cuts:
//! hal-sim's `CalibrationFlash` models those.

use embedded_storage::nor_flash::{
    ErrorType, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash,
};

/// `SECTORS` sectors of `SECTOR_BYTES` each, erased at creation.
pub struct RamFlash<const SECTORS: usize, const SECTOR_BYTES: usize> {
    sectors: [[u8; SECTOR_BYTES]; SECTORS],
}

/// Why a RAM flash operation failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum RamFlashError {
    /// The range runs past the end of the last sector.
    OutOfBounds,
    /// A write not on 4-byte words, or an erase not on sector boundaries.
    NotAligned,
}

impl NorFlashError for RamFlashError {
    fn kind(&self) -> NorFlashErrorKind {
        match self {
            Self::OutOfBounds => NorFlashErrorKind::OutOfBounds,
            Self::NotAligned => NorFlashErrorKind::NotAligned,
        }
    }
}

impl<const SECTORS: usize, const SECTOR_BYTES: usize> RamFlash<SECTORS, SECTOR_BYTES> {
    /// All sectors erased.
    pub const fn new() -> Self {
        Self {
            sectors: [[0xFF; SECTOR_BYTES]; SECTORS],
        }
    }

    /// The whole flash as one byte slice.
    pub fn bytes(&self) -> &[u8] {
        self.sectors.as_flattened()
    }

    fn bytes_mut(&mut self) -> &mut [u8] {
        self.sectors.as_flattened_mut()
    }

    /// The bytes from `offset`, `len` long, or `OutOfBounds`.
    fn cells(&mut self, offset: u32, len: usize) -> Result<&mut [u8], RamFlashError> {
        let start = offset as usize;
        let end = start.checked_add(len).ok_or(RamFlashError::OutOfBounds)?;
        self.bytes_mut()
            .get_mut(start..end)
            .ok_or(RamFlashError::OutOfBounds)
    }
}

impl<const SECTORS: usize, const SECTOR_BYTES: usize> Default for RamFlash<SECTORS, SECTOR_BYTES> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const SECTORS: usize, const SECTOR_BYTES: usize> ErrorType
    for RamFlash<SECTORS, SECTOR_BYTES>
{
    type Error = RamFlashError;
}

impl<const SECTORS: usize, const SECTOR_BYTES: usize> ReadNorFlash
    for RamFlash<SECTORS, SECTOR_BYTES>
{
    const READ_SIZE: usize = 1;

    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), RamFlashError> {
        let cells = self.cells(offset, bytes.len())?;
        bytes.copy_from_slice(cells);
        Ok(())
    }

    fn capacity(&self) -> usize {
        self.bytes().len()
    }
}

impl<const SECTORS: usize, const SECTOR_BYTES: usize> NorFlash for RamFlash<SECTORS, SECTOR_BYTES> {
    const WRITE_SIZE: usize = 4;
    const ERASE_SIZE: usize = SECTOR_BYTES;

    fn erase(&mut self, from: u32, to: u32) -> Result<(), RamFlashError> {
        if !(from as usize).is_multiple_of(SECTOR_BYTES)
            || !(to as usize).is_multiple_of(SECTOR_BYTES)
            || to < from
        {
            return Err(RamFlashError::NotAligned);
        }
        let len = to.checked_sub(from).ok_or(RamFlashError::NotAligned)?;
        self.cells(from, len as usize)?.fill(0xFF);
        Ok(())
    }

    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), RamFlashError> {
        if !offset.is_multiple_of(4) || !bytes.len().is_multiple_of(4) {
            return Err(RamFlashError::NotAligned);
        }
        for (cell, &b) in self.cells(offset, bytes.len())?.iter_mut().zip(bytes) {
            *cell &= b;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nor_semantics() {
        let mut f = RamFlash::<2, 1024>::new();
        assert_eq!(f.capacity(), 2048);
        f.write(4, &[0x0F, 0xF0, 0x00, 0xFF]).unwrap();
        f.write(4, &[0xFF, 0x0F, 0xFF, 0x0F]).unwrap(); // programming only clears bits
        let mut b = [0u8; 4];
        f.read(4, &mut b).unwrap();
        assert_eq!(b, [0x0F, 0x00, 0x00, 0x0F]);
        assert_eq!(f.write(2, &[0; 4]), Err(RamFlashError::NotAligned));
        assert_eq!(f.write(2046, &[0; 4]), Err(RamFlashError::NotAligned));
        assert_eq!(f.write(2044, &[0; 8]), Err(RamFlashError::OutOfBounds));
        assert_eq!(f.erase(0, 100), Err(RamFlashError::NotAligned));
        f.erase(0, 1024).unwrap();
        f.read(4, &mut b).unwrap();
        assert_eq!(b, [0xFF; 4]);
    }
}
