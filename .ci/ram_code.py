#!/usr/bin/env python3
"""Checks that the board firmware's RAM-resident code never touches flash, and prints its size.

Usage: python3 .ci/ram_code.py target/thumbv7em-none-eabihf/release/firmware
       python3 .ci/ram_code.py --rtic target/thumbv7em-none-eabihf/release/examples/rtic_board

While the F405's single flash bank programs or erases, every fetch from flash stalls (RM0090
3.5); what must run then lives in RAM (firmware/src/board/ram.rs). This script reads the ELF
(standard library only), decodes every Thumb instruction of the functions linked into RAM, and
fails when one of them
  - branches or calls into flash, except through the long-branch thunks to the functions named
    in ALLOWED (the controller's tick, called only while the flash is idle; the panic path,
    which never returns);
  - loads an address in flash as a constant (a table or a function pointer in flash), or
  - makes an indirect call or jump (which cannot be checked),
and when one of the REQUIRED functions or tables is not in RAM. It prints each RAM-resident
function and table with its bytes.

The RAM-resident handlers are the board's `board::ram::{tim4, usart1, systick}` (patched into the
RAM copy of the vector table), or with --rtic those of the RTIC study (examples/rtic_board.rs:
the vector symbols TIM4, USART1 and SysTick that RTIC generates, linked into RAM by the tasks'
link_section); there the linked vector table is copied unchanged, so its entries for the three
must point into RAM, which is checked too.
"""
import re
import struct
import sys

sys.path.insert(0, __import__("os").path.dirname(__file__))
from image_size import FLASH, RAM  # noqa: E402

STT_FUNC = 2
# The RAM-resident handlers, by binding: (what, pattern of the symbol, vector table entry).
HANDLERS = {
    "board": [
        ("drive tick (TIM4)", r"board3ram4tim4", None),
        ("serial link (USART1)", r"board3ram6usart1", None),
        ("millisecond tick (SysTick)", r"board3ram7systick", None),
    ],
    "rtic": [
        ("drive tick (TIM4)", r"^TIM4$", 16 + 30),
        ("serial link (USART1)", r"^USART1$", 16 + 37),
        ("millisecond tick (SysTick)", r"^SysTick$", 15),
    ],
}
# (what, pattern of its mangled name): must be linked into RAM (with the handlers above).
REQUIRED = [
    ("flash erase: start and wait", r"board3ram14start_and_wait"),
    ("flash program: write and wait", r"board3ram16program_and_wait"),
    ("cossin", r"math6cossin6cossin"),
    ("cossin's table", r"math6cossin6COSSIN"),
    ("vector table", r"board3ram11RAM_VECTORS"),
]
# Flash functions the RAM-resident code may call (through a thunk), and why.
ALLOWED = [
    (r"board6dither15controller_tick", "the controller's tick: called only while the flash is idle"),
    (r"panicking|rust_begin_unwind|2rt5fatal", "the panic path: never returns"),
]


def in_range(addr, region):
    return region[0] <= addr < region[0] + region[1]


def read_elf(path):
    b = open(path, "rb").read()
    (shoff,) = struct.unpack_from("<I", b, 0x20)
    (shentsize, shnum, shstrndx) = struct.unpack_from("<HHH", b, 0x2E)
    sections = [struct.unpack_from("<IIIIIIIIII", b, shoff + i * shentsize) for i in range(shnum)]

    def cstr(off):
        return b[off : b.index(b"\0", off)].decode()

    secs = [dict(name=cstr(sections[shstrndx][4] + s[0]), type=s[1], addr=s[3], off=s[4], size=s[5]) for s in sections]
    symbols = []
    for s in sections:
        if s[1] == 2:  # SHT_SYMTAB
            strtab = sections[s[6]][4]
            for off in range(s[4], s[4] + s[5], 16):
                st_name, value, size, info = struct.unpack_from("<IIIB", b, off)
                if st_name:
                    symbols.append(dict(name=cstr(strtab + st_name), value=value, size=size, type=info & 0xF))
    return b, secs, symbols


class Image:
    def __init__(self, path):
        self.bytes, self.secs, self.symbols = read_elf(path)

    def read(self, addr, n):
        """n bytes at run-time address addr (from the section's file image)."""
        for s in self.secs:
            if s["type"] != 8 and s["addr"] <= addr and addr + n <= s["addr"] + s["size"] and s["addr"]:
                o = s["off"] + addr - s["addr"]
                return self.bytes[o : o + n]
        return None


