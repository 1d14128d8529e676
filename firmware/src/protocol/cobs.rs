//! The binary frames' envelope, shared by the per-cycle stream ([`super::stream`]) and the
//! fixed-rate output ([`super::output_frame`]): `COBS(payload || crc32(payload) LE) || 0x00`.
//!
//! COBS (consistent overhead byte stuffing) removes every zero from the body, so 0x00 delimits
//! frames and a receiver resynchronises at the next delimiter after any loss; the CRC-32 (the
//! flash records' own, `storage::crc`) catches corruption. Bodies are at most 253 bytes: one
//! COBS block, one byte of overhead.

use crate::storage::crc::crc32;

/// Largest payload a frame carries, bytes (payload + CRC in one COBS block).
pub const MAX_PAYLOAD: usize = 249;

/// Why a frame was dropped.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FrameError {
    /// Wrong length or broken COBS structure.
    Malformed,
    /// The CRC-32 does not match the payload.
    BadCrc,
}

/// Encodes `payload` (at most [`MAX_PAYLOAD`] bytes) with its CRC into `out`, the delimiter
/// included; returns the length (`payload.len() + 6`). `out` must hold that many bytes (the
/// callers pass arrays of the frame's size; bytes beyond `out` would be left out).
pub fn encode(payload: &[u8], out: &mut [u8]) -> usize {
    let data = payload.get(..MAX_PAYLOAD).unwrap_or(payload);
    let crc = crc32(data).to_le_bytes();
    let mut put = |at: usize, byte: u8| {
        if let Some(slot) = out.get_mut(at) {
            *slot = byte;
        }
    };
    // Each zero is replaced by the distance to the next zero (or the end). At most 253 bytes
    // of body: `code` stays below 255 and `n` below 256, so the additions cannot wrap.
    let mut code_at = 0;
    let mut code: u8 = 1;
    let mut n: usize = 1;
    for &byte in data.iter().chain(crc.iter()) {
        if byte == 0 {
            put(code_at, code);
            code_at = n;
            code = 1;
        } else {
            put(n, byte);
            code = code.wrapping_add(1);
        }
        n = n.wrapping_add(1);
    }
    put(code_at, code);
    put(n, 0);
    n.wrapping_add(1)
}

/// Decodes one frame (without its 0x00 delimiter) into `payload`, whose length is the
/// expected payload length; checks the CRC.
pub fn decode(encoded: &[u8], payload: &mut [u8]) -> Result<(), FrameError> {
    let want = payload
        .len()
        .checked_add(4)
        .filter(|&w| w <= MAX_PAYLOAD + 4)
        .ok_or(FrameError::Malformed)?;
    let mut body = [0u8; MAX_PAYLOAD + 4];
    let mut n: usize = 0;
    // Appends a body byte; more than `want` is malformed. `n < want <= 253`: no wrap.
    let mut push = |n: &mut usize, byte: u8| -> Result<(), FrameError> {
        let slot = body
            .get_mut(*n)
            .filter(|_| *n < want)
            .ok_or(FrameError::Malformed)?;
        *slot = byte;
        *n = n.wrapping_add(1);
        Ok(())
    };
    let mut rest = encoded;
    while let Some((&code, after)) = rest.split_first() {
        // A block is its code byte plus code - 1 data bytes, and must end inside the frame.
        let data_len = usize::from(code)
            .checked_sub(1)
            .ok_or(FrameError::Malformed)?;
        let (data, tail) = after
            .split_at_checked(data_len)
            .ok_or(FrameError::Malformed)?;
        for &byte in data {
            if byte == 0 {
                return Err(FrameError::Malformed);
            }
            push(&mut n, byte)?;
        }
        rest = tail;
        // Every block but the last and but a full 0xFF block stands for a following zero.
        if !rest.is_empty() && code != 0xFF {
            push(&mut n, 0)?;
        }
    }
    if n != want {
        return Err(FrameError::Malformed);
    }
    let (data, crc) = body
        .get(..want)
        .and_then(|b| b.split_last_chunk::<4>())
        .ok_or(FrameError::Malformed)?;
    if u32::from_le_bytes(*crc) != crc32(data) {
        return Err(FrameError::BadCrc);
    }
    payload.copy_from_slice(data);
    Ok(())
}
