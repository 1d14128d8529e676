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
/// included; returns the length (`payload.len() + 6`). `out` must hold that many bytes.
pub fn encode(payload: &[u8], out: &mut [u8]) -> usize {
    let len = payload.len().min(MAX_PAYLOAD);
    let crc = crc32(&payload[..len]).to_le_bytes();
    let body = payload[..len].iter().chain(crc.iter());
    // Each zero is replaced by the distance to the next zero (or the end).
    let mut code_at = 0;
    let mut code: u8 = 1;
    let mut n = 1;
    for &byte in body {
        if byte == 0 {
            out[code_at] = code;
            code_at = n;
            code = 1;
        } else {
            out[n] = byte;
            code += 1;
        }
        n += 1;
    }
    out[code_at] = code;
    out[n] = 0;
    n + 1
}

/// Decodes one frame (without its 0x00 delimiter) into `payload`, whose length is the
/// expected payload length; checks the CRC.
pub fn decode(encoded: &[u8], payload: &mut [u8]) -> Result<(), FrameError> {
    let want = payload.len() + 4;
    if want > MAX_PAYLOAD + 4 {
        return Err(FrameError::Malformed);
    }
    let mut body = [0u8; MAX_PAYLOAD + 4];
    let mut n = 0;
    let mut i = 0;
    while i < encoded.len() {
        let code = encoded[i] as usize;
        // A block is its code byte plus code - 1 data bytes, and must end inside the frame.
        if code == 0 || i + code > encoded.len() {
            return Err(FrameError::Malformed);
        }
        for &byte in &encoded[i + 1..i + code] {
            if byte == 0 || n >= want {
                return Err(FrameError::Malformed);
            }
            body[n] = byte;
            n += 1;
        }
        i += code;
        // Every block but the last and but a full 0xFF block stands for a following zero.
        if i < encoded.len() && code != 0xFF {
            if n >= want {
                return Err(FrameError::Malformed);
            }
            body[n] = 0;
            n += 1;
        }
    }
    if n != want {
        return Err(FrameError::Malformed);
    }
    let (data, crc) = body[..want].split_at(want - 4);
    if u32::from_le_bytes([crc[0], crc[1], crc[2], crc[3]]) != crc32(data) {
        return Err(FrameError::BadCrc);
    }
    payload.copy_from_slice(data);
    Ok(())
}
