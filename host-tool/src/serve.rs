//! The simulated board served on a TCP port or a pty, so that any serial client (this tool,
//! pyserial, picocom, socat) talks to the firmware's protocol running against the simulated
//! gyro.
//!
//! One loop, like a board on a UART: bytes from the client go to [`SimDevice::receive`] (each
//! completed line is answered at once), simulated time follows the wall clock times `speed`
//! (in steps of at most [`MAX_STEP_S`], so the link stays responsive), and the device's output
//! goes to the client. The board keeps running with nobody attached, and what it sends then is
//! lost, as on a UART with nothing connected.
//!
//! - TCP: one client at a time; a new connection takes over from the previous one, and starts
//!   a session of its own: locked, no stream, an empty line buffer, none of the previous
//!   client's output ([`SimDevice::new_session`]). Nobody inherits another client's unlock.
//! - pty: the server owns the master side and prints the slave's path; the slave is in raw mode
//!   (no echo, no line editing, no CR/LF translation, 8-bit clean for the stream). A client
//!   opens the path as a serial port (any baud rate). Every open of the path starts a session
//!   of its own, as a TCP connection does: the server watches the path with inotify
//!   (`IN_OPEN`, `IN_CLOSE`), so a client that reopens the pty between two polls is still seen,
//!   and its session starts before any byte read in that poll. One buffer holds the bytes of
//!   both clients, so a line the previous client left unfinished, unread when it closed, would
//!   join the new client's first line; that line then runs in the new, locked session (with
//!   the host tool's CRC it is refused as corrupted). While no one has the slave open, reading
//!   the master fails with `EIO`: that is "nobody attached".
//!
//! If the simulation cannot keep up with `speed`, it runs as fast as it can (a warning says
//! so once) rather than catching up in a burst.

use hal_sim::device::SimDevice;
use std::fs::File;
use std::io::{self, Read, Write};
use std::net::{TcpListener, TcpStream};
use std::os::fd::{AsRawFd, FromRawFd, OwnedFd};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// Largest simulated step between two I/O polls, s.
pub const MAX_STEP_S: f64 = 0.02;
/// Lag behind the scaled wall clock after which the pacing restarts from now, s.
const MAX_LAG_S: f64 = 1.0;
/// Output kept for a slow client before the oldest bytes are dropped (a UART overrun).
const MAX_BACKLOG: usize = 1 << 20;
/// Idle sleep of the loop.
const TICK: Duration = Duration::from_millis(1);

/// How the served board runs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ServeOptions {
    /// Simulated seconds per wall-clock second.
    pub speed: f64,
    /// Stop after this long (wall clock); `None` runs until `stop` is set.
    pub max_duration: Option<Duration>,
}

/// The client side of the served board.
pub trait Endpoint {
    /// Client bytes, without blocking: `Some(n)` bytes arrived, `None` nothing now.
    fn read(&mut self, buf: &mut [u8]) -> io::Result<Option<usize>>;
    /// Writes without blocking; returns the bytes taken (0 when full or nobody is attached).
    fn write(&mut self, bytes: &[u8]) -> io::Result<usize>;
    /// Whether a client is attached (as far as the last read told).
    fn attached(&self) -> bool;
    /// Whether a new client attached since the last call (true once per client).
    fn take_new_client(&mut self) -> bool;
}

/// Keeps the simulation at `speed` times the wall clock.
struct Pacer {
    speed: f64,
    wall0: Instant,
    sim0: f64,
    warned: bool,
}

impl Pacer {
    fn new(device: &SimDevice, speed: f64) -> Self {
        Self {
            speed,
            wall0: Instant::now(),
            sim0: device.time_s(),
            warned: false,
        }
    }

    /// Runs the device one step towards the scaled wall clock; returns whether it ran.
    fn advance(&mut self, device: &mut SimDevice) -> bool {
        let target = self.sim0 + self.wall0.elapsed().as_secs_f64() * self.speed;
        let behind = target - device.time_s();
        if behind > MAX_LAG_S {
            if !self.warned {
                eprintln!(
                    "rlg-cal: the simulation runs slower than --speed {}",
                    self.speed
                );
                self.warned = true;
            }
            (self.wall0, self.sim0) = (Instant::now(), device.time_s());
        }
        if behind > 0.0 {
            device.run_for(behind.min(MAX_STEP_S));
            return true;
        }
        false
    }
}

/// Serves `device` on `endpoint` until `stop` is set or the time is up; returns the device.
pub fn serve(
    mut device: SimDevice,
    endpoint: &mut dyn Endpoint,
    options: &ServeOptions,
    stop: &AtomicBool,
) -> io::Result<SimDevice> {
    let started = Instant::now();
    let mut pacer = Pacer::new(&device, options.speed);
    let mut buf = vec![0u8; 4096];
    let mut outbox: Vec<u8> = Vec::new();
    while !stop.load(Ordering::Relaxed)
        && options.max_duration.is_none_or(|d| started.elapsed() < d)
    {
        let mut busy = false;
        let read = endpoint.read(&mut buf)?;
        if endpoint.take_new_client() {
            device.new_session();
            outbox.clear();
        }
        if let Some(n) = read {
            device.receive(&buf[..n]);
            busy = true;
        }
        busy |= pacer.advance(&mut device);
        let output = device.take_output();
        if endpoint.attached() {
            outbox.extend_from_slice(&output);
            if outbox.len() > MAX_BACKLOG {
                outbox.drain(..outbox.len() - MAX_BACKLOG);
            }
            let sent = endpoint.write(&outbox)?;
            outbox.drain(..sent);
        } else {
            outbox.clear();
        }
        if !busy {
            std::thread::sleep(TICK);
        }
    }
    Ok(device)
}

