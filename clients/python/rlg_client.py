#!/usr/bin/env python3
"""A reference client of the RLG readout board's serial protocol (docs/protocol.md), in Python
with the standard library only: the document's executable example for integrators.

It sends every line with its CRC-16 suffix and checks the answer's, unlocks with the key of a key
file or the RLG_KEY environment variable (never from the command line), decodes both binary
streams (the per-cycle frames of `stream on` and the fixed-rate output of `stream output`),
counts sequence gaps and integrates the angle. Written from docs/protocol.md alone.

Usage:
  python3 rlg_client.py --tcp HOST:PORT [--key-file PATH] send WORDS...
  python3 rlg_client.py --tcp HOST:PORT stream --seconds S [--divider N]
  python3 rlg_client.py --tcp HOST:PORT record --seconds S
  python3 rlg_client.py --tcp HOST:PORT [--key-file PATH] check --rate DEG_H
  (--port PATH [--baud N] instead of --tcp: a serial port or a pty)

`check` runs an integrator's acceptance against a board at a known constant input rate (a
simulated one: `rlg-cal serve-sim --tcp 127.0.0.1:0 --rate 15 --board-key-file key.txt`): the
CRC, the error codes and the confirmation, a calibration, both streams (no gap, the rate of the
input), stores while streaming (the output whole, the drive locked), the unlock windows. It
prints one line per check and closes with `rlg-client: N passed, M failed`.

Exit status: 0 success; 1 the board answered ERR, or a check failed; 2 usage error; 3 the
connection failed, no answer in time, or a corrupted answer.
"""
import argparse
import math
import os
import socket
import struct
import sys
import time
import zlib

# ---- the protocol's facts (docs/protocol.md) --------------------------------------------------

MAX_LINE = 96                    # "Limits": bytes of a command line, its *XXXX suffix included
STORE_TIMEOUT_S = 2.5            # "Limits": a store may stall the board for a sector erase (2 s)
CYCLE_PAYLOAD = 41               # "Streaming": the cycle frame's payload
OUTPUT_PAYLOAD = 38              # "The fixed-rate output": the output frame's payload (at least)
THERMAL_PAYLOAD = 12             # "The fixed-rate output": the thermal frame's payload
THERMAL_FRAME_CHUNK = 17         # "The fixed-rate output": its bytes before the delimiter
NO_TEMPERATURE = -32768          # the thermal frame's i16 fields: no value
Q32 = 2.0 ** 32
Q16 = 2.0 ** 16
# Output status bits ("The fixed-rate output").
VALID, DITHER_LOCKED, COMPENSATION_ON, RESTART, NO_DITHER_MODEL = 1, 2, 4, 1 << 8, 1 << 10
# Cycle frame flags ("Streaming").
SIGNAL_LOST, COUNTER_GLITCH, TURNAROUND_MISSED, DITHER_INVALID, DRIVE_UNLOCKED = 1, 2, 4, 8, 16


class ProtocolError(Exception):
    """No answer in time, a corrupted answer or frame, a closed connection (exit 3)."""


class BoardError(Exception):
    """The board answered `ERR <code> <text>` (exit 1)."""

    def __init__(self, line, code, text):
        super().__init__(f"`{line}`: ERR {code} {text}")
        self.code, self.text = code, text


def crc16(data: bytes) -> int:
    """CRC-16/CCITT-FALSE: poly 0x1021, init 0xFFFF, no reflection (check: 0x29B1)."""
    crc = 0xFFFF
    for b in data:
        crc ^= b << 8
        for _ in range(8):
            crc = (crc << 1) ^ 0x1021 if crc & 0x8000 else crc << 1
            crc &= 0xFFFF
    return crc


def with_crc(line: str) -> bytes:
    body = line.encode("ascii")
    return body + b"*%04X\n" % crc16(body)


