//! Seeded, bounded random fuzzing of the firmware's protocol (line assembler, checksum, parser,
//! executor) in every `cargo test`: the harness of the coverage-guided `cargo fuzz` target
//! (`fuzz/src/lib.rs`, included here by path) over mutations of its seed corpus
//! (`fuzz/seeds/`) with its dictionary (`fuzz/protocol.dict`). Deterministic: a failure names
//! the iteration, and the same seed reproduces it. CI also runs the coverage-guided target for
//! a bounded time (`fuzz/run.sh`).

#[path = "../../fuzz/src/lib.rs"]
mod harness;

use std::path::PathBuf;
use std::time::{Duration, Instant};

fn fuzz_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../fuzz")
}

fn seeds() -> Vec<Vec<u8>> {
    let mut files: Vec<_> = std::fs::read_dir(fuzz_dir().join("seeds"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    files.sort();
    assert!(files.len() >= 5, "the seed corpus");
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
        3 => [harness::TICK, harness::CYCLES, harness::FAIL_STORE][rng.below(3)],
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

#[test]
fn the_seed_corpus_keeps_the_promises() {
    for seed in seeds() {
        harness::check(&seed);
    }
}

/// Seeded mutations, bounded in count and in time (whichever ends first).
#[test]
fn seeded_mutations_keep_the_promises() {
    let (seeds, words) = (seeds(), dictionary());
    assert!(words.len() > 20, "the dictionary");
    let mut rng = Rng(0x5EED_2026_C0FF_EE42);
    let start = Instant::now();
    let mut runs = 0;
    while runs < 20_000 && start.elapsed() < Duration::from_secs(6) {
        let input = mutate(&mut rng, &seeds, &words);
        let outcome = std::panic::catch_unwind(|| harness::check(&input));
        assert!(
            outcome.is_ok(),
            "iteration {runs} broke a promise; input: {:?}",
            String::from_utf8_lossy(&input)
        );
        runs += 1;
    }
    assert!(runs >= 200, "only {runs} inputs in the time bound");
}