/// A TCP port: one client at a time, the newest connection wins.
pub struct TcpEndpoint {
    listener: TcpListener,
    client: Option<TcpStream>,
    new_client: bool,
}

impl TcpEndpoint {
    /// Serves on `listener` (made non-blocking); no client yet.
    pub fn new(listener: TcpListener) -> io::Result<Self> {
        listener.set_nonblocking(true)?;
        Ok(Self {
            listener,
            client: None,
            new_client: false,
        })
    }

    fn accept(&mut self) -> io::Result<()> {
        match self.listener.accept() {
            Ok((stream, peer)) => {
                stream.set_nonblocking(true)?;
                stream.set_nodelay(true)?;
                if self.client.is_some() {
                    eprintln!("rlg-cal: {peer} takes over from the previous client");
                } else {
                    eprintln!("rlg-cal: {peer} connected");
                }
                self.client = Some(stream);
                self.new_client = true;
                Ok(())
            }
            Err(e) if e.kind() == io::ErrorKind::WouldBlock => Ok(()),
            Err(e) => Err(e),
        }
    }

    fn drop_client(&mut self, why: &str) {
        if self.client.take().is_some() {
            eprintln!("rlg-cal: client {why}");
        }
    }
}

impl Endpoint for TcpEndpoint {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<Option<usize>> {
        self.accept()?;
        let Some(client) = self.client.as_mut() else {
            return Ok(None);
        };
        match client.read(buf) {
            Ok(0) => {
                self.drop_client("disconnected");
                Ok(None)
            }
            Ok(n) => Ok(Some(n)),
            Err(e) if e.kind() == io::ErrorKind::WouldBlock => Ok(None),
            Err(e) => {
                self.drop_client(&format!("dropped: {e}"));
                Ok(None)
            }
        }
    }

    fn write(&mut self, bytes: &[u8]) -> io::Result<usize> {
        let Some(client) = self.client.as_mut() else {
            return Ok(0);
        };
        match client.write(bytes) {
            Ok(n) => Ok(n),
            Err(e) if e.kind() == io::ErrorKind::WouldBlock => Ok(0),
            Err(e) => {
                self.drop_client(&format!("dropped: {e}"));
                Ok(0)
            }
        }
    }

    fn attached(&self) -> bool {
        self.client.is_some()
    }

    fn take_new_client(&mut self) -> bool {
        std::mem::take(&mut self.new_client)
    }
}

/// A pseudo-terminal: the server holds the master, a client opens [`PtyEndpoint::path`].
pub struct PtyEndpoint {
    master: File,
    path: PathBuf,
    attached: bool,
    new_client: bool,
    /// The inotify instance watching the slave's path for opens and closes.
    watch: OwnedFd,
    /// Descriptors of the slave open now, as the watch counted them.
    openers: u64,
}

/// Opens and closes of the slave's path seen since the last look.
#[derive(Clone, Copy, Default)]
struct PathEvents {
    opened: u64,
    closed: u64,
}

fn os_result(ret: libc::c_int) -> io::Result<libc::c_int> {
    if ret < 0 {
        Err(io::Error::last_os_error())
    } else {
        Ok(ret)
    }
}

impl PtyEndpoint {
    /// Opens a pty pair, puts the slave in raw mode and closes the server's slave handle.
    pub fn open() -> io::Result<Self> {
        let (mut master, mut slave): (libc::c_int, libc::c_int) = (-1, -1);
        // SAFETY: openpty writes two descriptors; name, termios and winsize may be null.
        os_result(unsafe {
            libc::openpty(
                &mut master,
                &mut slave,
                std::ptr::null_mut(),
                std::ptr::null(),
                std::ptr::null(),
            )
        })?;
        // SAFETY: both descriptors were just opened and are owned here alone.
        let (master, slave) =
            unsafe { (OwnedFd::from_raw_fd(master), OwnedFd::from_raw_fd(slave)) };
        make_raw(&slave)?;
        let path = slave_path(&master)?;
        // SAFETY: fcntl on a descriptor we own.
        unsafe {
            let flags = os_result(libc::fcntl(master.as_raw_fd(), libc::F_GETFL))?;
            os_result(libc::fcntl(
                master.as_raw_fd(),
                libc::F_SETFL,
                flags | libc::O_NONBLOCK,
            ))?;
        }
        drop(slave);
        let watch = watch_opens(&path)?;
        Ok(Self {
            master: File::from(master),
            path,
            attached: false,
            new_client: false,
            watch,
            openers: 0,
        })
    }