def cobs_decode(chunk: bytes) -> bytes:
    """COBS: each code byte n is followed by n - 1 data bytes and stands for a zero after them
    (none after the last block, nor after a block of 254 data bytes)."""
    out, i = bytearray(), 0
    while i < len(chunk):
        code = chunk[i]
        block = chunk[i + 1 : i + code]
        if code == 0 or len(block) != code - 1:
            raise ProtocolError("malformed COBS")
        out += block
        i += code
        if code < 0xFF and i < len(chunk):
            out.append(0)
    return bytes(out)


def unframe(chunk: bytes, payload_bytes: int) -> bytes:
    """COBS(payload || crc32(payload) LE), the 0x00 delimiter removed: the payload."""
    body = cobs_decode(chunk)
    if len(body) < payload_bytes + 4:
        raise ProtocolError(f"frame of {len(body)} bytes")
    payload, crc = body[:-4], struct.unpack("<I", body[-4:])[0]
    if zlib.crc32(payload) != crc:
        raise ProtocolError("frame CRC-32")
    return payload


def decode_cycle(chunk: bytes) -> dict:
    p = unframe(chunk, CYCLE_PAYLOAD)
    seq, end, raw, comp, p1, p2, duration, flags = struct.unpack_from("<IqqqffIB", p)
    return dict(sequence=seq, end_phase=end, raw=raw, compensated=comp, p1=p1, p2=p2,
                duration=duration, flags=flags)


def is_thermal(chunk: bytes) -> bool:
    """The output stream carries two frames; a receiver tells them by length before the
    delimiter (17 bytes for a thermal frame, 43 or more for an output record)."""
    return len(chunk) == THERMAL_FRAME_CHUNK


def decode_thermal(chunk: bytes) -> dict:
    """The block's temperature (degC) and its rate (degC/min) from record `from_sequence` on;
    None where the board has no value."""
    p = unframe(chunk, THERMAL_PAYLOAD)
    first, t, rate = struct.unpack_from("<Qhh", p)
    return dict(from_sequence=first,
                temperature_c=None if t == NO_TEMPERATURE else t / 128.0,
                temperature_rate_c_per_min=None if rate == NO_TEMPERATURE else rate / 100.0)


def decode_output(chunk: bytes) -> dict:
    p = unframe(chunk, OUTPUT_PAYLOAD)
    seq, t, period, delta, angle, rate, status = struct.unpack_from("<QQIiqfH", p)
    return dict(sequence=seq, time=t, period=period, delta=delta, angle=angle, rate=rate,
                status=status, extra=len(p) - OUTPUT_PAYLOAD)


# ---- the link ---------------------------------------------------------------------------------

class Link:
    """Bytes both ways: a TCP socket, or a serial port / pty (raw, 8N1)."""

    def __init__(self, tcp=None, port=None, baud=460800):
        if tcp:
            host, _, p = tcp.rpartition(":")
            self.sock = socket.create_connection((host, int(p)), timeout=5)
            self.fd = None
        else:
            import termios
            import tty
            self.sock = None
            self.fd = os.open(port, os.O_RDWR | os.O_NOCTTY)
            tty.setraw(self.fd)
            attrs = termios.tcgetattr(self.fd)
            speed = getattr(termios, f"B{baud}", termios.B115200)
            attrs[4] = attrs[5] = speed
            termios.tcsetattr(self.fd, termios.TCSANOW, attrs)

    def send(self, data: bytes):
        if self.sock:
            self.sock.sendall(data)
        else:
            os.write(self.fd, data)

    def receive(self, wait_s: float) -> bytes:
        import select
        handle = self.sock if self.sock else self.fd
        ready, _, _ = select.select([handle], [], [], max(wait_s, 0))
        if not ready:
            return b""
        data = self.sock.recv(65536) if self.sock else os.read(self.fd, 65536)
        if not data:
            raise ProtocolError("connection closed")
        return data


# ---- the client -------------------------------------------------------------------------------