def sign(value, bits):
    return value - (1 << bits) if value & (1 << (bits - 1)) else value


def decode(image, start, end):
    """Yields (address, kind, value) for every branch target, indirect branch and flash
    constant between start and end (a Thumb function)."""
    pc = start
    movw = {}
    while pc < end:
        hw1 = struct.unpack("<H", image.read(pc, 2))[0]
        if hw1 >> 11 in (0b11101, 0b11110, 0b11111):
            hw2 = struct.unpack("<H", image.read(pc + 2, 2))[0]
            size = 4
        else:
            hw2, size = None, 2
        here = pc
        pc += size
        base = (here + 4) & ~3
        if size == 2:
            if hw1 & 0xF000 == 0xD000 and (hw1 >> 8) & 0xF < 0xE:  # B<c> T1
                yield here, "branch", here + 4 + sign((hw1 & 0xFF) << 1, 9)
            elif hw1 & 0xF800 == 0xE000:  # B T2
                yield here, "branch", here + 4 + sign((hw1 & 0x7FF) << 1, 12)
            elif hw1 & 0xF500 == 0xB100:  # CBZ/CBNZ
                yield here, "branch", here + 4 + ((hw1 >> 9 & 1) << 6 | (hw1 >> 3 & 0x1F) << 1)
            elif hw1 & 0xFF00 == 0x4700:  # BX/BLX register
                if hw1 & 0x80 or (hw1 >> 3) & 0xF != 14:
                    yield here, "indirect", hw1
            elif hw1 & 0xFF87 == 0x4687:  # MOV pc, Rm
                yield here, "indirect", hw1
            elif hw1 & 0xF800 == 0x4800:  # LDR literal T1
                (value,) = struct.unpack("<I", image.read(base + (hw1 & 0xFF) * 4, 4))
                yield here, "constant", value
            continue
        if hw1 & 0xF800 == 0xF000 and hw2 & 0x8000:  # branches and misc control
            s_bit = hw1 >> 10 & 1
            j1, j2 = hw2 >> 13 & 1, hw2 >> 11 & 1
            if hw2 & 0x5000 == 0x0000:  # B T3 (conditional), or misc control (cond 111x)
                if (hw1 >> 6) & 0xE == 0xE:
                    continue
                imm = s_bit << 20 | j2 << 19 | j1 << 18 | (hw1 & 0x3F) << 12 | (hw2 & 0x7FF) << 1
                yield here, "branch", here + 4 + sign(imm, 21)
            elif hw2 & 0x1000:  # B T4 (0x9000) or BL (0xD000)
                i1, i2 = 1 - (j1 ^ s_bit), 1 - (j2 ^ s_bit)
                imm = s_bit << 24 | i1 << 23 | i2 << 22 | (hw1 & 0x3FF) << 12 | (hw2 & 0x7FF) << 1
                yield here, "call" if hw2 & 0x4000 else "branch", here + 4 + sign(imm, 25)
            elif hw2 & 0x4000:  # BLX immediate (to ARM state): never valid on an M core
                yield here, "indirect", hw1
            continue
        if hw1 & 0xFF7F == 0xF85F:  # LDR.W literal
            offset = hw2 & 0xFFF
            (value,) = struct.unpack("<I", image.read(base + (offset if hw1 & 0x80 else -offset), 4))
            if hw2 >> 12 == 15:
                yield here, "indirect", hw1
            yield here, "constant", value
        elif hw1 & 0xFE7F == 0xE85F:  # LDRD literal
            offset = (hw2 & 0xFF) * 4
            addr = base + (offset if hw1 & 0x80 else -offset)
            for word in struct.unpack("<II", image.read(addr, 8)):
                yield here, "constant", word
        elif hw1 & 0xFFF0 == 0xE8D0 and hw2 & 0xFFE0 == 0xF000:  # TBB/TBH: an inline table
            yield here, "indirect", hw1
        elif hw1 & 0xFBF0 in (0xF240, 0xF2C0) and not hw2 & 0x8000:  # MOVW / MOVT
            imm = (hw1 & 0xF) << 12 | (hw1 >> 10 & 1) << 11 | (hw2 >> 12 & 7) << 8 | hw2 & 0xFF
            rd = hw2 >> 8 & 0xF
            if hw1 & 0xFBF0 == 0xF240:
                movw[rd] = imm
            elif rd in movw:
                yield here, "constant", imm << 16 | movw.pop(rd)


