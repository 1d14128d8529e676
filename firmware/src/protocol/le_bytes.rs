//! Little-endian fields read from a frame's payload at fixed offsets, shared by the frame
//! decoders (`stream`, `output_frame`).
//!
//! A decoder's payload is a fixed-size array and its layout puts every field inside it, so a
//! read never misses; should an offset ever lie outside (a layout edited wrongly), the field
//! reads as 0 instead of panicking (the crate's no-panic rule), and the decoders' round-trip
//! tests show it.

/// The `u32` at byte `offset`.
pub fn u32_at(payload: &[u8], offset: usize) -> u32 {
    u32::from_le_bytes(field(payload, offset))
}

/// The `u64` at byte `offset`.
pub fn u64_at(payload: &[u8], offset: usize) -> u64 {
    u64::from_le_bytes(field(payload, offset))
}

/// The `i64` at byte `offset`.
pub fn i64_at(payload: &[u8], offset: usize) -> i64 {
    i64::from_le_bytes(field(payload, offset))
}

fn field<const N: usize>(payload: &[u8], offset: usize) -> [u8; N] {
    payload
        .get(offset..)
        .and_then(|rest| rest.first_chunk::<N>())
        .copied()
        .unwrap_or([0; N])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fields_read_little_endian_and_outside_read_zero() {
        let b = [1, 2, 3, 4, 5, 6, 7, 8, 9];
        assert_eq!(u32_at(&b, 0), 0x0403_0201);
        assert_eq!(u32_at(&b, 5), 0x0908_0706);
        assert_eq!(u64_at(&b, 1), 0x0908_0706_0504_0302);
        assert_eq!(i64_at(&[0xff; 8], 0), -1);
        assert_eq!(u32_at(&b, 6), 0, "a field past the end");
        assert_eq!(u64_at(&b, 100), 0);
    }
}
