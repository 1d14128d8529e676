//! The simulated board served on loopback TCP and on a pty, talked to through real sockets and
//! a real terminal device. Each server runs in a thread, bounded in time, and is stopped at the
//! end of its test.

use hal_sim::device::SimDevice;
use hal_sim::flash::CalibrationFlash;
use rlg_cal::client::Client;
use rlg_cal::link;
use rlg_cal::ops;
use rlg_cal::serve::{serve, Endpoint, PtyEndpoint, ServeOptions, TcpEndpoint};
use rlg_cal::sim::{self, SimInput};
use std::io::{Read, Write};
use std::net::TcpListener;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

fn device() -> SimDevice {
    sim::boot(
        SimInput::Constant {
            rate_deg_per_h: 13.888,
        },
        11,
        CalibrationFlash::default(),
        0,
        Some(sim::test_key()),
    )
    .unwrap()
}

/// A server in a thread: 4x real time, at most 20 s.
fn spawn(mut endpoint: impl Endpoint + Send + 'static) -> (Arc<AtomicBool>, JoinHandle<SimDevice>) {
    let stop = Arc::new(AtomicBool::new(false));
    let flag = stop.clone();
    let options = ServeOptions {
        speed: 4.0,
        max_duration: Some(Duration::from_secs(20)),
    };
    let handle =
        std::thread::spawn(move || serve(device(), &mut endpoint, &options, &flag).unwrap());
    (stop, handle)
}

#[test]
fn tcp_server_answers_a_real_socket() {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let address = listener.local_addr().unwrap().to_string();
    let (stop, server) = spawn(TcpEndpoint::new(listener).unwrap());
    let started = Instant::now();

    let mut c = Client::new(link::tcp(&address, Duration::from_secs(2)).unwrap());
    assert!(c.command("id").unwrap().text.contains("serial=4242"));
    ops::unlock(&mut c, &sim::key_hex(&sim::test_key())).unwrap();
    assert_eq!(c.command("set a 300").unwrap().text, "a=300");
    assert_eq!(c.command("get a").unwrap().text, "a=300");
    // Half a second of streaming on the wall clock: frames at 4 x 389 Hz / 4.
    let capture = ops::stream(&mut c, 4, Duration::from_millis(500), &mut |_| {}).unwrap();
    assert!(capture.records.len() > 100, "{}", capture.records.len());
    assert_eq!((capture.lost(), capture.bad_frames), (0, 0));
    drop(c);

    // A second client finds the board as the first left it (a board on a port, not a session).
    let mut c = Client::new(link::tcp(&address, Duration::from_secs(2)).unwrap());
    assert_eq!(c.command("get a").unwrap().text, "a=300");
    let status = c.command("status").unwrap();
    assert_eq!(status.field("signal"), Some("ok"));
    drop(c);

    // Plain text, as a person at a terminal would type it (no CRC).
    let mut raw = std::net::TcpStream::connect(&address).unwrap();
    raw.set_read_timeout(Some(Duration::from_secs(2))).unwrap();
    raw.write_all(b"get a\r\n").unwrap();
    let answer = read_line(&mut raw);
    assert_eq!(answer, "OK a=300\r\n");

    stop.store(true, Ordering::Relaxed);
    let device = server.join().unwrap();
    let wall = started.elapsed().as_secs_f64();
    assert!(device.time_s() > 0.5, "the board ran: {}", device.time_s());
    assert!(
        device.time_s() < 4.0 * wall + 1.0,
        "paced: {} s in {wall} s",
        device.time_s()
    );
}

fn read_line(r: &mut impl Read) -> String {
    let mut line = Vec::new();
    let mut byte = [0u8];
    while !line.ends_with(b"\r\n") {
        r.read_exact(&mut byte).unwrap();
        line.push(byte[0]);
    }
    String::from_utf8(line).unwrap()
}

/// A new TCP connection starts its own session: the previous client's unlock, stream and
/// half-typed line do not carry over (the board's coefficients do).
#[test]
fn each_tcp_connection_starts_locked_without_stream_and_with_an_empty_line() {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let address = listener.local_addr().unwrap().to_string();
    let (stop, server) = spawn(TcpEndpoint::new(listener).unwrap());
    let mut first = std::net::TcpStream::connect(&address).unwrap();
    first
        .set_read_timeout(Some(Duration::from_secs(2)))
        .unwrap();
    let unlock = format!("unlock {}\r\n", sim::key_hex(&sim::test_key()));
    first.write_all(unlock.as_bytes()).unwrap();
    assert!(read_line(&mut first).starts_with("OK unlocked"));
    first.write_all(b"set a 300\r\n").unwrap();
    assert_eq!(
        read_line(&mut first),
        "ERR 18 confirm (send yes) cmd=set a 300\r\n"
    );
    first.write_all(b"yes\r\n").unwrap();
    assert_eq!(read_line(&mut first), "OK a=300\r\n");
    first.write_all(b"stream on 1\r\n").unwrap();
    std::thread::sleep(Duration::from_millis(300));
    first.write_all(b"set a 12").unwrap(); // no end of line: left in the board's buffer
    std::thread::sleep(Duration::from_millis(100));

    let mut second = std::net::TcpStream::connect(&address).unwrap();
    second
        .set_read_timeout(Some(Duration::from_secs(2)))
        .unwrap();
    std::thread::sleep(Duration::from_millis(200));
    // Not "set a 123.5": the first client's fragment is gone. Plain text: no stream is on.
    second.write_all(b"3.5\r\n").unwrap();
    assert_eq!(
        read_line(&mut second),
        "ERR 1 unknown command (try help)\r\n"
    );
    second.write_all(b"set b 1\r\n").unwrap();
    assert!(read_line(&mut second).starts_with("ERR 18 "));
    second.write_all(b"yes\r\n").unwrap();
    assert_eq!(read_line(&mut second), "ERR 9 locked (unlock first)\r\n");
    second.write_all(b"get a\r\n").unwrap();
    assert_eq!(
        read_line(&mut second),
        "OK a=300\r\n",
        "the board's state stays"
    );
    drop(first);
    stop.store(true, Ordering::Relaxed);
    server.join().unwrap();
}

