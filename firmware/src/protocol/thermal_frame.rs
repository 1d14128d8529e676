//! The block's temperature and its rate in the fixed-rate output stream: a short frame of its
//! own, sent before the first record whose values differ from the last ones sent, in the
//! envelope of [`super::cobs`].
//!
//! ```text
//! payload, little-endian:
//!   0  u64  from sequence   the first output record the values hold for
//!   8  i16  temperature     1/128 °C (the TMP117's own LSB); -32768: none (no reading, a fault)
//!  10  i16  rate            0.01 °C/min; -32768: not known yet
//! ```
//!
//! 12 bytes of payload, [`THERMAL_FRAME`] = 18 on the wire. A receiver tells it from a record's
//! frame by its length (the CRC covers the length: one cannot be taken for the other).
//!
//! # Why not a field in every record's frame
//!
//! Every record carries the temperature and its rate on the board (`OutputRecord`), and its
//! status word carries the sensor's fault and whether the model corrected it (bits 11 and 12),
//! on the wire too. The two 16-bit values would make each record's frame 48 bytes: 48 kB/s at
//! the default 1 kHz output, more than 460 800 Bd carries (46.08 kB/s of 8N1 bytes). They change
//! only with the sensor's results (8 a second), so they go on change: [`ThermalFramer`] puts a
//! frame before the first streamed record whose values differ from the last frame's, before the
//! stream's first record, and at least every [`REFRESH_RECORDS`] records (a receiver that
//! started late or lost a frame to corruption has them again within about a second). At most
//! 9 frames a second: 162 B/s, so the 1 kHz stream takes 44.16 kB/s of 46.08, and a command's
//! answer shares the 1.9 kB/s left (a 100-byte answer: 52 ms) without a record lost.
//!
//! Raising the link to 921 600 Bd instead (BRR 5.6875 at 84 MHz: 923 077 Bd, +0.16 %) would
//! halve the character time the receive interrupt must meet to 10.85 us, and the three
//! handlers above it hold it off for up to 18 us (`board::resources`): the dither drive's
//! half-cycle tick alone takes 12.2 us, twice per dither cycle. Bytes of a command line would
//! be lost to overruns.
//!
//! The receiver ([`super::output_frame::OutputStreamDecoder`]) gives every record the values
//! of the last thermal frame whose sequence it has reached; records of an older firmware (no
//! thermal frames) have none.

use super::cobs::{self, FrameError};
use crate::signal::output::record::OutputRecord;
use crate::thermal::state::NO_VALUE;

/// Payload bytes of a thermal frame.
pub const THERMAL_PAYLOAD: usize = 12;
/// Encoded thermal frame, delimiter included.
pub const THERMAL_FRAME: usize = THERMAL_PAYLOAD + 6;
/// A thermal frame goes out at least every this many streamed records (about 1 s at 1 kHz).
pub const REFRESH_RECORDS: u32 = 1024;

/// The temperature and its rate from one output record on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ThermalFrame {
    /// The first record (sequence number) the values hold for.
    pub from_sequence: u64,
    /// 1/128 °C, `NO_VALUE` for none.
    pub temperature_q7: i16,
    /// 0.01 °C/min, `NO_VALUE` while unknown.
    pub rate_centi_c_per_min: i16,
}

impl ThermalFrame {
    /// The values `record` carries, from it on.
    pub fn of(record: &OutputRecord) -> Self {
        Self {
            from_sequence: record.sequence,
            temperature_q7: record.temperature_q7,
            rate_centi_c_per_min: record.temperature_rate_centi_c_per_min,
        }
    }

    /// `record` with this frame's values (none when the frame starts after it).
    pub fn fill(&self, record: &mut OutputRecord) {
        let holds = record.sequence >= self.from_sequence;
        record.temperature_q7 = if holds { self.temperature_q7 } else { NO_VALUE };
        record.temperature_rate_centi_c_per_min = if holds {
            self.rate_centi_c_per_min
        } else {
            NO_VALUE
        };
    }
}

/// Encodes a thermal frame into `out`; returns its length (delimiter included).
pub fn encode_thermal_frame(frame: &ThermalFrame, out: &mut [u8; THERMAL_FRAME]) -> usize {
    let mut b = [0u8; THERMAL_PAYLOAD];
    let (sequence, values) = b.split_at_mut(8);
    sequence.copy_from_slice(&frame.from_sequence.to_le_bytes());
    let (temperature, rate) = values.split_at_mut(2);
    temperature.copy_from_slice(&frame.temperature_q7.to_le_bytes());
    rate.copy_from_slice(&frame.rate_centi_c_per_min.to_le_bytes());
    cobs::encode(&b, out)
}