class Client:
    """One command out (with its CRC), exactly one checked answer back; frames collected while a
    stream is on."""

    def __init__(self, link: Link, timeout_s=2.0):
        self.link, self.timeout_s = link, timeout_s
        self.inbox = bytearray()
        self.streaming = False
        self.frames = []           # 0x00-delimited chunks received while streaming

    def _fill(self, deadline):
        data = self.link.receive(deadline - time.monotonic())
        self.inbox += data
        return bool(data)

    def _next_chunk(self):
        zero = self.inbox.find(b"\0")
        if zero < 0:
            return None
        chunk = bytes(self.inbox[:zero])
        del self.inbox[: zero + 1]
        return chunk

    def _answer_in_inbox(self):
        """The next answer line (with its \\r\\n), frames set aside; None when none is complete.
        Text mode: lines; a `#` line is a notice, a leading 0x00 is the delimiter of an answer
        that starts a stream. Stream mode: 0x00-delimited chunks."""
        while True:
            if self.streaming:
                chunk = self._next_chunk()
                if chunk is None:
                    return None
                if chunk.startswith((b"OK", b"ERR")) and chunk.endswith(b"\r\n"):
                    return chunk
                if chunk:
                    self.frames.append(chunk)
                continue
            end = self.inbox.find(b"\r\n")
            if end < 0:
                return None
            line = bytes(self.inbox[: end + 2]).lstrip(b"\0")
            del self.inbox[: end + 2]
            if line.startswith((b"OK", b"ERR")):
                return line
            # a notice (`# ...`) or leftovers: not an answer

    def send_raw(self, data: bytes) -> bytes:
        """Sends bytes as they are; returns the next answer line."""
        self.link.send(data)
        deadline = time.monotonic() + self.timeout_s
        while True:
            line = self._answer_in_inbox()
            if line is not None:
                return line
            if time.monotonic() >= deadline:
                raise ProtocolError(f"no answer to {data[:40]!r}")
            self._fill(deadline)

    def command(self, line: str, timeout_s=None) -> dict:
        """`line` with its CRC; the answer's fields (`OK` answers) or BoardError."""
        old = self.timeout_s
        if timeout_s:
            self.timeout_s = timeout_s
        try:
            answer = self.send_raw(with_crc(line))
        finally:
            self.timeout_s = old
        text = answer[:-2].decode("ascii")
        if text.startswith("ERR") and text.split()[1] in ("6", "7", "8"):
            raise BoardError(line, int(text.split()[1]), text)  # unread lines: no suffix
        body, star, suffix = text.rpartition("*")
        if not star or len(suffix) != 4 or int(suffix, 16) != crc16(body.encode()):
            raise ProtocolError(f"answer to `{line}` without a valid CRC: {text!r}")
        truncated = body.endswith("~")
        body = body.rstrip("~")
        if body.startswith("ERR "):
            _, code, rest = body.split(" ", 2)
            raise BoardError(line, int(code), rest)
        fields = {"_text": body[3:], "_truncated": truncated}
        for i, word in enumerate(body[3:].split(" ")):
            key, eq, value = word.partition("=")
            fields[key if eq else f"_{i}"] = value if eq else word
        if line.startswith("stream"):
            self.streaming = fields.get("stream") in ("on", "output")
        return fields

    def unlock(self, key: str):
        """`unlock`; an ERR 14 (wrong keys before) is waited out, three times at most."""
        for _ in range(3):
            try:
                return self.command(f"unlock {key}")
            except BoardError as e:
                if e.code != 14:
                    raise
                wait_ms = int(e.text.rpartition("wait_ms=")[2])
                time.sleep(wait_ms / 1000 + 0.05)
        return self.command(f"unlock {key}")

    def collect(self, seconds: float):
        """Frames received over `seconds` (stream mode)."""
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self._fill(min(end, time.monotonic() + 0.1))
            while self.streaming:
                chunk = self._next_chunk()
                if chunk is None:
                    break
                if chunk:
                    self.frames.append(chunk)
        frames, self.frames = self.frames, []
        return frames


