//! The board's serial link (the calibration protocol's UART or USB CDC) as an in-memory duplex
//! pair implementing `embedded-io` 0.6, with optional seeded line noise.
//!
//! # Model
//!
//! [`serial_link`] returns two [`SerialEnd`]s, the host end and the device end. Each direction
//! is a bounded byte queue (the receiver's buffer); bytes written at one end can be read at the
//! other in order. Both ends implement [`Read`], [`Write`], [`ReadReady`] and [`WriteReady`], and
//! are `Send`, so the host side may run in another thread.
//!
//! Nothing in a single-threaded simulation can block, so the ends never block:
//!
//! - `read` with an empty queue returns `Err(SerialError::WouldBlock)` (kind `TimedOut`: a
//!   blocking read with a zero timeout); poll [`ReadReady::read_ready`] first. Once the other
//!   end is dropped and the queue is drained, `read` returns `Ok(0)`: end of file. A read into an
//!   empty buffer returns `Ok(0)` as the trait allows.
//! - `write` stores as many bytes as fit and returns how many; with the queue full it returns
//!   `Err(SerialError::WouldBlock)` (it never returns `Ok(0)` for a non-empty buffer, as the
//!   trait requires). Bytes written after the other end was dropped vanish, as on a real line.
//!   `flush` does nothing: bytes are on the wire as soon as they are written.
//!
//! Line noise ([`LineNoise`]) acts on the wire, per direction, at write time: each byte is
//! dropped with probability `drop_probability` (a framing error the receiver discards) or else
//! has one random bit flipped with probability `corrupt_probability`. Each direction draws from
//! its own ChaCha8 stream derived from the seed, so the same seed and the same bytes give the
//! same damage, independently of how the other direction is used. Dropped bytes still count as
//! written and take no queue space.
//!
//! ```
//! use embedded_io::{Read, ReadReady, Write};
//! use hal_sim::serial::{serial_link, SerialConfig};
//!
//! let (mut host, mut device) = serial_link(SerialConfig::default(), 0);
//! host.write_all(b"get p1\n").unwrap();
//! let mut line = [0; 16];
//! assert!(device.read_ready().unwrap());
//! let n = device.read(&mut line).unwrap();
//! assert_eq!(&line[..n], b"get p1\n");
//! assert!(device.read(&mut line).is_err()); // nothing more: WouldBlock, not EOF
//! ```
//!
//! # Limits
//!
//! - No baud rate: bytes arrive instantly, however many are sent. Protocol timing (a 115200 Bd
//!   UART carries ~11.5 kB/s) is not modelled.
//! - No hardware flow control and no overrun: a full queue refuses bytes instead of losing them.
//! - Noise is independent per byte (no bursts), and corruption never inserts bytes.

use std::collections::VecDeque;
use std::sync::{Arc, Mutex, MutexGuard};

use embedded_io::{ErrorKind, ErrorType, Read, ReadReady, Write, WriteReady};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Per-byte damage on one direction of the line.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct LineNoise {
    /// Probability that a byte is lost.
    pub drop_probability: f64,
    /// Probability that a byte that is not lost has one bit flipped.
    pub corrupt_probability: f64,
}

impl LineNoise {
    /// A clean line.
    pub const NONE: Self = Self {
        drop_probability: 0.0,
        corrupt_probability: 0.0,
    };
}

/// The link's settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SerialConfig {
    /// Receive buffer size of each end (bytes), > 0.
    pub capacity_bytes: usize,
    /// Noise on bytes the host sends to the device.
    pub host_to_device: LineNoise,
    /// Noise on bytes the device sends to the host.
    pub device_to_host: LineNoise,
}

impl Default for SerialConfig {
    /// 1 KiB buffers, clean line.
    fn default() -> Self {
        Self {
            capacity_bytes: 1024,
            host_to_device: LineNoise::NONE,
            device_to_host: LineNoise::NONE,
        }
    }
}

/// Errors of a serial end.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SerialError {
    /// Nothing to read, or no room to write: try again later.
    WouldBlock,
}

impl embedded_io::Error for SerialError {
    fn kind(&self) -> ErrorKind {
        ErrorKind::TimedOut
    }
}

/// One direction of the line.
#[derive(Debug)]
struct Direction {
    queue: VecDeque<u8>,
    noise: LineNoise,
    rng: ChaCha8Rng,
    receiver_alive: bool,
    sender_alive: bool,
}