/// Decodes one thermal frame (without its 0x00 delimiter).
pub fn decode_thermal_frame(encoded: &[u8]) -> Result<ThermalFrame, FrameError> {
    let mut b = [0u8; THERMAL_PAYLOAD];
    cobs::decode(encoded, &mut b)?;
    let [s0, s1, s2, s3, s4, s5, s6, s7, t0, t1, r0, r1] = b;
    Ok(ThermalFrame {
        from_sequence: u64::from_le_bytes([s0, s1, s2, s3, s4, s5, s6, s7]),
        temperature_q7: i16::from_le_bytes([t0, t1]),
        rate_centi_c_per_min: i16::from_le_bytes([r0, r1]),
    })
}

/// The board's side: which thermal frame, if any, goes before a streamed record.
#[derive(Clone, Copy, Debug, Default)]
pub struct ThermalFramer {
    /// The values of the last frame sent; `None`: none sent in this stream (or it was lost).
    last: Option<(i16, i16)>,
    /// Records streamed since the last frame.
    since: u32,
}

impl ThermalFramer {
    /// The frame to send before `record`, if its values are new to the receiver (see the
    /// module docs). Counts it as sent: a frame that could not be queued is [`Self::restart`].
    pub fn before(&mut self, record: &OutputRecord) -> Option<ThermalFrame> {
        let values = (
            record.temperature_q7,
            record.temperature_rate_centi_c_per_min,
        );
        self.since = self.since.saturating_add(1);
        if self.last == Some(values) && self.since < REFRESH_RECORDS {
            return None;
        }
        self.last = Some(values);
        self.since = 0;
        Some(ThermalFrame::of(record))
    }

    /// The stream stopped, or a frame was not sent: the next record gets one.
    pub fn restart(&mut self) {
        self.last = None;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::signal::output::record::OutputStatus;

    fn record(sequence: u64, temperature_q7: i16, rate: i16) -> OutputRecord {
        OutputRecord {
            sequence,
            time_ticks: 0,
            period_ticks: 84_000,
            delta_angle_q16: 0,
            angle_q16: 0,
            rate_deg_per_h: 0.0,
            status: OutputStatus::VALID,
            temperature_q7,
            temperature_rate_centi_c_per_min: rate,
        }
    }

    #[test]
    fn round_trip_and_length() {
        let f = ThermalFrame {
            from_sequence: u64::MAX - 3,
            temperature_q7: -20 * 128 + 3,
            rate_centi_c_per_min: NO_VALUE,
        };
        let mut buf = [0u8; THERMAL_FRAME];
        let n = encode_thermal_frame(&f, &mut buf);
        assert_eq!(n, THERMAL_FRAME);
        assert!(buf[..n - 1].iter().all(|&b| b != 0));
        assert_eq!(decode_thermal_frame(&buf[..n - 1]), Ok(f));
    }

    /// A frame before the stream's first record, on every change, every REFRESH_RECORDS
    /// records without one, and again after a restart (a frame not queued).
    #[test]
    fn frames_go_on_change_and_refresh() {
        let mut framer = ThermalFramer::default();
        let mut sent = Vec::new();
        for seq in 0..3000u64 {
            let temperature = if seq < 500 { 3000 } else { 3001 };
            if seq == 2500 {
                framer.restart();
            }
            if let Some(f) = framer.before(&record(seq, temperature, 12)) {
                sent.push(f.from_sequence);
            }
        }
        assert_eq!(sent, [0, 500, 1524, 2500]);
    }

    /// The receiver fills a record only from the frame's sequence on.
    #[test]
    fn fills_from_its_sequence_on() {
        let f = ThermalFrame::of(&record(10, 3200, -40));
        let mut before = record(9, NO_VALUE, NO_VALUE);
        f.fill(&mut before);
        assert_eq!(before.temperature_c(), None);
        let mut after = record(11, NO_VALUE, NO_VALUE);
        f.fill(&mut after);
        assert_eq!(after.temperature_c(), Some(25.0));
        assert_eq!(after.temperature_rate_c_per_min(), Some(-0.4));
    }
}
