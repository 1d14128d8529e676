//! On-target suite: the firmware's core functions on the Cortex-M4F (QEMU's netduinoplus2, or a
//! board under probe-rs), checked against the golden values that `tests/golden.rs` checks on the
//! host, so target == host (bit-identical, or within the tolerance a case states). A parity
//! check, not a correctness check: the golden values come from the code itself (see
//! `tests/golden.rs`); the physics is checked by the host's unit and system tests.
//!
//! Its own tiny harness rather than defmt-test's: every case runs even after one fails, the run
//! closes with `qemu: N passed, M failed` and exits through semihosting with status 0, or 1 if
//! any case failed. A panic inside a case cannot be recovered from (no unwinding): the fatal
//! hook names the case and prints the closing line, then the run ends with status 1 (panic) or
//! 2 (HardFault), so QEMU never hangs (and the runner has a timeout).
//! Run: `cargo fw-test`. Cases live in `vectors/cases.rs`.
#![cfg_attr(target_os = "none", no_std, no_main)]

mod vectors;

#[cfg(target_os = "none")]
mod app {
    use super::vectors::{self, cases::CASES, Check, Failure};
    use core::sync::atomic::{AtomicU32, AtomicUsize, Ordering::Relaxed};
    use firmware::rt::MemoryMap;

    /// Label of the closing line.
    const WHERE: &str = if cfg!(feature = "qemu") {
        "qemu"
    } else {
        "board"
    };

    /// Progress, for the closing line when a case panics or faults (the run cannot go on).
    static PASSED: AtomicU32 = AtomicU32::new(0);
    static FAILED: AtomicU32 = AtomicU32::new(0);
    static RUNNING: AtomicUsize = AtomicUsize::new(0);

    fn close_after_fatal() {
        let (running, passed) = (RUNNING.load(Relaxed), PASSED.load(Relaxed));
        let failed = FAILED.load(Relaxed) + 1;
        defmt::error!(
            "FAIL {=str}: panicked or faulted; {=usize} later cases not run",
            CASES[running].name,
            CASES.len() - running - 1
        );
        defmt::println!(
            "{=str}: {=u32} passed, {=u32} failed",
            WHERE,
            passed,
            failed
        );
    }

    #[cortex_m_rt::entry]
    fn main() -> ! {
        let _ = MemoryMap::linked(); // links the firmware's runtime (vector table, handlers)
        firmware::rt::set_fatal_hook(close_after_fatal);
        defmt::info!("{=usize} cases, golden values from the host", CASES.len());
        let (mut passed, mut failed) = (0u32, 0u32);
        for (i, case) in CASES.iter().enumerate() {
            RUNNING.store(i, Relaxed);
            match vectors::check(case) {
                Ok(o) => {
                    passed += 1;
                    PASSED.store(passed, Relaxed);
                    match case.check {
                        Check::Exact => defmt::info!(
                            "ok   {=str}: {=u32} outputs bit-identical (digest {=u64:#018x})",
                            case.name,
                            o.words,
                            o.digest
                        ),
                        Check::AbsTol(tol) => defmt::info!(
                            "ok   {=str}: {=u32} exact + {=u32} f32 outputs, worst |err| {=f32} (tol {=f32})",
                            case.name,
                            o.words,
                            o.f32_count,
                            o.worst_abs_err,
                            tol
                        ),
                    }
                }
                Err(failure) => {
                    failed += 1;
                    FAILED.store(failed, Relaxed);
                    log_failure(case.name, failure);
                }
            }
        }
        defmt::println!(
            "{=str}: {=u32} passed, {=u32} failed",
            WHERE,
            passed,
            failed
        );
        semihosting::process::exit(if failed == 0 { 0 } else { 1 })
    }

    fn log_failure(name: &str, failure: Failure) {
        match failure {
            Failure::NoGolden => defmt::error!(
                "FAIL {=str}: no golden entry: UPDATE_GOLDEN=1 cargo test -p firmware --test golden",
                name
            ),
            Failure::Digest { words, want_words, digest, want_digest } => defmt::error!(
                "FAIL {=str}: {=u32} outputs, digest {=u64:#018x}; golden: {=u32}, {=u64:#018x}",
                name,
                words,
                digest,
                want_words,
                want_digest
            ),
            Failure::F32Count { got, want } => {
                defmt::error!("FAIL {=str}: {=u32} f32 outputs, golden has {=u32}", name, got, want)
            }
            Failure::F32OutOfTolerance(bad) => defmt::error!(
                "FAIL {=str}: f32 output #{=u32} = {=f32} ({=u32:#010x}), golden {=f32} ({=u32:#010x})",
                name,
                bad.index,
                bad.got,
                bad.got.to_bits(),
                bad.want,
                bad.want.to_bits()
            ),
        }
    }
}

#[cfg(not(target_os = "none"))]
fn main() {
    println!("on_target: runs on the MCU (`cargo fw-test`); its host twin is tests/golden.rs");
}
