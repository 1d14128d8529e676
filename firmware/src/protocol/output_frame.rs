//! The fixed-rate output on the wire: one frame per output record
//! ([`crate::signal::output::record::OutputRecord`]), in the envelope of [`super::cobs`]
//! (COBS, CRC-32, 0x00 delimiter).
//!
//! ```text
//! payload, little-endian:
//!   0  u64  sequence        +1 per record made (a gap on the host = records lost)
//!   8  u64  time            capture-timer ticks (84 MHz) of the latch that ended the period
//!  16  u32  period          ticks
//!  20  i32  delta angle     Q16 fringes: LSB 2^-16 fringe (2.85e-5 arcsec at 1.8655 arcsec/fringe)
//!  24  i64  angle           Q16 fringes, integrated over the valid periods
//!  32  f32  rate            deg/h over the period
//!  36  u16  status          OutputStatus bits (bit 0 VALID)
//!  38  i16  thermal         even sequence: the temperature, 1/128 °C (the TMP117's own LSB);
//!                           odd sequence: its rate, 0.01 °C/min; -32768: none
//! ```
//!
//! 40 bytes of payload, 46 on the wire: 46.0 kB/s at a 1 kHz sync, which 460800 baud
//! (46.08 kB/s of 8N1 bytes) carries; a 2 kHz sync needs 1 Mbaud or more (the F405's USART1
//! does 10.5 Mbit/s).
//!
//! # The thermal word: one field, two quantities
//!
//! The temperature and its rate need 16 bits each, but four more bytes would make the frame
//! 48 bytes, 48 kB/s at the default 1 kHz output: more than 460800 baud carries. So one word
//! alternates by the record's sequence number: the temperature in even records, the rate in odd
//! ones. Both change far slower than the records come (the sensor gives 8 results a second), so
//! a receiver has both, each at most one record old; the sequence number in the same frame
//! says which it is, a lost record included. The status word carries the sensor's fault and
//! whether the model corrected the record (bits 11 and 12) in every record.
//!
//! # Older frames
//!
//! A receiver accepts both lengths: a 38-byte payload is an older firmware's frame (no
//! thermal word: both quantities none). The frame's CRC covers its own length, so one cannot
//! be taken for the other.

use super::cobs::{self, FrameError};
use crate::signal::output::record::{OutputRecord, OutputStatus};
use crate::thermal::state::NO_VALUE;

/// Payload bytes.
pub const OUTPUT_PAYLOAD: usize = 40;
/// Payload bytes of an older firmware's frame (no thermal word).
pub const OUTPUT_PAYLOAD_V1: usize = 38;
/// The most output records a board makes per second: five times the fastest sync it is
/// documented for (2 kHz, which already needs 1 Mbaud). A receiver believes no gap that would
/// need records faster than this.
pub const MAX_OUTPUT_RATE_HZ: f64 = 10_000.0;
/// Largest encoded frame, delimiter included.
pub const MAX_OUTPUT_FRAME: usize = OUTPUT_PAYLOAD + 6;

fn to_bytes(r: &OutputRecord) -> [u8; OUTPUT_PAYLOAD] {
    let mut b = [0u8; OUTPUT_PAYLOAD];
    b[0..8].copy_from_slice(&r.sequence.to_le_bytes());
    b[8..16].copy_from_slice(&r.time_ticks.to_le_bytes());
    b[16..20].copy_from_slice(&r.period_ticks.to_le_bytes());
    b[20..24].copy_from_slice(&r.delta_angle_q16.to_le_bytes());
    b[24..32].copy_from_slice(&r.angle_q16.to_le_bytes());
    b[32..36].copy_from_slice(&r.rate_deg_per_h.to_le_bytes());
    b[36..38].copy_from_slice(&r.status.0.to_le_bytes());
    b[38..40].copy_from_slice(&thermal_word(r).to_le_bytes());
    b
}

/// The thermal word of a record: the temperature in even records, the rate in odd ones.
pub fn thermal_word(r: &OutputRecord) -> i16 {
    if r.sequence.is_multiple_of(2) {
        r.temperature_q7
    } else {
        r.temperature_rate_centi_c_per_min
    }
}

fn from_bytes(b: &[u8; OUTPUT_PAYLOAD], thermal: bool) -> OutputRecord {
    // The fields' offsets lie inside the payload (a fixed layout): `get` never misses.
    let u64_at = |i: usize| {
        u64::from_le_bytes(
            b.get(i..)
                .and_then(|r| r.first_chunk::<8>())
                .copied()
                .unwrap_or_default(),
        )
    };
    let (sequence, time_ticks, angle) = (u64_at(0), u64_at(8), u64_at(24));
    let u32_at = |i: usize| {
        u32::from_le_bytes(
            b.get(i..)
                .and_then(|r| r.first_chunk::<4>())
                .copied()
                .unwrap_or_default(),
        )
    };
    let (period_ticks, delta, rate) = (u32_at(16), u32_at(20), u32_at(32));
    let mut record = OutputRecord {
        sequence,
        time_ticks,
        period_ticks,
        delta_angle_q16: delta as i32,
        angle_q16: angle as i64,
        rate_deg_per_h: f32::from_bits(rate),
        status: OutputStatus(u16::from_le_bytes([b[36], b[37]])),
        temperature_q7: NO_VALUE,
        temperature_rate_centi_c_per_min: NO_VALUE,
    };
    if thermal {
        let word = i16::from_le_bytes([b[38], b[39]]);
        if sequence.is_multiple_of(2) {
            record.temperature_q7 = word;
        } else {
            record.temperature_rate_centi_c_per_min = word;
        }
    }
    record
}