def read_key(path):
    if path:
        with open(path) as f:
            return f.readline().strip()
    key = os.environ.get("RLG_KEY", "").strip()
    if not key:
        raise SystemExit("rlg-client: no key (--key-file PATH or RLG_KEY)")
    return key


# ---- what a host does with the streams --------------------------------------------------------

class Gaps:
    """Lost frames by the sequence numbers (a number that does not advance is no gap)."""

    def __init__(self, modulus):
        self.modulus, self.last, self.lost, self.received = modulus, None, 0, 0

    def observe(self, seq):
        if self.last is not None:
            step = (seq - self.last) % self.modulus
            if 0 < step < self.modulus // 2:
                self.lost += step - 1
        self.last, self.received = seq, self.received + 1


def cycle_summary(chunks, sf_arcsec, timer_hz):
    frames, bad = [], 0
    for c in chunks:
        try:
            frames.append(decode_cycle(c))
        except ProtocolError:
            bad += 1
    gaps = Gaps(2 ** 32)
    for f in frames:
        gaps.observe(f["sequence"])
    seconds = sum(f["duration"] for f in frames) / timer_hz
    rate = lambda key: (sum(f[key] for f in frames) / Q32 * sf_arcsec / seconds) if seconds else float("nan")
    return dict(frames=frames, bad=bad, lost=gaps.lost, raw_deg_h=rate("raw"),
                compensated_deg_h=rate("compensated"),
                flagged=sum(1 for f in frames if f["flags"]))


def output_summary(chunks, sf_arcsec, timer_hz):
    """Each record gets the temperature of the last thermal frame before it."""
    records, bad, thermal = [], 0, None
    for c in chunks:
        try:
            if is_thermal(c):
                thermal = decode_thermal(c)
                continue
            r = decode_output(c)
        except ProtocolError:
            bad += 1
            continue
        held = thermal is not None and r["sequence"] >= thermal["from_sequence"]
        r["temperature_c"] = thermal["temperature_c"] if held else None
        records.append(r)
    gaps = Gaps(2 ** 64)
    for r in records:
        gaps.observe(r["sequence"])
    valid = [r for r in records if r["status"] & VALID]
    # The rate: the least-squares slope of the integrated angle of the valid records.
    slope = float("nan")
    if len(valid) > 2:
        ts = [r["time"] / timer_hz for r in valid]
        ys = [r["angle"] / Q16 * sf_arcsec for r in valid]
        mt, my = sum(ts) / len(ts), sum(ys) / len(ys)
        stt = sum((t - mt) ** 2 for t in ts)
        slope = sum((t - mt) * (y - my) for t, y in zip(ts, ys)) / stt if stt else float("nan")
    return dict(records=records, bad=bad, lost=gaps.lost,
                invalid=len(records) - len(valid), rate_deg_h=slope)


# ---- the integrator's acceptance --------------------------------------------------------------

class Checks:
    def __init__(self):
        self.passed = self.failed = 0

    def check(self, name, ok, detail=""):
        print(f"check {name}: {'ok' if ok else 'FAIL'} {detail}".rstrip(), flush=True)
        if ok:
            self.passed += 1
        else:
            self.failed += 1
        return ok


def expect_error(client, checks, name, data, code, crc=False):
    line = with_crc(data) if crc else data.encode("latin-1") + b"\n"
    answer = client.send_raw(line).decode("latin-1").rstrip("\r\n")
    checks.check(f"ERR {code}: {name}", answer.startswith(f"ERR {code} "), answer)
    return answer


