#!/usr/bin/env bash
# Fuzzes the firmware and the host tool with libFuzzer: each target (default: all five) for
# SECONDS (default 60). The targets and what each checks: fuzz/src/lib.rs.
#
#   fuzz/run.sh [SECONDS] [TARGET...]      TARGET: protocol service device decoders host
#
# cargo fuzz needs nightly-only flags (-Zsanitizer=address); RUSTC_BOOTSTRAP=1 lets the stable
# toolchain accept them. Installs cargo-fuzz (pinned) when it is missing: about 1.5 min from a
# clean cargo cache on 2 cores. The targets are built once, together (the instrumented build
# of the firmware, hal-sim and rlg-cal: a few minutes the first time). Each starts from its
# seeds in seeds/<target>/ (the line-driven ones with the dictionary protocol.dict); its corpus
# grows in corpus/<target>/ (ignored by git). Exit status 0 when no input broke a promise;
# otherwise libFuzzer prints the panic, saves the input under artifacts/<target>/ and the
# status is non-zero. Reproduce a crash with
#   RUSTC_BOOTSTRAP=1 cargo fuzz run <target> artifacts/<target>/<file>
set -euo pipefail
seconds="${1:-60}"
shift || true
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(protocol service device decoders host)
cd "$(dirname "$0")"
[ -d "${HOME:-/root}/.cargo/bin" ] && export PATH="${HOME:-/root}/.cargo/bin:$PATH"
CARGO_FUZZ_VERSION=0.13.2
if ! cargo fuzz --version 2>/dev/null | grep -q "$CARGO_FUZZ_VERSION"; then
    echo "installing cargo-fuzz $CARGO_FUZZ_VERSION"
    cargo install cargo-fuzz --version "$CARGO_FUZZ_VERSION" --locked
fi
RUSTC_BOOTSTRAP=1 cargo fuzz build
for target in "${targets[@]}"; do
    case "$target" in
        protocol|service|device) dict=(-dict=protocol.dict) ;;
        decoders|host) dict=() ;;
        *) echo "unknown target: $target" >&2; exit 2 ;;
    esac
    echo "==== fuzz target $target: $seconds s"
    mkdir -p "corpus/$target"
    RUSTC_BOOTSTRAP=1 cargo fuzz run "$target" "corpus/$target" "seeds/$target" -- \
        -max_total_time="$seconds" "${dict[@]}" -print_final_stats=1
done
