//! Binary streaming of per-cycle records: sequence-numbered, CRC-32 checked, COBS framed.
//!
//! `stream on <n>` switches the serial output to frames (every n-th dither cycle); `stream off`
//! (typed as a line, which the device still parses while streaming) returns to text. A frame:
//!
//! ```text
//! COBS( payload[FRAME_PAYLOAD] || crc32(payload) as u32 LE ) || 0x00
//! payload, little-endian:
//!   0  u32  sequence            (+1 per frame sent; a gap = lost frames)
//!   4  i64  end phase           Q32 fringes at the cycle's closing turnaround (count + fraction)
//!  12  i64  raw increment       Q32 fringes
//!  20  i64  compensated incr.   Q32 fringes
//!  28  f32  P1                  s
//!  32  f32  P2                  s
//!  36  u32  duration            capture-timer ticks
//!  40  u8   flags               output::CycleFlags bits
//! ```
//!
//! 47 bytes on the wire per frame: at 389 Hz that is 18.3 kB/s, so the full dither rate needs
//! 460800 baud or more (the F405's USART does 10 Mbit/s); slower links use a divider. The host
//! decodes with the same [`decode_frame`]; the CRC is the same CRC-32 as the flash records.

use super::cobs;
pub use super::cobs::FrameError;
use crate::signal::lockin::CycleRecord;

/// Payload bytes.
pub const FRAME_PAYLOAD: usize = 41;
/// Largest encoded frame, delimiter included: payload, CRC, one COBS byte, the delimiter.
pub const MAX_FRAME: usize = FRAME_PAYLOAD + 6;

/// One streamed cycle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StreamRecord {
    /// Frame number, +1 per frame sent (wrapping): a gap means lost frames.
    pub sequence: u32,
    /// Total beat phase at the cycle's end, Q32 fringes (wrapping; `CycleRecord::end_phase`).
    pub end_phase_q32: i64,
    /// Beat-phase increment over the cycle before compensation, Q32 fringes.
    pub raw_increment_q32: i64,
    /// The increment after subtracting a P1 + b P2, Q32 fringes.
    pub compensated_increment_q32: i64,
    /// The cycle's lock-in term P1, s.
    pub p1_s: f32,
    /// The cycle's lock-in term P2, s.
    pub p2_s: f32,
    /// Cycle duration, capture-timer ticks (`id` reports the timer's Hz).
    pub duration_ticks: u32,
    /// The cycle's `output::CycleFlags` bits.
    pub flags: u8,
}

impl StreamRecord {
    /// The frame for cycle `c`, numbered `sequence`.
    pub fn from_cycle(sequence: u32, c: &CycleRecord) -> Self {
        Self {
            sequence,
            end_phase_q32: c.end_phase.to_q32(),
            raw_increment_q32: c.raw_increment.to_q32(),
            compensated_increment_q32: c.output.increment.to_q32(),
            p1_s: c.terms.p1_s,
            p2_s: c.terms.p2_s,
            duration_ticks: c.output.duration_ticks,
            flags: c.output.flags.0,
        }
    }

    fn to_bytes(self) -> [u8; FRAME_PAYLOAD] {
        let mut b = [0u8; FRAME_PAYLOAD];
        b[0..4].copy_from_slice(&self.sequence.to_le_bytes());
        b[4..12].copy_from_slice(&self.end_phase_q32.to_le_bytes());
        b[12..20].copy_from_slice(&self.raw_increment_q32.to_le_bytes());
        b[20..28].copy_from_slice(&self.compensated_increment_q32.to_le_bytes());
        b[28..32].copy_from_slice(&self.p1_s.to_le_bytes());
        b[32..36].copy_from_slice(&self.p2_s.to_le_bytes());
        b[36..40].copy_from_slice(&self.duration_ticks.to_le_bytes());
        b[40] = self.flags;
        b
    }

    fn from_bytes(b: &[u8; FRAME_PAYLOAD]) -> Self {
        use super::le_bytes::{i64_at, u32_at};
        Self {
            sequence: u32_at(b, 0),
            end_phase_q32: i64_at(b, 4),
            raw_increment_q32: i64_at(b, 12),
            compensated_increment_q32: i64_at(b, 20),
            p1_s: f32::from_bits(u32_at(b, 28)),
            p2_s: f32::from_bits(u32_at(b, 32)),
            duration_ticks: u32_at(b, 36),
            flags: b[40],
        }
    }
}

/// Encodes a frame into `out`; returns its length (delimiter included).
pub fn encode_frame(record: &StreamRecord, out: &mut [u8; MAX_FRAME]) -> usize {
    cobs::encode(&record.to_bytes(), out)
}

