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
//!  36  u16  status          OutputStatus bits (bit 0 VALID; 11 thermal sensor fault, 12
//!                           thermally corrected)
//! ```
//!
//! 38 bytes of payload, 44 on the wire: 44 kB/s at a 1 kHz sync, which 460800 baud (46.08 kB/s)
//! carries; a 2 kHz sync needs 1 Mbaud or more (the F405's USART1 does 10.5 Mbit/s).
//!
//! The block's temperature and its rate travel in the same stream, in a frame of their own
//! sent when they change ([`super::thermal_frame`], which says why); a receiver reads both
//! kinds with [`OutputStreamDecoder`], which gives each record the values in force for it.

use super::cobs::{self, FrameError};
use super::thermal_frame::{decode_thermal_frame, ThermalFrame, THERMAL_FRAME};
use crate::signal::output::record::{OutputRecord, OutputStatus};
use crate::thermal::state::NO_VALUE;

/// Payload bytes.
pub const OUTPUT_PAYLOAD: usize = 38;
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
    b
}

fn from_bytes(b: &[u8; OUTPUT_PAYLOAD]) -> OutputRecord {
    use super::le_bytes::{u32_at, u64_at};
    let (sequence, time_ticks, angle) = (u64_at(b, 0), u64_at(b, 8), u64_at(b, 24));
    let (period_ticks, delta, rate) = (u32_at(b, 16), u32_at(b, 20), u32_at(b, 32));
    OutputRecord {
        sequence,
        time_ticks,
        period_ticks,
        delta_angle_q16: delta as i32,
        angle_q16: angle as i64,
        rate_deg_per_h: f32::from_bits(rate),
        status: OutputStatus(u16::from_le_bytes([b[36], b[37]])),
        temperature_q7: NO_VALUE,
        temperature_rate_centi_c_per_min: NO_VALUE,
    }
}

/// Encodes a record's frame into `out`; returns its length (delimiter included). The
/// record's temperature and rate are not in it ([`super::thermal_frame`]).
pub fn encode_output_frame(record: &OutputRecord, out: &mut [u8; MAX_OUTPUT_FRAME]) -> usize {
    cobs::encode(&to_bytes(record), out)
}

/// Decodes one record's frame (without its 0x00 delimiter); the temperature and its rate are
/// none (the stream's thermal frames carry them: [`OutputStreamDecoder`]).
pub fn decode_output_frame(encoded: &[u8]) -> Result<OutputRecord, FrameError> {
    let mut payload = [0u8; OUTPUT_PAYLOAD];
    cobs::decode(encoded, &mut payload)?;
    Ok(from_bytes(&payload))
}

/// A thermal frame's length without its delimiter.
const THERMAL_ENCODED: usize = THERMAL_FRAME - 1;

/// One frame of the output stream.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum OutputStreamFrame {
    /// A record, with the temperature and rate of the thermal frame in force for it.
    Record(OutputRecord),
    /// New thermal values (already taken into account for the records that follow).
    Thermal(ThermalFrame),
}

/// The receiver of the output stream: records and thermal frames, told apart by length.
#[derive(Clone, Copy, Debug, Default)]
pub struct OutputStreamDecoder {
    thermal: Option<ThermalFrame>,
}

impl OutputStreamDecoder {
    /// Decodes one 0x00-delimited chunk (without the delimiter).
    pub fn decode(&mut self, encoded: &[u8]) -> Result<OutputStreamFrame, FrameError> {
        // A record's frame is 43 bytes without its delimiter, a thermal frame 17: the length
        // says which to try.
        if encoded.len() == THERMAL_ENCODED {
            let frame = decode_thermal_frame(encoded)?;
            self.thermal = Some(frame);
            return Ok(OutputStreamFrame::Thermal(frame));
        }
        let mut record = decode_output_frame(encoded)?;
        if let Some(thermal) = &self.thermal {
            thermal.fill(&mut record);
        }
        Ok(OutputStreamFrame::Record(record))
    }

    /// Forgets the thermal values (a new stream: they come again before its first record).
    pub fn restart(&mut self) {
        self.thermal = None;
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

    /// A record's frame carries every field but the thermal values, exactly.
    #[test]
    fn round_trip_and_no_zero_inside_a_frame() {
        for seq in [0, 1, 255, 256, 1 << 40, u64::MAX] {
            let r = record(seq);
            let mut buf = [0u8; MAX_OUTPUT_FRAME];
            let n = encode_output_frame(&r, &mut buf);
            assert_eq!(n, MAX_OUTPUT_FRAME);
            assert_eq!(buf[n - 1], 0);
            assert!(buf[..n - 1].iter().all(|&b| b != 0));
            let want = OutputRecord {
                temperature_q7: NO_VALUE,
                temperature_rate_centi_c_per_min: NO_VALUE,
                ..r
            };
            assert_eq!(decode_output_frame(&buf[..n - 1]), Ok(want));
        }
    }

    /// The board's framer and the host's decoder together: every record decodes with the
    /// values it carried on the board; a stream of an older firmware (records only) decodes
    /// with none.
    #[test]
    fn the_stream_carries_every_records_thermal_values() {
        use crate::protocol::thermal_frame::{encode_thermal_frame, ThermalFramer, THERMAL_FRAME};
        let mut framer = ThermalFramer::default();
        let mut decoder = OutputStreamDecoder::default();
        let mut older = OutputStreamDecoder::default();
        let (mut thermal_frames, mut bytes) = (0, 0);
        for seq in 0..2000u64 {
            let mut r = record(seq);
            r.temperature_q7 = 3000 + (seq / 125) as i16;
            r.temperature_rate_centi_c_per_min = if seq < 300 { NO_VALUE } else { 48 };
            if let Some(f) = framer.before(&r) {
                let mut buf = [0u8; THERMAL_FRAME];
                let n = encode_thermal_frame(&f, &mut buf);
                assert!(matches!(
                    decoder.decode(&buf[..n - 1]),
                    Ok(OutputStreamFrame::Thermal(_))
                ));
                thermal_frames += 1;
                bytes += n;
            }
            let mut buf = [0u8; MAX_OUTPUT_FRAME];
            let n = encode_output_frame(&r, &mut buf);
            bytes += n;
            assert_eq!(
                decoder.decode(&buf[..n - 1]),
                Ok(OutputStreamFrame::Record(r))
            );
            let Ok(OutputStreamFrame::Record(old)) = older.decode(&buf[..n - 1]) else {
                panic!("a record");
            };
            assert_eq!((old.temperature_c(), old.sequence), (None, seq));
        }
        // 2 s at 1 kHz, the temperature changing 8 times a second, the rate known after
        // 0.3 s: 16 + 1 frames, 44 bytes per record and 18 per thermal frame.
        assert_eq!(thermal_frames, 17);
        assert_eq!(bytes, 2000 * 44 + 17 * 18);
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
