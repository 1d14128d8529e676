#!/usr/bin/env python3
"""Host side of the QEMU serial test: the calibration protocol over the emulated USART1.

Usage: python3 .ci/qemu_serial.py target/thumbv7em-none-eabihf/release/examples/serial_protocol
       python3 .ci/qemu_serial.py --board target/thumbv7em-none-eabihf/release/examples/board
       python3 .ci/qemu_serial.py --help      (this text; starts nothing)

Starts qemu-system-arm (netduinoplus2) with USART1 on a TCP socket (server, wait=on: the CPU
starts only once this script is connected, so nothing is lost), waits for the firmware's banner,
checks a fixed list of exchanges (one answer line per command), sends `quit` (an example-only
hook: the firmware exits through semihosting with status 0) and checks QEMU's exit status.
QEMU's stdout is the defmt stream: kept in a temporary file and decoded with defmt-print (if
installed) when something fails. Every wait has a timeout; the whole run is bounded to 90 s.
With `--board`, the ELF is the complete board image (`board::app::run`: clocks, watchdog, ADC,
timers, DMA, the internal-flash driver): a smoke test that it comes up in QEMU and serves the
protocol; `store` must fail cleanly with ERR 13 (QEMU does not model flash programming). Then
three wrong keys, a reset through QEMU's monitor (`system_reset`), and the wrong-key count must
have survived it: after the reset the right key is refused until the first unlock window
(ERR 14, wait_ms up to 10000). QEMU is killed at the end (that image has no quit hook).
Closing line: `qemu-serial: N passed, M failed`; exit status 0 when M == 0, else 1.
Standard library only.
"""
import os
import secrets
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time

BANNER = b"# rlg-readout ready"
# A fresh 128-bit key per run: the emulated board boots unprovisioned (QEMU's OTP is a blank RAM
# model) and is provisioned first, as at production.
KEY = secrets.token_hex(16)
LINE_TIMEOUT_S = 5.0
OVERALL_TIMEOUT_S = 90


def crc16(data: bytes) -> int:
    """CRC-16/CCITT-FALSE, as firmware::protocol::parse::crc16."""
    crc = 0xFFFF
    for b in data:
        crc ^= b << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1021) if crc & 0x8000 else (crc << 1)
            crc &= 0xFFFF
    return crc


def with_crc(text: str) -> bytes:
    return f"{text}*{crc16(text.encode()):04X}".encode()


class Link:
    def __init__(self, sock):
        self.sock = sock
        self.buf = b""

    def read_line(self, timeout=LINE_TIMEOUT_S) -> bytes:
        deadline = time.monotonic() + timeout
        while b"\n" not in self.buf:
            left = deadline - time.monotonic()
            if left <= 0:
                raise TimeoutError(f"no complete line within {timeout} s (have {self.buf!r})")
            self.sock.settimeout(left)
            chunk = self.sock.recv(4096)
            if not chunk:
                raise ConnectionError(f"QEMU closed the serial link (have {self.buf!r})")
            self.buf += chunk
        line, self.buf = self.buf.split(b"\n", 1)
        return line.rstrip(b"\r")

    def ask(self, request: bytes) -> str:
        self.sock.sendall(request + b"\n")
        return self.read_line().decode("ascii", "replace")


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def connect(port, qemu, timeout=15.0):
    deadline = time.monotonic() + timeout
    while True:
        if qemu.poll() is not None:
            raise RuntimeError(f"QEMU exited early with status {qemu.returncode}")
        try:
            return socket.create_connection(("127.0.0.1", port), timeout=1.0)
        except OSError:
            if time.monotonic() > deadline:
                raise
            time.sleep(0.05)


def crc_answer_ok(answer: str, body: str) -> bool:
    """`body*XXXX` with the right CRC."""
    if "*" not in answer:
        return False
    text, crc = answer.rsplit("*", 1)
    return text == body and crc == f"{crc16(text.encode()):04X}"


