#!/usr/bin/env bash
# rlg-cal against the firmware image in QEMU: the calibration protocol over the emulated USART1
# of the STM32F405 (machine netduinoplus2), which QEMU serves on a loopback TCP port.
#
#   host-tool/qemu-smoke.sh RLG_CAL ELF
#
# RLG_CAL: the rlg-cal binary; ELF: firmware's `serial_protocol` example built with
#   cargo build -p firmware --target thumbv7em-none-eabihf --release --features qemu --example serial_protocol
# Every exchange goes through rlg-cal (CRC suffixes, exit codes), one process per command, each
# a new TCP connection to the same running board. QEMU does not model the readout's timers and
# ADC (no turnarounds), so calibration and streaming are not exercised here; the simulated board
# covers them (host-tool/tests). Bounded: QEMU is killed after 60 s at the latest.
# Closing line: `qemu-rlg-cal: N passed, M failed`; exit status 0 when M == 0, else 1.
set -uo pipefail
unset RLG_KEY   # each check that needs the key sets it
rlg_cal=$1
elf=$2
port=$(python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
timeout 60 qemu-system-arm -machine netduinoplus2 -display none \
    -semihosting-config enable=on,target=native -kernel "$elf" \
    -serial "tcp:127.0.0.1:$port,server=on,wait=off" >/dev/null 2>&1 &
qemu=$!
trap 'kill "$qemu" 2>/dev/null; wait "$qemu" 2>/dev/null' EXIT

passed=0
failed=0
# check NAME EXIT_STATUS STDOUT_SUBSTRING RLG_CAL_ARGS...   (a key comes from RLG_KEY, set
# for one check as `RLG_KEY=... check ...`: no key on a command line)
check() {
    local name=$1 want_status=$2 want_out=$3
    shift 3
    local out status=0
    out=$("$rlg_cal" --tcp "127.0.0.1:$port" "$@" 2>&1) || status=$?
    if [ "$status" -eq "$want_status" ] && [[ "$out" == *"$want_out"* ]]; then
        passed=$((passed + 1))
        echo "ok    $name"
    else
        failed=$((failed + 1))
        echo "FAIL  $name: exit $status (want $want_status), output: $out"
    fi
}

# The board is up once it answers (bytes sent before its USART is enabled are lost).
for _ in $(seq 50); do
    "$rlg_cal" --tcp "127.0.0.1:$port" --timeout-ms 500 id >/dev/null 2>&1 && break
    sleep 0.2
done

# The emulated board boots unprovisioned (blank OTP model): a fresh key per run, provisioned first.
key=$(python3 -c 'import secrets; print(secrets.token_hex(16))')
check "id"                          0 "board=netduinoplus2" id
check "unprovisioned status"        0 "key=unprovisioned" status
other=11111111111111111111111111111111
RLG_KEY=$key check "unprovisioned unlock ERR 16" 1 "ERR 16 no key provisioned" unlock
RLG_KEY=$key check "key provision"          0 "key=provisioned" key-provision
RLG_KEY=$other check "second provision ERR 11" 1 "ERR 11" key-provision
check "status"                              0 "coeffs=defaults:erased" status
check "locked set is ERR 9"                 1 "ERR 9 locked" set a 1
RLG_KEY=12341234123412341234123412341234 check "wrong key is ERR 15" 1 "ERR 15 wrong key" unlock
RLG_KEY=$key check "set with the key"       0 "a=344.12344" set a 344.123456
check "get applied value"                   0 "a=344.12344" get a
RLG_KEY=$key check "comp on"                0 "comp=on" comp on
RLG_KEY=$key check "store"                  0 "result=stored" store
RLG_KEY=$key check "defaults"               0 "comp=off" defaults
RLG_KEY=$key check "reload"                 0 "coeffs=flash:1" reload
check "reloaded value"                      0 "a=344.12344" get a
RLG_KEY=$key check "NaN is ERR 4"           1 "ERR 4" set b NaN
check "cal result without a run"    1 "ERR 11" send cal result
check "help"                        0 "commands=id status" send help
check "lock"                        0 "result=locked" lock

echo "qemu-rlg-cal: $passed passed, $failed failed"
[ "$failed" -eq 0 ]