    /// The opens and closes of the slave's path since the last call.
    fn path_events(&mut self) -> io::Result<PathEvents> {
        let mut events = PathEvents::default();
        let mut buf = [0u8; 1024];
        loop {
            // SAFETY: the buffer and its length are passed together; the descriptor is ours.
            let n =
                unsafe { libc::read(self.watch.as_raw_fd(), buf.as_mut_ptr().cast(), buf.len()) };
            if n < 0 {
                let e = io::Error::last_os_error();
                return match e.kind() {
                    io::ErrorKind::WouldBlock => Ok(events),
                    _ => Err(e),
                };
            }
            let n = usize::try_from(n).unwrap_or(0);
            if n == 0 {
                return Ok(events);
            }
            let header = std::mem::size_of::<libc::inotify_event>();
            let mut at = 0;
            while at + header <= n {
                // SAFETY: a whole event header lies at `at` (the kernel writes whole events);
                // read unaligned from the byte buffer.
                let event: libc::inotify_event =
                    unsafe { std::ptr::read_unaligned(buf.as_ptr().add(at).cast()) };
                events.opened += u64::from(event.mask & libc::IN_OPEN != 0);
                events.closed += u64::from(event.mask & libc::IN_CLOSE != 0);
                at += header + event.len as usize;
            }
        }
    }

    /// The slave's path, for the client.
    pub fn path(&self) -> &std::path::Path {
        &self.path
    }
}

/// Raw mode: 8-bit clean, no echo, no line editing, no CR/LF translation.
fn make_raw(fd: &OwnedFd) -> io::Result<()> {
    // SAFETY: termios is plain data, filled by tcgetattr before use.
    unsafe {
        let mut t: libc::termios = std::mem::zeroed();
        os_result(libc::tcgetattr(fd.as_raw_fd(), &mut t))?;
        libc::cfmakeraw(&mut t);
        os_result(libc::tcsetattr(fd.as_raw_fd(), libc::TCSANOW, &t))?;
    }
    Ok(())
}

/// An inotify instance (non-blocking) watching `path` for opens and closes.
fn watch_opens(path: &std::path::Path) -> io::Result<OwnedFd> {
    use std::os::unix::ffi::OsStrExt;
    // SAFETY: plain system call; the descriptor is owned below.
    let fd = os_result(unsafe { libc::inotify_init1(libc::IN_NONBLOCK | libc::IN_CLOEXEC) })?;
    // SAFETY: just opened, owned here alone.
    let watch = unsafe { OwnedFd::from_raw_fd(fd) };
    let name = std::ffi::CString::new(path.as_os_str().as_bytes())
        .map_err(|_| io::Error::new(io::ErrorKind::InvalidInput, "NUL in the pty path"))?;
    // SAFETY: a valid descriptor and a NUL-terminated path.
    os_result(unsafe {
        libc::inotify_add_watch(
            watch.as_raw_fd(),
            name.as_ptr(),
            libc::IN_OPEN | libc::IN_CLOSE,
        )
    })?;
    Ok(watch)
}

fn slave_path(master: &OwnedFd) -> io::Result<PathBuf> {
    let mut name = [0 as libc::c_char; 128];
    // SAFETY: the buffer and its length are passed together.
    let ret = unsafe { libc::ptsname_r(master.as_raw_fd(), name.as_mut_ptr(), name.len()) };
    if ret != 0 {
        return Err(io::Error::from_raw_os_error(ret));
    }
    // SAFETY: ptsname_r wrote a NUL-terminated string into the buffer.
    let name = unsafe { std::ffi::CStr::from_ptr(name.as_ptr()) };
    Ok(PathBuf::from(name.to_string_lossy().into_owned()))
}

impl Endpoint for PtyEndpoint {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<Option<usize>> {
        let events = self.path_events()?;
        self.openers = (self.openers + events.opened).saturating_sub(events.closed);
        // Every open is a new client, however soon after the previous one closed.
        self.new_client |= events.opened > 0;
        let read = match self.master.read(buf) {
            Ok(0) => None,
            Ok(n) => Some(n),
            Err(e) if e.kind() == io::ErrorKind::WouldBlock => None,
            Err(e) if e.raw_os_error() == Some(libc::EIO) => {
                self.attached = false;
                self.openers = 0;
                return Ok(None);
            }
            Err(e) => return Err(e),
        };
        self.attached = self.openers > 0 || read.is_some();
        Ok(read)
    }

    fn write(&mut self, bytes: &[u8]) -> io::Result<usize> {
        if bytes.is_empty() {
            return Ok(0);
        }
        match self.master.write(bytes) {
            Ok(n) => Ok(n),
            Err(e) if e.kind() == io::ErrorKind::WouldBlock => Ok(0),
            Err(e) if e.raw_os_error() == Some(libc::EIO) => {
                self.attached = false;
                Ok(0)
            }
            Err(e) => Err(e),
        }
    }

    fn attached(&self) -> bool {
        self.attached
    }

    /// A client that opened the slave since the last call.
    fn take_new_client(&mut self) -> bool {
        std::mem::take(&mut self.new_client)
    }
}