impl Direction {
    fn new(noise: LineNoise, seed: u64, stream: u64, capacity: usize) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        rng.set_stream(stream);
        Self {
            queue: VecDeque::with_capacity(capacity),
            noise,
            rng,
            receiver_alive: true,
            sender_alive: true,
        }
    }

    /// Put `byte` on the wire: maybe lost, maybe corrupted, then queued.
    fn transmit(&mut self, byte: u8) {
        if self.noise.drop_probability > 0.0 && self.rng.random_bool(self.noise.drop_probability) {
            return;
        }
        let mut byte = byte;
        if self.noise.corrupt_probability > 0.0
            && self.rng.random_bool(self.noise.corrupt_probability)
        {
            byte ^= 1 << self.rng.random_range(0..8);
        }
        if self.receiver_alive {
            self.queue.push_back(byte);
        }
    }
}

#[derive(Debug)]
struct Link {
    capacity: usize,
    /// Index 0: host -> device, 1: device -> host.
    directions: [Direction; 2],
}

/// Which end of the link.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Side {
    Host,
    Device,
}

impl Side {
    fn tx(self) -> usize {
        match self {
            Self::Host => 0,
            Self::Device => 1,
        }
    }

    fn rx(self) -> usize {
        1 - self.tx()
    }
}

/// One end of the serial link.
#[derive(Debug)]
pub struct SerialEnd {
    link: Arc<Mutex<Link>>,
    side: Side,
}

/// A connected pair `(host, device)`. `seed` drives the line noise.
pub fn serial_link(config: SerialConfig, seed: u64) -> (SerialEnd, SerialEnd) {
    assert!(config.capacity_bytes > 0, "capacity must be positive");
    let capacity = config.capacity_bytes;
    let link = Arc::new(Mutex::new(Link {
        capacity,
        directions: [
            Direction::new(config.host_to_device, seed, 0, capacity),
            Direction::new(config.device_to_host, seed, 1, capacity),
        ],
    }));
    let end = |side| SerialEnd {
        link: Arc::clone(&link),
        side,
    };
    (end(Side::Host), end(Side::Device))
}

impl SerialEnd {
    fn lock(&self) -> MutexGuard<'_, Link> {
        self.link
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner())
    }

    /// Which end this is.
    pub fn side(&self) -> Side {
        self.side
    }

    /// Bytes waiting to be read at this end.
    pub fn available(&self) -> usize {
        self.lock().directions[self.side.rx()].queue.len()
    }

    /// Free space in the other end's receive queue (bytes).
    pub fn room(&self) -> usize {
        let link = self.lock();
        link.capacity - link.directions[self.side.tx()].queue.len()
    }
}

impl Drop for SerialEnd {
    fn drop(&mut self) {
        let side = self.side;
        let mut link = self.lock();
        link.directions[side.tx()].sender_alive = false;
        link.directions[side.rx()].receiver_alive = false;
        link.directions[side.rx()].queue.clear();
    }
}

impl ErrorType for SerialEnd {
    type Error = SerialError;
}

impl Read for SerialEnd {
    fn read(&mut self, buf: &mut [u8]) -> Result<usize, SerialError> {
        if buf.is_empty() {
            return Ok(0);
        }
        let rx = self.side.rx();
        let mut link = self.lock();
        let direction = &mut link.directions[rx];
        if direction.queue.is_empty() {
            return if direction.sender_alive {
                Err(SerialError::WouldBlock)
            } else {
                Ok(0)
            };
        }
        let n = buf.len().min(direction.queue.len());
        for (slot, byte) in buf.iter_mut().zip(direction.queue.drain(..n)) {
            *slot = byte;
        }
        Ok(n)
    }
}

impl ReadReady for SerialEnd {
    /// True when bytes are waiting or the other end is gone (a read then returns EOF).
    fn read_ready(&mut self) -> Result<bool, SerialError> {
        let link = self.lock();
        let direction = &link.directions[self.side.rx()];
        Ok(!direction.queue.is_empty() || !direction.sender_alive)
    }
}

impl Write for SerialEnd {
    fn write(&mut self, buf: &[u8]) -> Result<usize, SerialError> {
        if buf.is_empty() {
            return Ok(0);
        }
        let tx = self.side.tx();
        let mut link = self.lock();
        let capacity = link.capacity;
        let direction = &mut link.directions[tx];
        let mut written = 0;
        for &byte in buf {
            if direction.queue.len() >= capacity {
                break;
            }
            direction.transmit(byte);
            written += 1;
        }
        if written == 0 {
            Err(SerialError::WouldBlock)
        } else {
            Ok(written)
        }
    }

    fn flush(&mut self) -> Result<(), SerialError> {
        Ok(())
    }
}

impl WriteReady for SerialEnd {
    /// True when at least one byte fits.
    fn write_ready(&mut self) -> Result<bool, SerialError> {
        Ok(self.room() > 0)
    }
}
