#!/usr/bin/env bash
# Fuzzes the serial protocol (line assembler -> checksum -> parser -> executor, against an
# in-memory device; the checks are in src/lib.rs) for SECONDS (default 60).
#
#   fuzz/run.sh [SECONDS]
#
# cargo fuzz needs nightly-only flags (-Zsanitizer=address); RUSTC_BOOTSTRAP=1 lets the stable
# toolchain accept them. Installs cargo-fuzz (pinned) when it is missing: about 1.5 min from a
# clean cargo cache on 2 cores, plus about 1.5 min for the first instrumented build. Starts from
# the seeds in seeds/ with the dictionary protocol.dict; the corpus grows in corpus/ (ignored
# by git). Exit status 0 when no input broke a promise; otherwise libFuzzer prints the panic,
# saves the input under artifacts/protocol/ and the status is non-zero. Reproduce a crash with
#   RUSTC_BOOTSTRAP=1 cargo fuzz run protocol artifacts/protocol/<file>
set -euo pipefail
seconds="${1:-60}"
cd "$(dirname "$0")"
[ -d "${HOME:-/root}/.cargo/bin" ] && export PATH="${HOME:-/root}/.cargo/bin:$PATH"
CARGO_FUZZ_VERSION=0.13.2
if ! cargo fuzz --version 2>/dev/null | grep -q "$CARGO_FUZZ_VERSION"; then
    echo "installing cargo-fuzz $CARGO_FUZZ_VERSION"
    cargo install cargo-fuzz --version "$CARGO_FUZZ_VERSION" --locked
fi
mkdir -p corpus/protocol
RUSTC_BOOTSTRAP=1 cargo fuzz run protocol corpus/protocol seeds -- \
    -max_total_time="$seconds" -dict=protocol.dict -print_final_stats=1