def provision(exchange):
    """An unprovisioned board: no key unlocks it (the old published one neither); provisioned
    once, a second provisioning is refused."""
    exchange("unprovisioned status", b"status", lambda a: " key=unprovisioned " in a + " ")
    exchange("unprovisioned unlock", f"unlock {KEY}".encode(), lambda a: a.startswith("ERR 16 "))
    exchange("32-bit key refused", b"unlock c0ffee42", lambda a: a.startswith("ERR 3 "))
    exchange("key provision", f"key provision {KEY}".encode(), lambda a: a == "OK key=provisioned")
    exchange("provisioned status", b"status", lambda a: " key=provisioned " in a + " ")
    exchange("second provision refused", b"key provision " + b"1" * 32,
             lambda a: a.startswith("ERR 11 "))


def protocol_checks(exchange, link, check, qemu):
    """The serial_protocol example: the protocol end to end, RAM-backed flash."""
    exchange("id", b"id", lambda a: a.startswith("OK fw=") and "board=netduinoplus2" in a)
    exchange("status", b"status",
             lambda a: a.startswith("OK signal=") and "turnarounds=0" in a and "locked=yes" in a)
    exchange("locked set", b"set a 1", lambda a: a.startswith("ERR 9 "))
    provision(exchange)
    exchange("wrong key", b"unlock " + b"12345678" * 4, lambda a: a.startswith("ERR 15 "))
    exchange("unlock", f"unlock {KEY}".encode(), lambda a: a.startswith("OK unlocked"))
    exchange("set", b"set a 12.5", lambda a: a == "OK a=12.5")
    exchange("get", b"get a", lambda a: a == "OK a=12.5")
    echo = link.ask(b"set a 2.5")  # `set a 12.5` with a byte lost: shown, not executed
    check("echo without crc", echo == "ERR 18 confirm (send yes) cmd=set a 2.5", repr(echo))
    exchange("echoed command not run", b"get a", lambda a: a == "OK a=12.5")
    exchange("crc request", with_crc("get a"), lambda a: crc_answer_ok(a, "OK a=12.5"))
    exchange("bad crc", b"get a*0000", lambda a: a.startswith("ERR 6 "))
    # The thermal model: QEMU has no I2C, so the sensor reports a bus fault and no correction
    # is made; the model still goes into the calibration record (format 4) and comes back.
    exchange("thermal sensor", b"thermal", lambda a: a.startswith("OK temp_c=none ") and " sensor=bus " in a)
    for name, value in [("t_ref", "25"), ("t_min", "-20"), ("t_max", "60"), ("b1", "0.002"),
                        ("b3", "-1.25e-7"), ("s1", "0.5")]:
        exchange(f"thermal set {name}", f"thermal set {name} {value}".encode(),
                 lambda a: a.startswith("OK ") and a.endswith(" model=edited"))
    thermal_model = ("OK thermal=on t_ref=25 t_min=-20 t_max=60 b0=0 b1=0.002 b2=0 b3=-0.000000125 "
                     "b_rate=0 s0=0 s1=0.5 s2=0 model=no_sensor")
    exchange("thermal apply", b"thermal apply", lambda a: a == thermal_model)
    exchange("store", b"store", lambda a: a.startswith("OK stored seq=1 "))
    exchange("set after store", b"set a 3", lambda a: a == "OK a=3")
    exchange("thermal off after store", b"thermal off", lambda a: a.startswith("OK thermal=off "))
    exchange("reload", b"reload", lambda a: a in ("OK coeffs=flash:1 dither=stored strip=kept thermal=stored", "OK coeffs=flash:1 dither=stored strip=stored thermal=stored"))
    exchange("thermal model after reload", b"thermal model", lambda a: a == thermal_model)
    exchange("get after reload", b"get a", lambda a: a == "OK a=12.5")
    exchange("dither status", b"dither status",
             lambda a: a.startswith("OK state=off ") and "setpoint_arcsec=450.00" in a)
    exchange("dither amp", b"dither amp 420", lambda a: a == "OK dither=off amp_arcsec=420 noise_pct=0")
    exchange("dither amp out of range", b"dither amp 900", lambda a: a.startswith("ERR 5 "))
    exchange("cal start without a locked drive", b"cal start 100", lambda a: a.startswith("ERR 11 "))
    exchange("second store, with crc", with_crc("store"),
             lambda a: a.startswith("OK stored seq=2 ") and crc_answer_ok(a, a.rsplit("*", 1)[0]))
    exchange("overlong line", b"x" * 300, lambda a: a.startswith("ERR 7 "))
    exchange("binary garbage", b"\x00\xff\x01\x80garbage\x1b[A", lambda a: a.startswith("ERR 8 "))
    exchange("unknown command", b"frobnicate", lambda a: a.startswith("ERR 1 "))
    exchange("in step after garbage", b"id", lambda a: a.startswith("OK fw="))

    # Pipelined: 50 commands in one write (~800 bytes, more than the 511-byte RX queue);
    # every one must be answered, in order.
    burst = 50
    link.sock.sendall(b"".join(with_crc("get a") + b"\n" for _ in range(burst)))
    try:
        answers = [link.read_line().decode("ascii", "replace") for _ in range(burst)]
        good = sum(crc_answer_ok(a, "OK a=12.5") for a in answers)
        check("pipelined burst", good == burst, f"{good}/{burst} answers correct")
    except (TimeoutError, ConnectionError) as e:
        check("pipelined burst", False, str(e))

    link.sock.sendall(b"quit\n")
    try:
        status = qemu.wait(timeout=10)
        check("quit", status == 0, f"QEMU exit status {status}")
    except subprocess.TimeoutExpired:
        check("quit", False, "QEMU still running 10 s after quit")


