//! The serial link: ordering, bounded queues, non-blocking behaviour, seeded line noise.
//!
//! Tolerances: the models are deterministic and discrete, so counts, codes, bytes and ticks are
//! compared exactly, marked "(exact)"; statistical and floating checks state bound and reason.

use embedded_io::{Error, ErrorKind, Read, ReadReady, Write, WriteReady};
use hal_sim::serial::{serial_link, LineNoise, SerialConfig, SerialEnd, SerialError, Side};

fn read_everything(end: &mut SerialEnd) -> Vec<u8> {
    let mut out = Vec::new();
    let mut buf = [0; 7];
    while let Ok(n) = end.read(&mut buf) {
        if n == 0 {
            break;
        }
        out.extend_from_slice(&buf[..n]);
    }
    out
}

/// Bytes arrive in order, each direction independently (exact).
#[test]
fn ordering_both_directions() {
    let (mut host, mut device) = serial_link(SerialConfig::default(), 0);
    assert_eq!(host.side(), Side::Host);
    assert_eq!(device.side(), Side::Device);
    host.write_all(b"get p1\n").unwrap();
    device.write_all(b"OK 1.25\n").unwrap();
    host.write_all(b"store\n").unwrap();
    assert_eq!(read_everything(&mut device), b"get p1\nstore\n");
    assert_eq!(read_everything(&mut host), b"OK 1.25\n");
}

/// A full queue accepts what fits, then refuses with WouldBlock; never Ok(0) for a non-empty
/// buffer (exact).
#[test]
fn bounded_queue() {
    let config = SerialConfig {
        capacity_bytes: 8,
        ..SerialConfig::default()
    };
    let (mut host, mut device) = serial_link(config, 0);
    assert!(host.write_ready().unwrap());
    assert_eq!(host.write(b"0123456789"), Ok(8));
    assert!(!host.write_ready().unwrap());
    assert_eq!(host.write(b"89"), Err(SerialError::WouldBlock));
    assert_eq!(host.write(b""), Ok(0));
    assert_eq!(device.available(), 8);
    let mut buf = [0; 3];
    assert_eq!(device.read(&mut buf), Ok(3));
    assert_eq!(&buf, b"012");
    assert_eq!(host.room(), 3);
    assert_eq!(host.write(b"89abc"), Ok(3));
    assert_eq!(read_everything(&mut device), b"3456789a");
}

/// An empty queue: read_ready false and read WouldBlock (kind TimedOut); after the other end is
/// dropped: read_ready true and Ok(0), end of file. Writes to a dropped end vanish. (exact)
#[test]
fn non_blocking_read_and_eof() {
    let (mut host, mut device) = serial_link(SerialConfig::default(), 0);
    let mut buf = [0; 4];
    assert!(!device.read_ready().unwrap());
    let err = device.read(&mut buf).unwrap_err();
    assert_eq!(err, SerialError::WouldBlock);
    assert_eq!(err.kind(), ErrorKind::TimedOut);
    assert_eq!(device.read(&mut []), Ok(0));
    host.write_all(b"hi").unwrap();
    drop(host);
    assert!(device.read_ready().unwrap());
    assert_eq!(device.read(&mut buf), Ok(2));
    assert_eq!(device.read(&mut buf), Ok(0));
    for _ in 0..2000 {
        assert_eq!(device.write(b"lost"), Ok(4));
    }
}

/// Same seed, same damage, bit for bit; another seed differs; the damage of one direction does
/// not depend on traffic in the other.
#[test]
fn noise_is_deterministic() {
    let noisy = LineNoise {
        drop_probability: 0.05,
        corrupt_probability: 0.05,
    };
    let config = SerialConfig {
        capacity_bytes: 1 << 16,
        host_to_device: noisy,
        device_to_host: noisy,
    };
    let message: Vec<u8> = (0..10_000u32).map(|i| (i * 7 % 251) as u8).collect();
    let run = |seed, with_reverse_traffic: bool| {
        let (mut host, mut device) = serial_link(config, seed);
        for chunk in message.chunks(100) {
            host.write_all(chunk).unwrap();
            if with_reverse_traffic {
                device.write_all(b"OK\n").unwrap();
            }
        }
        read_everything(&mut device)
    };
    let a = run(1, false);
    assert_eq!(a, run(1, false));
    assert_eq!(a, run(1, true));
    assert_ne!(a, run(2, false));
}

/// Drop rate: 10 000 bytes at p = 0.1: mean 1000 lost, sigma 30; bounds at 5 sigma (+-150).
/// Corruption alone keeps the length and flips exactly one bit per damaged byte; at p = 0.1 the
/// damaged count has the same statistics.
#[test]
fn noise_rates_and_single_bit_flips() {
    let message: Vec<u8> = (0..10_000u32).map(|i| (i % 256) as u8).collect();
    let run = |noise: LineNoise| {
        let config = SerialConfig {
            capacity_bytes: 1 << 16,
            host_to_device: noise,
            device_to_host: LineNoise::NONE,
        };
        let (mut host, mut device) = serial_link(config, 77);
        host.write_all(&message).unwrap();
        read_everything(&mut device)
    };
    let dropped = run(LineNoise {
        drop_probability: 0.1,
        corrupt_probability: 0.0,
    });
    let lost = message.len() - dropped.len();
    assert!((850..=1150).contains(&lost), "{lost}");
    // What arrives is a subsequence of what was sent.
    let mut sent = message.iter();
    assert!(dropped.iter().all(|b| sent.any(|s| s == b)));

    let corrupted = run(LineNoise {
        drop_probability: 0.0,
        corrupt_probability: 0.1,
    });
    assert_eq!(corrupted.len(), message.len());
    let damaged: Vec<u32> = message
        .iter()
        .zip(&corrupted)
        .map(|(a, b)| (a ^ b).count_ones())
        .filter(|&bits| bits > 0)
        .collect();
    assert!(damaged.iter().all(|&bits| bits == 1));
    assert!((850..=1150).contains(&damaged.len()), "{}", damaged.len());
}

/// The ends are Send: the host side can run in its own thread. (exact)
#[test]
fn ends_work_across_threads() {
    let (mut host, mut device) = serial_link(SerialConfig::default(), 0);
    let worker = std::thread::spawn(move || {
        let mut line = Vec::new();
        let mut byte = [0; 1];
        while !line.ends_with(b"\n") {
            match device.read(&mut byte) {
                Ok(1) => line.push(byte[0]),
                Ok(_) => break,
                Err(SerialError::WouldBlock) => std::thread::yield_now(),
            }
        }
        device.write_all(b"OK\n").unwrap();
        line
    });
    host.write_all(b"ping\n").unwrap();
    assert_eq!(worker.join().unwrap(), b"ping\n");
    assert_eq!(read_everything(&mut host), b"OK\n");
}