def main(path, binding):
    image = Image(path)
    funcs = [s for s in image.symbols if s["type"] == STT_FUNC and in_range(s["value"], RAM)]
    by_addr = {s["value"] & ~1: s for s in image.symbols if s["type"] == STT_FUNC}
    ram_objects = [s for s in image.symbols if in_range(s["value"], RAM) and s["size"]]
    failures = []
    required = [(what, pattern) for what, pattern, _ in HANDLERS[binding]] + REQUIRED
    for what, pattern in required:
        if not any(re.search(pattern, s["name"]) for s in ram_objects):
            failures.append(f"not in RAM: {what} (/{pattern}/)")
    table = next((s["value"] for s in image.symbols if s["name"] == "__RESET_VECTOR"), None)
    for what, _, entry in HANDLERS[binding]:
        if entry is None:
            continue
        # __RESET_VECTOR is entry 1 of the linked table (cortex-m-rt's .vector_table).
        word = table is not None and image.read(table + 4 * (entry - 1), 4)
        if not word or not in_range(struct.unpack("<I", word)[0] & ~1, RAM):
            failures.append(f"the linked vector table's entry {entry} ({what}) does not point into RAM")
    thunk = re.compile(r"^__Thumbv7\w*LongThunk_(.+)$")
    code_bytes, allowed_seen = 0, {}
    for f in sorted(funcs, key=lambda s: s["value"]):
        m = thunk.match(f["name"])
        if m:
            # Checked where it is called from: its target decides.
            code_bytes += f["size"]
            continue
        start = f["value"] & ~1
        code_bytes += f["size"]
        events = list(decode(image, start, start + f["size"]))
        allowed_calls = set()
        for at, kind, value in events:
            where = f"{f['name']} +{at - start:#x}"
            if kind == "indirect":
                failures.append(f"{where}: an indirect branch or inline table ({value:#06x}): cannot be checked")
            elif kind in ("branch", "call"):
                target = value & ~1
                if in_range(target, RAM):
                    callee = by_addr.get(target)
                    t = callee and thunk.match(callee["name"])
                    if not t:
                        continue
                    name = t.group(1)
                    real = next((s for s in image.symbols if s["name"] == name), None)
                    if real and in_range(real["value"], RAM):
                        continue
                    reason = next((why for pat, why in ALLOWED if re.search(pat, name)), None)
                    if reason:
                        allowed_seen[name] = reason
                        allowed_calls.add(at)
                    else:
                        failures.append(f"{where}: calls {name} in flash")
                else:
                    failures.append(f"{where}: branches to {target:#010x} in flash")
        for at, kind, value in events:
            # An address in flash right before an allowed call is that call's argument (the
            # panic path's location): it is read only on that path.
            if kind == "constant" and in_range(value & ~1, FLASH):
                if not any(0 < call - at <= 8 for call in allowed_calls):
                    failures.append(f"{f['name']} +{at - start:#x}: loads {value:#010x}, an address in flash")
    print("RAM-resident code and tables (bytes):")
    for s in sorted(ram_objects, key=lambda s: s["value"]):
        if s["type"] == STT_FUNC or any(re.search(p, s["name"]) for _, p in required):
            print(f"  {s['size']:>6}  {s['name']}")
    tables = sum(s["size"] for s in ram_objects if s["type"] != STT_FUNC and any(re.search(p, s["name"]) for _, p in required))
    print(f"  code {code_bytes} bytes, tables {tables} bytes: {code_bytes + tables} bytes of RAM in all")
    for name, why in sorted(allowed_seen.items()):
        print(f"  calls into flash allowed: {name} ({why})")
    if failures:
        print("\n".join(["RAM-resident code touches flash:"] + [f"  {f}" for f in failures]))
        sys.exit(1)
    print("RAM-resident code: no branch, call or address constant into flash outside the allowed calls")


if __name__ == "__main__":
    args = sys.argv[1:]
    binding = "rtic" if "--rtic" in args else "board"
    args = [a for a in args if a != "--rtic"]
    if len(args) != 1:
        sys.exit(__doc__)
    main(args[0], binding)
