//! Links: the byte pipe between the host and a board.
//!
//! [`Link`] is all the client needs: send bytes, receive what arrived within a timeout, and a
//! clock. The real links ([`IoLink`]: a serial port or pty through the `serialport` crate, or a
//! TCP connection) run on the wall clock. The in-process `SimLink` runs a hal-sim `SimDevice` on
//! simulated time, advanced only while the host waits or pauses, so a calibration run or a
//! minute of streaming costs only the simulation's time, and tests are deterministic (with the
//! cargo feature `sim`).

#[cfg(feature = "sim")]
use hal_sim::device::SimDevice;
use std::io::{self, Read, Write};
use std::net::{TcpStream, ToSocketAddrs};
use std::time::{Duration, Instant};

/// A byte pipe to a board, with its clock.
pub trait Link {
    /// Sends all of `bytes`.
    fn send(&mut self, bytes: &[u8]) -> io::Result<()>;
    /// Waits up to `timeout` for bytes and appends what arrived to `out`; returns how many
    /// (0: none within the timeout). A link closed by the other side is an error.
    fn receive(&mut self, out: &mut Vec<u8>, timeout: Duration) -> io::Result<usize>;
    /// Time on the link's clock since it was opened (simulated time for `SimLink`).
    fn elapsed(&self) -> Duration;
    /// Lets `duration` pass on the link's clock without reading (between polls); what arrives
    /// meanwhile is kept for the next [`receive`](Self::receive).
    fn pause(&mut self, duration: Duration);
}

impl<L: Link + ?Sized> Link for Box<L> {
    fn send(&mut self, bytes: &[u8]) -> io::Result<()> {
        (**self).send(bytes)
    }
    fn receive(&mut self, out: &mut Vec<u8>, timeout: Duration) -> io::Result<usize> {
        (**self).receive(out, timeout)
    }
    fn elapsed(&self) -> Duration {
        (**self).elapsed()
    }
    fn pause(&mut self, duration: Duration) {
        (**self).pause(duration)
    }
}

/// A byte stream whose reads can be bounded in time.
pub trait TimedPort: Read + Write {
    /// Bounds how long the next reads wait for bytes (a zero timeout may become the smallest
    /// the port supports, never "forever").
    fn set_read_timeout(&mut self, timeout: Duration) -> io::Result<()>;
}

impl TimedPort for TcpStream {
    fn set_read_timeout(&mut self, timeout: Duration) -> io::Result<()> {
        // A zero timeout means "block forever" to the socket API.
        TcpStream::set_read_timeout(self, Some(timeout.max(Duration::from_millis(1))))
    }
}

impl TimedPort for Box<dyn serialport::SerialPort> {
    fn set_read_timeout(&mut self, timeout: Duration) -> io::Result<()> {
        self.set_timeout(timeout).map_err(io::Error::from)
    }
}

/// A link over a real byte stream (serial port, pty, TCP) on the wall clock.
pub struct IoLink<T> {
    port: T,
    opened: Instant,
    buf: Box<[u8; 4096]>,
}

impl<T: TimedPort> IoLink<T> {
    /// A link over an open `port`; its clock starts now.
    pub fn new(port: T) -> Self {
        Self {
            port,
            opened: Instant::now(),
            buf: Box::new([0; 4096]),
        }
    }
}

impl<T: TimedPort> Link for IoLink<T> {
    fn send(&mut self, bytes: &[u8]) -> io::Result<()> {
        self.port.write_all(bytes)?;
        self.port.flush()
    }

    fn receive(&mut self, out: &mut Vec<u8>, timeout: Duration) -> io::Result<usize> {
        self.port.set_read_timeout(timeout)?;
        match self.port.read(&mut self.buf[..]) {
            Ok(0) => Err(io::Error::new(
                io::ErrorKind::UnexpectedEof,
                "link closed by the other side",
            )),
            Ok(n) => {
                out.extend_from_slice(&self.buf[..n]);
                Ok(n)
            }
            Err(e)
                if matches!(
                    e.kind(),
                    io::ErrorKind::WouldBlock
                        | io::ErrorKind::TimedOut
                        | io::ErrorKind::Interrupted
                ) =>
            {
                Ok(0)
            }
            Err(e) => Err(e),
        }
    }

    fn elapsed(&self) -> Duration {
        self.opened.elapsed()
    }

    fn pause(&mut self, duration: Duration) {
        std::thread::sleep(duration);
    }
}

/// Connects to `HOST:PORT` (each resolved address in turn, `timeout` each).
pub fn tcp(address: &str, timeout: Duration) -> io::Result<IoLink<TcpStream>> {
    let mut last = io::Error::new(io::ErrorKind::NotFound, "no address");
    for addr in address.to_socket_addrs()? {
        match TcpStream::connect_timeout(&addr, timeout) {
            Ok(stream) => {
                stream.set_nodelay(true)?;
                return Ok(IoLink::new(stream));
            }
            Err(e) => last = e,
        }
    }
    Err(last)
}

/// Opens a serial port or pty by path, 8N1 at `baud`, discarding input received before.
pub fn serial(path: &str, baud: u32) -> io::Result<IoLink<Box<dyn serialport::SerialPort>>> {
    let port = serialport::new(path, baud)
        .timeout(Duration::from_millis(100))
        .open()
        .map_err(io::Error::from)?;
    // Stale bytes (an answer nobody read, stream frames) must not pass for an answer.
    port.clear(serialport::ClearBuffer::Input)
        .map_err(io::Error::from)?;
    Ok(IoLink::new(port))
}

/// The simulated board in this process, on simulated time.
#[cfg(feature = "sim")]
pub struct SimLink {
    device: SimDevice,
    start_s: f64,
}

/// Simulated time run per step while waiting for output.
#[cfg(feature = "sim")]
const SIM_WAIT_STEP_S: f64 = 0.005;

#[cfg(feature = "sim")]
impl SimLink {
    /// A link to `device`; its clock starts at the device's current simulated time.
    pub fn new(device: SimDevice) -> Self {
        let start_s = device.time_s();
        Self { device, start_s }
    }

    /// The simulated board.
    pub fn device(&self) -> &SimDevice {
        &self.device
    }

    /// The simulated board, to act on it outside the link (e.g. arm a power cut in its flash).
    pub fn device_mut(&mut self) -> &mut SimDevice {
        &mut self.device
    }

    /// Ends the link and hands back the board (its output not yet received is kept in it).
    pub fn into_device(self) -> SimDevice {
        self.device
    }
}

#[cfg(feature = "sim")]
impl Link for SimLink {
    fn send(&mut self, bytes: &[u8]) -> io::Result<()> {
        self.device.receive(bytes);
        Ok(())
    }

    fn receive(&mut self, out: &mut Vec<u8>, timeout: Duration) -> io::Result<usize> {
        let end_s = self.device.time_s() + timeout.as_secs_f64();
        loop {
            let bytes = self.device.take_output();
            if !bytes.is_empty() {
                out.extend_from_slice(&bytes);
                return Ok(bytes.len());
            }
            let left = end_s - self.device.time_s();
            if left <= 0.0 {
                return Ok(0);
            }
            self.device.run_for(left.min(SIM_WAIT_STEP_S));
        }
    }

    fn elapsed(&self) -> Duration {
        Duration::from_secs_f64((self.device.time_s() - self.start_s).max(0.0))
    }

    fn pause(&mut self, duration: Duration) {
        self.device.run_for(duration.as_secs_f64());
    }
}
