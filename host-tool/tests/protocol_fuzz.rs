//! Seeded, bounded random fuzzing in every `cargo test`: the harnesses of the coverage-guided
//! `cargo fuzz` targets (`fuzz/src/`, included here by path: protocol, service, device,
//! decoders, host) over mutations of each target's seed corpus (`fuzz/seeds/<target>/`) with
//! the dictionary (`fuzz/protocol.dict`). Deterministic: a failure names the target and the
//! iteration, and the same seed reproduces it. CI also runs the coverage-guided targets for a
//! bounded time each (`fuzz/run.sh`).

#[path = "../../fuzz/src/lib.rs"]
mod harness;

use std::path::PathBuf;
use std::time::{Duration, Instant};

fn fuzz_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../fuzz")
}

fn seeds(target: &str) -> Vec<Vec<u8>> {
    let mut files: Vec<_> = std::fs::read_dir(fuzz_dir().join("seeds").join(target))
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    files.sort();
    assert!(files.len() >= 3, "the seed corpus of {target}");
    files.iter().map(|p| std::fs::read(p).unwrap()).collect()
}

/// The dictionary's words (`name="text"` with `\xNN` escapes).
fn dictionary() -> Vec<Vec<u8>> {
    let text = std::fs::read_to_string(fuzz_dir().join("protocol.dict")).unwrap();
    text.lines()
        .filter_map(|l| l.split_once('=').map(|(_, v)| v))
        .filter_map(|v| v.strip_prefix('"')?.strip_suffix('"'))
        .map(|v| {
            let mut out = Vec::new();
            let mut rest = v.as_bytes();
            while let Some((&b, tail)) = rest.split_first() {
                if b == b'\\' && tail.first() == Some(&b'x') && tail.len() >= 3 {
                    let hex = std::str::from_utf8(&tail[1..3]).unwrap();
                    out.push(u8::from_str_radix(hex, 16).unwrap());
                    rest = &tail[3..];
                } else {
                    out.push(b);
                    rest = tail;
                }
            }
            out
        })
        .collect()
}

/// xorshift64*.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

/// A byte biased towards what matters to the protocol.
fn interesting_byte(rng: &mut Rng) -> u8 {
    match rng.below(10) {
        0 => b'\n',
        1 => b'\r',
        2 => *b" *0123456789abcdefABCDEF.-+eE".get(rng.below(29)).unwrap(),
        3 => 1 + rng.below(8) as u8, // the event bytes (harness::events)
        4 => (rng.next() >> 8) as u8,
        _ => b' ' + rng.below(95) as u8,
    }
}

fn mutate(rng: &mut Rng, seeds: &[Vec<u8>], words: &[Vec<u8>]) -> Vec<u8> {
    let mut input = seeds[rng.below(seeds.len())].clone();
    for _ in 0..1 + rng.below(8) {
        let at = rng.below(input.len() + 1);
        match rng.below(6) {
            0 if !input.is_empty() => {
                let i = rng.below(input.len());
                input[i] ^= 1 << rng.below(8);
            }
            1 => input.insert(at, interesting_byte(rng)),
            2 if !input.is_empty() => {
                let end = (at + rng.below(8)).min(input.len());
                input.drain(at.min(end)..end);
            }
            3 => {
                let w = &words[rng.below(words.len())];
                input.splice(at..at, w.iter().copied());
            }
            4 => {
                let other = &seeds[rng.below(seeds.len())];
                let from = rng.below(other.len());
                let end = (from + rng.below(64)).min(other.len());
                input.splice(at..at, other[from..end].iter().copied());
            }
            _ => input.insert(at, b'\n'),
        }
    }
    input.truncate(4096);
    input
}

/// Every target's seeds, then seeded mutations of them, bounded in count and in time
/// (whichever ends first); `min_runs` asserts the bound left room for real work.
fn fuzz(target: &str, check: fn(&[u8]), seconds: f64, min_runs: usize) {
    let (seeds, words) = (seeds(target), dictionary());
    for seed in &seeds {
        check(seed);
    }
    assert!(words.len() > 20, "the dictionary");
    let mut rng = Rng(0x5EED_2026_C0FF_EE42);
    let start = Instant::now();
    let mut runs = 0;
    while runs < 20_000 && start.elapsed() < Duration::from_secs_f64(seconds) {
        let input = mutate(&mut rng, &seeds, &words);
        let outcome = std::panic::catch_unwind(|| check(&input));
        assert!(
            outcome.is_ok(),
            "{target}: iteration {runs} broke a promise; input: {:?}",
            String::from_utf8_lossy(&input)
        );
        runs += 1;
    }
    assert!(
        runs >= min_runs,
        "{target}: only {runs} inputs in the time bound"
    );
}

#[test]
fn protocol_keeps_the_promises() {
    fuzz("protocol", harness::protocol::check, 5.0, 200);
}

#[test]
fn service_keeps_the_promises() {
    fuzz("service", harness::service::check, 3.0, 100);
}

#[test]
fn device_keeps_the_promises() {
    fuzz("device", harness::device::check, 6.0, 10);
}

#[test]
fn decoders_keep_the_promises() {
    fuzz("decoders", harness::decoders::check, 2.0, 200);
}

#[test]
fn host_keeps_the_promises() {
    fuzz("host", harness::host::check, 2.0, 200);
}