/// Decodes one frame (without its 0x00 delimiter).
pub fn decode_frame(encoded: &[u8]) -> Result<StreamRecord, FrameError> {
    let mut payload = [0u8; FRAME_PAYLOAD];
    cobs::decode(encoded, &mut payload)?;
    Ok(StreamRecord::from_bytes(&payload))
}

/// The frames from `last` to `sequence` (1 = the next one), when `sequence` lies ahead of
/// `last` in the wrapping sequence, by at most 2^31 (a wrap after 2^32 frames, 128 days at
/// 389 Hz, is a step forward); `None` for a repeat or a step back: a board restart (its
/// sequence starts again from 0) or a duplicated frame, neither a gap.
pub fn sequence_step(last: u32, sequence: u32) -> Option<u32> {
    let step = sequence.wrapping_sub(last);
    (1..=1 << 31).contains(&step).then_some(step)
}

/// Counts lost frames from the sequence numbers a host receives.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct GapCounter {
    last: Option<u32>,
    /// Frames missing between the sequence numbers received.
    pub lost: u64,
    /// Frames received.
    pub received: u64,
    /// Frames whose sequence did not step forward ([`sequence_step`]: a repeat or a board
    /// restart): counted, not taken as a gap.
    pub out_of_order: u64,
}

impl GapCounter {
    /// One frame received with `sequence`: counts it and any gap before it.
    pub fn observe(&mut self, sequence: u32) {
        if let Some(last) = self.last {
            match sequence_step(last, sequence) {
                Some(step) => {
                    self.lost = self.lost.saturating_add(u64::from(step).saturating_sub(1))
                }
                None => self.out_of_order = self.out_of_order.saturating_add(1),
            }
        }
        self.last = Some(sequence);
        self.received = self.received.saturating_add(1);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn record(seq: u32) -> StreamRecord {
        StreamRecord {
            sequence: seq,
            end_phase_q32: -0x0000_0100_0000_0000 + seq as i64,
            raw_increment_q32: 0, // zeros exercise COBS
            compensated_increment_q32: 12_345_678_901,
            p1_s: 2.6e-5,
            p2_s: -1.3e-5,
            duration_ticks: 215_938,
            flags: 0b101,
        }
    }

    #[test]
    fn round_trip_and_no_zero_inside_a_frame() {
        for seq in [0, 1, 255, 256, 0x0100_0000, u32::MAX] {
            let r = record(seq);
            let mut buf = [0u8; MAX_FRAME];
            let n = encode_frame(&r, &mut buf);
            assert_eq!(buf[n - 1], 0);
            assert!(buf[..n - 1].iter().all(|&b| b != 0));
            assert_eq!(decode_frame(&buf[..n - 1]), Ok(r));
        }
    }

    /// Any single corrupted byte is caught (COBS structure or CRC), never misread.
    #[test]
    fn corruption_is_detected() {
        let mut buf = [0u8; MAX_FRAME];
        let n = encode_frame(&record(7), &mut buf);
        for i in 0..n - 1 {
            for flip in [0x01u8, 0x80, 0xFF] {
                let mut bad = buf;
                bad[i] ^= flip;
                assert!(
                    decode_frame(&bad[..n - 1]).is_err(),
                    "byte {i} flip {flip:#x}"
                );
            }
        }
        assert_eq!(decode_frame(&buf[..n - 2]), Err(FrameError::Malformed));
        assert_eq!(decode_frame(&[]), Err(FrameError::Malformed));
    }

    /// A board restart (the sequence starts again from 0) and a repeated frame are counted as
    /// out of order, not as about 4.29e9 lost frames; a forward step of up to 2^31 is a gap.
    #[test]
    fn a_restart_or_a_repeat_is_no_gap() {
        let mut g = GapCounter::default();
        for s in [100, 101, 101, 0, 1, 5, 3] {
            g.observe(s);
        }
        assert_eq!((g.received, g.lost, g.out_of_order), (7, 3, 3));
        assert_eq!(sequence_step(u32::MAX, 2), Some(3));
        assert_eq!(sequence_step(0, 1 << 31), Some(1 << 31));
        assert_eq!(sequence_step(0, (1 << 31) + 1), None);
        assert_eq!(sequence_step(7, 7), None);
    }

    #[test]
    fn gaps_are_counted_across_wrap() {
        let mut g = GapCounter::default();
        for s in [u32::MAX - 1, u32::MAX, 2, 3, 10] {
            g.observe(s);
        }
        assert_eq!(g.received, 5);
        assert_eq!(g.lost, 2 + 6);
    }
}