def check(client: Client, key: str, rate_deg_h: float) -> Checks:
    c = Checks()
    ident = client.command("id")
    sf, timer_hz = float(ident["sf_arcsec"]), float(ident["timer_hz"])
    c.check("crc16 check value", crc16(b"123456789") == 0x29B1)
    c.check("crc16 of `get a`", crc16(b"get a") == 0xF43A)
    client.command("lock")
    before = client.command("get coeffs")["_text"]

    # Error codes (docs/protocol.md "Error codes"); a refused command changes nothing.
    expect_error(client, c, "unknown command", "frobnicate", 1)
    expect_error(client, c, "missing word", "get", 2)
    expect_error(client, c, "spaces only", "   ", 2)
    expect_error(client, c, "not a number", "set a twelve", 3)
    expect_error(client, c, "not finite", "set a NaN", 4)
    expect_error(client, c, "out of range", "set a 1e9", 5)
    answer = expect_error(client, c, "bad checksum", "get a*0000", 6)
    c.check("ERR 6 has no suffix", "*" not in answer, answer)
    expect_error(client, c, "line too long", "get " + "a" * (MAX_LINE - 3), 7)
    c.check("96 bytes with the suffix are a line",
            client.send_raw(b"get a" + b" " * (MAX_LINE - 5 - 5) + b"*%04X\n"
                            % crc16(b"get a" + b" " * (MAX_LINE - 10))).startswith(b"OK a="))
    expect_error(client, c, "invalid character", "get\x01 a", 8)
    expect_error(client, c, "too long wins over invalid", "get " + "a" * (MAX_LINE - 3) + "\x01", 7)
    expect_error(client, c, "invalid bytes are not counted", "get a" + "\x01" * MAX_LINE, 8)
    expect_error(client, c, "locked", "set a 1", 9, crc=True)
    expect_error(client, c, "nothing to confirm", "yes", 11)
    expect_error(client, c, "wrong key", "unlock " + "0" * 31 + "1", 15)
    c.check("refusals changed nothing", client.command("get coeffs")["_text"] == before)
    c.check("empty line: no answer", probe_silence(client, b"\n"))

    client.unlock(key)
    echo = expect_error(client, c, "confirm", "comp off", 18)
    c.check("the echo is the command", echo.endswith("cmd=comp off"), echo)
    c.check("yes executes it", client.send_raw(b"yes\n").startswith(b"OK comp=off"))
    client.command("track on")
    expect_error(client, c, "tracking on", "set a 1", 17, crc=True)
    client.command("track off")

    # The drive, then a calibration outside the dead band (the input is the rate given).
    wait_for(lambda: client.command("status")["drive"] == "locked", 5.0)
    c.check("drive locked", client.command("status")["drive"] == "locked")
    client.command("cal start 100")
    expect_error(client, c, "calibration in progress", "set a 1", 10, crc=True)
    wait_for(lambda: client.command("cal status")["cal"] == "run_done", 5.0)
    try:
        client.command("cal result")
        c.check("ERR 12: too few cycles", False)
    except BoardError as e:
        c.check("ERR 12: too few cycles", e.code == 12 and "reason=2" in e.text, e.text)
    client.command("cal abort")
    client.command("cal start 3000 100")
    wait_for(lambda: client.command("cal status")["cal"] == "run_done", 15.0)
    fit = client.command("cal result")
    c.check("calibration fit", "lock_in_deg_h" in fit, fit["_text"])
    c.check("cal accept: compensation on", client.command("cal accept").get("comp") == "on")
    wait_for(lambda: client.command("output status")["strip"] == "converged", 6.0)

    # The cycle stream: every cycle, no gap, the input's rate.
    start = client.command("stream on 1")
    c.check("stream on answer", start.get("divider") == "1" and start.get("frame_bytes") == "47",
            start["_text"])
    cycles = cycle_summary(client.collect(2.0), sf, timer_hz)
    client.command("stream off")
    n = len(cycles["frames"])
    c.check("cycle frames", n > 500 and cycles["bad"] == 0 and cycles["lost"] == 0,
            f"frames={n} bad={cycles['bad']} lost={cycles['lost']}")
    err = cycles["compensated_deg_h"] - rate_deg_h
    c.check("cycle stream rate", abs(err) < 0.05,
            f"compensated {cycles['compensated_deg_h']:.4f} deg/h, raw {cycles['raw_deg_h']:.4f}")
    # `stream on 10`: each frame is one cycle (its own increment), every 10th.
    client.command("stream on 10")
    tenth = cycle_summary(client.collect(1.0), sf, timer_hz)["frames"]
    client.command("stream off")
    period = sum(f["duration"] for f in tenth) / max(len(tenth), 1) / timer_hz
    c.check("stream on 10: one cycle per frame", 1 / 700 < period < 1 / 250,
            f"{len(tenth)} frames, mean duration {period * 1e3:.3f} ms")

    # The fixed-rate output: every record, valid, the input's rate.
    client.command("stream output")
    out = output_summary(client.collect(2.0), sf, timer_hz)
    client.command("stream off")
    n = len(out["records"])
    c.check("output records", n > 1500 and out["bad"] == 0 and out["lost"] == 0 and out["invalid"] == 0,
            f"records={n} bad={out['bad']} lost={out['lost']} invalid={out['invalid']}")
    c.check("output rate", abs(out["rate_deg_h"] - rate_deg_h) < 0.05,
            f"{out['rate_deg_h']:.4f} deg/h")
    c.check("compensation bit", all(r["status"] & COMPENSATION_ON for r in out["records"]))
    # The block's temperature: a thermal frame before the stream's first record, so every record
    # has one (the simulated board's sensor works; docs/protocol.md "The fixed-rate output").
    temps = [r["temperature_c"] for r in out["records"]]
    c.check("temperature in every record", n > 0 and None not in temps,
            f"{sum(t is not None for t in temps)} of {n}, first {temps[0] if temps else None} degC")

    # Stores while streaming: the output whole, the drive locked (docs/protocol.md "store").
    for attempt in range(2):
        client.command("stream output")
        client.collect(0.3)
        stored = client.command("store", timeout_s=STORE_TIMEOUT_S)
        chunks = client.collect(0.5)
        client.command("stream off")
        out = output_summary(chunks, sf, timer_hz)
        records = out["records"]
        erased = stored.get("readout") == "resynchronised"
        c.check(f"store {attempt + 1} answer", stored.get("_0") == "stored" and "seq" in stored,
                stored["_text"])
        unlocked = sum(1 for r in records if not r["status"] & DITHER_LOCKED)
        limit = 10 if not erased else 15
        c.check(f"store {attempt + 1}: output whole",
                out["lost"] == 0 and out["bad"] == 0 and out["invalid"] <= limit and unlocked == 0,
                f"readout={stored.get('readout')} records={len(records)} lost={out['lost']} "
                f"invalid={out['invalid']} drive_unlocked={unlocked}")
    client.command("stream on 1")
    client.collect(0.2)
    client.command("store", timeout_s=STORE_TIMEOUT_S)
    cycles = cycle_summary(client.collect(0.5), sf, timer_hz)
    client.command("stream off")
    drive_flags = sum(1 for f in cycles["frames"] if f["flags"] & (DRIVE_UNLOCKED | DITHER_INVALID))
    c.check("store: cycle stream untouched", cycles["lost"] == 0 and drive_flags == 0,
            f"frames={len(cycles['frames'])} lost={cycles['lost']} drive_flags={drive_flags}")
    c.check("drive locked after the stores", client.command("status")["drive"] == "locked")

    # Wrong keys: three are checked at once, then only inside windows; the key holder gets in.
    client.command("lock")
    for i in range(3):
        expect_error(client, c, f"wrong key {i + 1}", "unlock " + "%032x" % (i + 1), 15)
    expect_error(client, c, "outside an unlock window", "unlock " + key, 14)
    started = time.monotonic()
    client.unlock(key)
    c.check("the key holder gets in", time.monotonic() - started < 11.0,
            f"after {time.monotonic() - started:.1f} s")
    client.command("lock")
    return c