# The power-up self-test's checks QEMU cannot pass (it models no RCC, no ADC/DAC trigger
# routing and runs its timers at 1 GHz; the pick-off check is then not run), and what the
# board image must answer for each: exactly these fail, the rest pass.
QEMU_UNMODELLED = ["clock", "timer_clock", "triggers", "pickoff"]
QEMU_SELFTEST = {
    "clock": "fail:hse",
    "timers": "pass",
    "timer_clock": "fail:tim2",
    "triggers": "fail:adc1_injected",
    "pickoff": "not_run",
}


def selftest_as_expected(answer: str) -> bool:
    fields = dict(w.split("=", 1) for w in answer.split()[1:] if "=" in w)
    return (answer.startswith("OK ")
            and all(fields.get(k) == v for k, v in QEMU_SELFTEST.items())
            and fields.get("unmodelled") == ",".join(QEMU_UNMODELLED)
            and fields.get("drive") == "inhibited"
            and "watch" in fields)


def board_checks(exchange):
    """The complete board image: comes up, serves the protocol, survives a failing store."""
    exchange("id", b"id", lambda a: a.startswith("OK fw=") and "board=rlg-readout-f405" in a)
    exchange("selftest (QEMU fails exactly what it does not model)", b"selftest",
             selftest_as_expected)
    exchange("status names the failed check, the drive inhibited", b"status",
             lambda a: " drive=inhibited board=clock " in a)
    exchange("status", b"status", lambda a: a.startswith("OK signal=") and "locked=yes" in a)
    provision(exchange)
    exchange("unlock", f"unlock {KEY}".encode(), lambda a: a.startswith("OK unlocked"))
    exchange("set", b"set a 12.5", lambda a: a == "OK a=12.5")
    exchange("dither on refused while inhibited", b"dither on", lambda a: a.startswith("ERR 11 "))
    exchange("store fails cleanly (no flash model)", b"store", lambda a: a.startswith("ERR 13 "))
    exchange("alive after the store", b"get a", lambda a: a == "OK a=12.5")


def monitor_command(port: int, command: bytes) -> None:
    """One command to QEMU's human monitor on a TCP port (its banner and echo are ignored)."""
    with socket.create_connection(("127.0.0.1", port), timeout=5.0) as m:
        m.settimeout(2.0)
        try:
            m.recv(4096)  # the banner and the first prompt
        except socket.timeout:
            pass
        m.sendall(command + b"\n")
        time.sleep(0.2)


def reset_keeps_the_wrong_keys(exchange, link, check, monitor_port):
    """Three wrong keys use the free attempts; the count is kept in backup RAM (`.uninit` RAM in
    the QEMU build) across a reset, so afterwards the right key waits for the first window."""
    for i in range(3):
        exchange(f"wrong key {i + 1}", b"unlock " + b"12345678" * 4,
                 lambda a: a.startswith("ERR 15 "))
    monitor_command(monitor_port, b"system_reset")
    try:
        banner = link.read_line(timeout=10.0)
        check("reset", banner == BANNER, banner.decode("ascii", "replace"))
    except (TimeoutError, ConnectionError) as e:
        check("reset", False, str(e))
        return
    # The QEMU build models OTP in RAM: blank again after the reset, provisioned again.
    exchange("key provision after the reset", f"key provision {KEY}".encode(),
             lambda a: a == "OK key=provisioned")

    def refused_until_a_window(answer):
        prefix = "ERR 14 too many attempts, wait wait_ms="
        return answer.startswith(prefix) and 0 < int(answer[len(prefix):]) <= 10_000

    exchange("wrong keys survive the reset", f"unlock {KEY}".encode(), refused_until_a_window)