/// Encodes a record's frame into `out`; returns its length (delimiter included).
pub fn encode_output_frame(record: &OutputRecord, out: &mut [u8; MAX_OUTPUT_FRAME]) -> usize {
    cobs::encode(&to_bytes(record), out)
}

/// Decodes one frame (without its 0x00 delimiter): this firmware's, or an older one's
/// without the thermal word. A decoded record holds the one thermal quantity its frame
/// carries; the other is `NO_VALUE`.
pub fn decode_output_frame(encoded: &[u8]) -> Result<OutputRecord, FrameError> {
    let mut payload = [0u8; OUTPUT_PAYLOAD];
    match cobs::decode(encoded, &mut payload) {
        Ok(()) => Ok(from_bytes(&payload, true)),
        Err(FrameError::Malformed) => {
            let mut older = [0u8; OUTPUT_PAYLOAD_V1];
            cobs::decode(encoded, &mut older)?;
            if let Some(head) = payload.get_mut(..OUTPUT_PAYLOAD_V1) {
                head.copy_from_slice(&older);
            }
            Ok(from_bytes(&payload, false))
        }
        Err(e) => Err(e),
    }
}

/// Counts the records lost on the way from the 64-bit sequence numbers a host receives.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct OutputGaps {
    last: Option<u64>,
    /// Records missing between the sequence numbers received.
    pub lost: u64,
    /// Records received.
    pub received: u64,
    /// Frames whose sequence did not advance (a repeat or a board restart): counted, not
    /// taken as a gap.
    pub out_of_order: u64,
    /// Frames whose step forward the receiver could not believe ([`OutputGaps::observe_jump`]:
    /// further than the elapsed time allows): a restart or a corrupt frame, not a gap.
    pub jumps: u64,
}

impl OutputGaps {
    /// One record received with `sequence`: counts it and any gap before it.
    pub fn observe(&mut self, sequence: u64) {
        match self.last {
            Some(last) if sequence > last => {
                self.lost = self
                    .lost
                    .saturating_add(sequence.abs_diff(last).saturating_sub(1));
            }
            Some(_) => self.out_of_order = self.out_of_order.saturating_add(1),
            None => {}
        }
        self.last = Some(sequence);
        self.received = self.received.saturating_add(1);
    }

    /// One record received with `sequence`, whose step from the last one is not believed (the
    /// receiver's clocks do not allow it): counted as a jump, not as lost records.
    pub fn observe_jump(&mut self, sequence: u64) {
        self.last = Some(sequence);
        self.received = self.received.saturating_add(1);
        self.jumps = self.jumps.saturating_add(1);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn record(sequence: u64) -> OutputRecord {
        OutputRecord {
            sequence,
            time_ticks: (84_000_000 * 3600 * 24 * 400u64).wrapping_add(sequence),
            period_ticks: 84_000,
            delta_angle_q16: -123_456,
            angle_q16: -(1 << 40) + 7,
            rate_deg_per_h: -13.888,
            status: OutputStatus::VALID.union(OutputStatus::DITHER_LOCKED),
            temperature_q7: -20 * 128 + 3,
            temperature_rate_centi_c_per_min: -150,
        }
    }

    /// A frame carries the temperature in even records and the rate in odd ones: the decoded
    /// record holds that one (the other none), and everything else exactly.
    #[test]
    fn round_trip_and_no_zero_inside_a_frame() {
        for seq in [0, 1, 255, 256, 1 << 40, u64::MAX] {
            let r = record(seq);
            let mut buf = [0u8; MAX_OUTPUT_FRAME];
            let n = encode_output_frame(&r, &mut buf);
            assert_eq!(n, MAX_OUTPUT_FRAME);
            assert_eq!(buf[n - 1], 0);
            assert!(buf[..n - 1].iter().all(|&b| b != 0));
            let mut want = r;
            if seq % 2 == 0 {
                want.temperature_rate_centi_c_per_min = NO_VALUE;
                assert_eq!(want.temperature_c(), Some(-20.0 + 3.0 / 128.0));
            } else {
                want.temperature_q7 = NO_VALUE;
                assert_eq!(want.temperature_rate_c_per_min(), Some(-1.5));
            }
            assert_eq!(decode_output_frame(&buf[..n - 1]), Ok(want));
        }
    }

    /// An older firmware's 38-byte frame decodes, with no thermal quantities.
    #[test]
    fn an_older_frame_without_the_thermal_word_decodes() {
        let r = record(6);
        let mut older = [0u8; OUTPUT_PAYLOAD_V1 + 6];
        let n = cobs::encode(&to_bytes(&r)[..OUTPUT_PAYLOAD_V1], &mut older);
        let want = OutputRecord {
            temperature_q7: NO_VALUE,
            temperature_rate_centi_c_per_min: NO_VALUE,
            ..r
        };
        assert_eq!(decode_output_frame(&older[..n - 1]), Ok(want));
    }

    /// Any single corrupted byte is caught (COBS structure or CRC), never misread.
    #[test]
    fn corruption_is_detected() {
        let mut buf = [0u8; MAX_OUTPUT_FRAME];
        let n = encode_output_frame(&record(9), &mut buf);
        for i in 0..n - 1 {
            for flip in [0x01u8, 0x80, 0xFF] {
                let mut bad = buf;
                bad[i] ^= flip;
                assert!(
                    decode_output_frame(&bad[..n - 1]).is_err(),
                    "byte {i} {flip:#x}"
                );
            }
        }
        assert_eq!(
            decode_output_frame(&buf[..n - 2]),
            Err(FrameError::Malformed)
        );
    }

    #[test]
    fn gaps_are_counted() {
        let mut g = OutputGaps::default();
        for s in [10, 11, 14, 15, 15, 20] {
            g.observe(s);
        }
        assert_eq!((g.received, g.lost, g.out_of_order), (6, 2 + 4, 1));
    }
}