def probe_silence(client, data, wait_s=0.3):
    """True when `data` gets no answer within `wait_s` (a `get a` after it is answered first)."""
    client.link.send(data)
    answer = client.send_raw(with_crc("get a"))
    return answer.startswith(b"OK a=")


def wait_for(condition, limit_s):
    end = time.monotonic() + limit_s
    while time.monotonic() < end:
        if condition():
            return True
        time.sleep(0.1)
    return False


# ---- command line -----------------------------------------------------------------------------

def main(argv=None):
    ap = argparse.ArgumentParser(prog="rlg_client.py", description=__doc__.split("\n\n")[0])
    where = ap.add_mutually_exclusive_group(required=True)
    where.add_argument("--tcp", metavar="HOST:PORT")
    where.add_argument("--port", metavar="PATH")
    ap.add_argument("--baud", type=int, default=460800)
    ap.add_argument("--key-file", metavar="PATH")
    ap.add_argument("--timeout-s", type=float, default=2.0)
    sub = ap.add_subparsers(dest="cmd", required=True)
    send = sub.add_parser("send")
    send.add_argument("words", nargs="+")
    for name in ("stream", "record"):
        p = sub.add_parser(name)
        p.add_argument("--seconds", type=float, required=True)
        if name == "stream":
            p.add_argument("--divider", type=int, default=1)
    chk = sub.add_parser("check")
    chk.add_argument("--rate", type=float, required=True, metavar="DEG_H")
    args = ap.parse_args(argv)
    if args.cmd == "send" and args.words[0] in ("unlock", "key"):
        ap.error("keys come from --key-file or RLG_KEY, never the command line")
    try:
        client = Client(Link(args.tcp, args.port, args.baud), args.timeout_s)
        if args.cmd == "send":
            line = " ".join(args.words)
            if line.split()[0] in ("set", "comp", "track", "store", "reload", "defaults", "cal", "dither"):
                if args.key_file or os.environ.get("RLG_KEY"):
                    client.unlock(read_key(args.key_file))
            print(client.command(line, timeout_s=STORE_TIMEOUT_S)["_text"])
        elif args.cmd in ("stream", "record"):
            ident = client.command("id")
            sf, timer_hz = float(ident["sf_arcsec"]), float(ident["timer_hz"])
            if args.cmd == "stream":
                client.command(f"stream on {args.divider}")
                s = cycle_summary(client.collect(args.seconds), sf, timer_hz)
                print(f"frames={len(s['frames'])} lost={s['lost']} bad={s['bad']} "
                      f"flagged={s['flagged']} raw_deg_h={s['raw_deg_h']:.4f} "
                      f"compensated_deg_h={s['compensated_deg_h']:.4f}")
            else:
                client.command("stream output")
                s = output_summary(client.collect(args.seconds), sf, timer_hz)
                print(f"records={len(s['records'])} lost={s['lost']} bad={s['bad']} "
                      f"invalid={s['invalid']} rate_deg_h={s['rate_deg_h']:.4f} "
                      f"temperature_c={s['records'][-1]['temperature_c'] if s['records'] else None}")
            client.command("stream off")
        else:
            result = check(client, read_key(args.key_file), args.rate)
            print(f"rlg-client: {result.passed} passed, {result.failed} failed")
            return 0 if result.failed == 0 else 1
    except BoardError as e:
        print(f"rlg-client: the board refused {e}", file=sys.stderr)
        return 1
    except (ProtocolError, OSError) as e:
        print(f"rlg-client: {e}", file=sys.stderr)
        return 3
    return 0


if __name__ == "__main__":
    sys.exit(main())