def main(elf: str, board: bool) -> int:
    signal.signal(signal.SIGALRM, lambda *_: (_ for _ in ()).throw(TimeoutError("overall timeout")))
    signal.alarm(OVERALL_TIMEOUT_S)
    port = free_port()
    monitor_port = free_port()
    log = tempfile.NamedTemporaryFile(prefix="qemu-serial-", suffix=".defmt", delete=False)
    cmd = ["qemu-system-arm", "-machine", "netduinoplus2", "-display", "none",
           "-semihosting-config", "enable=on,target=native", "-kernel", elf,
           "-serial", f"tcp:127.0.0.1:{port},server=on,wait=on",
           "-monitor", f"tcp:127.0.0.1:{monitor_port},server=on,wait=off"]
    qemu = subprocess.Popen(cmd, stdout=log, stderr=subprocess.PIPE)
    passed, failed = 0, 0

    def check(name, ok, detail):
        nonlocal passed, failed
        if ok:
            passed += 1
            print(f"  ok    {name}: {detail}")
        else:
            failed += 1
            print(f"  FAIL  {name}: {detail}")

    try:
        link = Link(connect(port, qemu))
        banner = link.read_line(timeout=10.0)
        check("banner", banner == BANNER, banner.decode("ascii", "replace"))

        def exchange(name, request, predicate):
            # A person at a terminal: a state-changing line without CRC is echoed as parsed
            # (ERR 18 ... cmd=...) and runs on `yes`.
            try:
                answer = link.ask(request)
                if answer.startswith("ERR 18 confirm (send yes) cmd="):
                    answer = link.ask(b"yes")
            except (TimeoutError, ConnectionError) as e:
                check(name, False, f"{request[:40]!r} -> {e}")
                return
            check(name, predicate(answer), f"{request[:40]!r} -> {answer!r}")

        if board:
            board_checks(exchange)
            reset_keeps_the_wrong_keys(exchange, link, check, monitor_port)
        else:
            protocol_checks(exchange, link, check, qemu)
    except Exception as e:  # noqa: BLE001 - any failure is a test failure, reported below
        check("run", False, f"{type(e).__name__}: {e}")
    finally:
        signal.alarm(0)
        if qemu.poll() is None:
            qemu.kill()
            qemu.wait(timeout=5)
        log.close()
        if failed:
            err = qemu.stderr.read().decode(errors="replace") if qemu.stderr else ""
            if err.strip():
                print("QEMU stderr:\n" + err)
            if shutil.which("defmt-print"):
                with open(log.name, "rb") as f:
                    out = subprocess.run(["defmt-print", "-e", elf], stdin=f,
                                         capture_output=True, timeout=10)
                print("defmt log:\n" + out.stdout.decode(errors="replace")[-4000:])
        elif shutil.which("defmt-print"):
            # The firmware's painted-stack figure for the run (docs/firmware.md "Stack").
            with open(log.name, "rb") as f:
                out = subprocess.run(["defmt-print", "-e", elf], stdin=f,
                                     capture_output=True, timeout=10)
            for line in out.stdout.decode(errors="replace").splitlines():
                if "stack:" in line:
                    print(line)
        os.unlink(log.name)
    print(f"qemu-serial: {passed} passed, {failed} failed")
    return 0 if failed == 0 else 1


if __name__ == "__main__":
    args = sys.argv[1:]
    if "-h" in args or "--help" in args:
        print(__doc__)
        sys.exit(0)
    board_mode = "--board" in args
    args = [a for a in args if a != "--board"]
    if len(args) != 1 or args[0].startswith("-"):
        print(__doc__, file=sys.stderr)
        sys.exit(2)
    sys.exit(main(args[0], board_mode))
