//! `rlg-cal console` at a real terminal: driven through a pty by Python's `pty` module (python3
//! is on every CI machine; no terminal crate needed in the tests). The board is served on
//! loopback TCP in this process behind an endpoint that records every byte the console sends,
//! so the test sees the wire: the CRC suffix on each line.

use firmware::protocol::parse::crc16;
use hal_sim::flash::CalibrationFlash;
use rlg_cal::serve::{serve, Endpoint, ServeOptions, TcpEndpoint};
use rlg_cal::sim::{self, SimInput};
use std::io;
use std::net::TcpListener;
use std::process::Command;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

/// The served board's endpoint, keeping a copy of what the client sent.
struct Recording {
    inner: TcpEndpoint,
    received: Arc<Mutex<Vec<u8>>>,
}

impl Endpoint for Recording {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<Option<usize>> {
        let n = self.inner.read(buf)?;
        if let Some(n) = n {
            self.received.lock().unwrap().extend_from_slice(&buf[..n]);
        }
        Ok(n)
    }
    fn write(&mut self, bytes: &[u8]) -> io::Result<usize> {
        self.inner.write(bytes)
    }
    fn attached(&self) -> bool {
        self.inner.attached()
    }
    fn take_new_client(&mut self) -> bool {
        self.inner.take_new_client()
    }
}

/// The keystrokes and what each must bring, for Python's pty: Tab completes `ge` to `get `
/// and `co` to `coeffs `; Up twice recalls `get coeffs` from the history; `set a 1` without
/// an unlock is answered with its error code in words.
const DRIVER: &str = r#"
import os, pty, select, sys, time
pid, fd = pty.fork()
if pid == 0:
    os.execv(sys.argv[1], sys.argv[1:])
out = b""
def expect(what, timeout=20.0):
    global out
    end = time.time() + timeout
    while what not in out:
        left = end - time.time()
        if left <= 0:
            sys.stdout.write("TIMEOUT waiting for %r\n--- output ---\n%s" % (what, out.decode("utf-8", "replace")))
            sys.exit(3)
        r, _, _ = select.select([fd], [], [], left)
        if r:
            try:
                out += os.read(fd, 4096)
            except OSError:
                break
    i = out.index(what) + len(what)
    seen, out = out[:i], out[i:]
    return seen
def send(keys):
    os.write(fd, keys)
    time.sleep(0.2)
expect(b"> ")
send(b"ge\t")
send(b"co\t")
send(b"\r")
expect(b"lock_in_deg_h=")
expect(b"> ")
send(b"set a 1\r")
sys.stdout.write(expect(b"> ").decode())
send(b"\x1b[A\x1b[A\r")
expect(b"lock_in_deg_h=")
expect(b"> ")
send(b"\x04")
_, status = os.waitpid(pid, 0)
sys.exit(os.waitstatus_to_exitcode(status))
"#;

#[test]
fn console_edits_completes_recalls_and_adds_the_crc() {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let address = listener.local_addr().unwrap().to_string();
    let received = Arc::new(Mutex::new(Vec::new()));
    let mut endpoint = Recording {
        inner: TcpEndpoint::new(listener).unwrap(),
        received: received.clone(),
    };
    let stop = Arc::new(AtomicBool::new(false));
    let flag = stop.clone();
    let server = std::thread::spawn(move || {
        let device = sim::boot(
            SimInput::Constant {
                rate_deg_per_h: 13.888,
            },
            1,
            CalibrationFlash::default(),
            0,
            None,
        )
        .unwrap();
        let options = ServeOptions {
            speed: 1.0,
            max_duration: Some(Duration::from_secs(60)),
        };
        serve(device, &mut endpoint, &options, &flag).unwrap();
    });
    let out = Command::new("python3")
        .args([
            "-c",
            DRIVER,
            env!("CARGO_BIN_EXE_rlg-cal"),
            "console",
            "--tcp",
            &address,
        ])
        .env_remove("RLG_KEY")
        .output()
        .expect("python3");
    stop.store(true, Ordering::Relaxed);
    server.join().unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        stdout.contains("ERR 9 (locked): locked (unlock first)"),
        "the error in words: {stdout}"
    );
    let wire = String::from_utf8_lossy(&received.lock().unwrap()).into_owned();
    let with_crc = |text: &str| format!("{text}*{:04X}\n", crc16(text.as_bytes()));
    // Completed by Tab, then recalled from the history: sent twice, each with its CRC.
    assert_eq!(wire.matches(&with_crc("get coeffs")).count(), 2, "{wire:?}");
    assert!(wire.contains(&with_crc("set a 1")), "{wire:?}");
    assert!(
        wire.lines().all(|l| l.contains('*')),
        "every line has its CRC: {wire:?}"
    );
}