#[test]
fn pty_server_answers_the_slave_device() {
    let endpoint = PtyEndpoint::open().unwrap();
    let path = endpoint.path().to_owned();
    assert!(path.starts_with("/dev/pts/"), "{}", path.display());
    let (stop, server) = spawn(endpoint);

    // The slave opened as a plain file: raw mode, so the answer comes back untouched.
    let mut tty = std::fs::OpenOptions::new()
        .read(true)
        .write(true)
        .open(&path)
        .unwrap();
    tty.write_all(b"id\n").unwrap();
    let answer = read_line(&mut tty);
    assert!(
        answer.starts_with("OK fw=") && answer.contains("serial=4242"),
        "{answer:?}"
    );
    drop(tty);

    // Through the serialport crate, as `rlg-cal --port` opens it, with CRCs.
    let mut c = Client::new(link::serial(path.to_str().unwrap(), 115_200).unwrap());
    std::thread::sleep(Duration::from_millis(300)); // the board's first simulated second
    let status = c.command("status").unwrap().text;
    assert!(status.starts_with("signal=ok"), "{status}");
    assert_eq!(c.command("set a 1").unwrap_err().device_code(), Some(9));
    let capture = ops::stream(&mut c, 8, Duration::from_millis(400), &mut |_| {}).unwrap();
    assert!(capture.records.len() > 30, "{}", capture.records.len());
    assert_eq!((capture.lost(), capture.bad_frames), (0, 0), "8-bit clean");
    drop(c);

    stop.store(true, Ordering::Relaxed);
    server.join().unwrap();
}

/// One pass of the server's loop, as `serve` does it: bytes in (a new client first starts its
/// session), the board run a little, its output out.
fn serve_once(endpoint: &mut PtyEndpoint, dev: &mut SimDevice) {
    let mut buf = [0u8; 4096];
    let read = endpoint.read(&mut buf).unwrap();
    if endpoint.take_new_client() {
        dev.new_session();
    }
    if let Some(n) = read {
        dev.receive(&buf[..n]);
    }
    dev.run_for(0.005);
    let out = dev.take_output();
    if endpoint.attached() {
        endpoint.write(&out).unwrap();
    }
}

/// Reads one answer line from the pty, serving meanwhile.
fn answer(tty: &mut std::fs::File, endpoint: &mut PtyEndpoint, dev: &mut SimDevice) -> String {
    let mut line = Vec::new();
    let mut byte = [0u8];
    let started = Instant::now();
    while !line.ends_with(b"\r\n") {
        assert!(
            started.elapsed() < Duration::from_secs(5),
            "no answer: {line:?}"
        );
        serve_once(endpoint, dev);
        while let Ok(1) = tty.read(&mut byte) {
            line.push(byte[0]);
            if line.ends_with(b"\r\n") {
                break;
            }
        }
    }
    String::from_utf8(line).unwrap()
}

/// A client that opens the pty right after the previous one closed it, before the server's
/// next poll, starts a session of its own: the previous client's unlock does not carry over.
#[test]
fn a_pty_reopened_before_the_next_poll_is_a_new_session() {
    use std::os::unix::fs::OpenOptionsExt;
    let mut endpoint = PtyEndpoint::open().unwrap();
    let path = endpoint.path().to_owned();
    let mut dev = device();
    let open = || {
        std::fs::OpenOptions::new()
            .read(true)
            .write(true)
            .custom_flags(libc::O_NONBLOCK)
            .open(&path)
            .unwrap()
    };
    let mut first = open();
    let unlock = format!("unlock {}\n", sim::key_hex(&sim::test_key()));
    first.write_all(unlock.as_bytes()).unwrap();
    let unlocked = answer(&mut first, &mut endpoint, &mut dev);
    assert!(unlocked.starts_with("OK unlocked"), "{unlocked}");
    drop(first);
    let mut second = open();
    second.write_all(b"status\n").unwrap();
    let status = answer(&mut second, &mut endpoint, &mut dev);
    assert!(status.contains(" locked=yes "), "{status}");
}
