#!/usr/bin/env python3
"""Size of the firmware image and a check that the linker kept out of the calibration sectors.

Usage: python3 .ci/image_size.py [--budget] target/thumbv7em-none-eabihf/release/firmware

Reads the ELF itself (standard library only: no llvm-tools, no arm-none-eabi binutils).
Prints Berkeley-style text/data/bss, flash and RAM use, and exits 1 if any loaded byte lies at or
beyond __calibration_start (0x080C0000, sectors 10 and 11) or the static RAM overflows; with
--budget also if the board image passes its budgets (docs/board.md "Image size").
"""
import struct
import sys

SHF_WRITE, SHF_ALLOC, SHT_NOBITS, PT_LOAD = 0x1, 0x2, 8, 1
FLASH = (0x0800_0000, 1024 * 1024)
RAM = (0x2000_0000, 128 * 1024)
# The board image's budgets (docs/board.md "Image size"): ceilings against unnoticed growth.
BUDGET_FLASH, BUDGET_STATIC_RAM = 128 * 1024, 16 * 1024


def read_elf(path):
    b = open(path, "rb").read()
    if b[:4] != b"\x7fELF" or b[4] != 1 or b[5] != 1:
        sys.exit(f"{path}: not a 32-bit little-endian ELF")
    (phoff, shoff) = struct.unpack_from("<II", b, 0x1C)
    (phentsize, phnum, shentsize, shnum, shstrndx) = struct.unpack_from("<HHHHH", b, 0x2A)
    sections = [struct.unpack_from("<IIIIIIIIII", b, shoff + i * shentsize) for i in range(shnum)]
    strtab = sections[shstrndx]

    def name(off, table):
        start = table[4] + off
        return b[start : b.index(b"\0", start)].decode()

    secs = [dict(name=name(s[0], strtab), type=s[1], flags=s[2], addr=s[3], size=s[5]) for s in sections]
    segs = [struct.unpack_from("<IIIIIIII", b, phoff + i * phentsize) for i in range(phnum)]
    symbols = {}
    for s in sections:
        if s[1] == 2:  # SHT_SYMTAB; s[6] = sh_link = its string table
            names = sections[s[6]]
            for off in range(s[4], s[4] + s[5], 16):
                st_name, st_value = struct.unpack_from("<II", b, off)
                if st_name:
                    symbols[name(st_name, names)] = st_value
    return secs, segs, symbols


def main(path, budget=False):
    secs, segs, sym = read_elf(path)
    alloc = [s for s in secs if s["flags"] & SHF_ALLOC and s["size"]]
    text = sum(s["size"] for s in alloc if not s["flags"] & SHF_WRITE)
    data = sum(s["size"] for s in alloc if s["flags"] & SHF_WRITE and s["type"] != SHT_NOBITS)
    bss = sum(s["size"] for s in alloc if s["flags"] & SHF_WRITE and s["type"] == SHT_NOBITS)
    # Physical (load) addresses of everything stored in flash: code, constants, .data's initial values.
    loads = [(p[3], p[4]) for p in segs if p[0] == PT_LOAD and p[4]]  # p_paddr, p_filesz
    flash_end = max(a + n for a, n in loads)
    calib = sym.get("__calibration_start", 0x080C_0000)
    calib_end = sym.get("__calibration_end", FLASH[0] + FLASH[1])
    ram_end = max((s["addr"] + s["size"] for s in alloc if s["flags"] & SHF_WRITE), default=RAM[0])

    print(f"{'text':>8} {'data':>8} {'bss':>8}  file")
    print(f"{text:>8} {data:>8} {bss:>8}  {path}")
    print(f"flash: {text + data} bytes = {(text + data) / 1024:.1f} KiB of {(calib - FLASH[0]) // 1024} KiB "
          f"(image 0x{FLASH[0]:08x}..0x{flash_end:08x})")
    intrudes = flash_end > calib or any(a < calib_end and a + n > calib for a, n in loads)
    verdict = "CODE INSIDE" if intrudes else "no code inside"
    print(f"calibration: 0x{calib:08x}..0x{calib_end:08x} ({(calib_end - calib) // 1024} KiB), {verdict}")
    print(f"ram: {data + bss} bytes static = {(data + bss) / 1024:.1f} KiB of {RAM[1] // 1024} KiB "
          "(the rest is stack)")
    ok = True
    if intrudes:
        print(f"ERROR: image reaches 0x{flash_end:08x}, into the calibration sectors at 0x{calib:08x}")
        ok = False
    if calib != 0x080C_0000 or calib_end != 0x0810_0000:
        print("ERROR: memory.x no longer puts the calibration store in sectors 10 and 11")
        ok = False
    if ram_end > RAM[0] + RAM[1]:
        print(f"ERROR: static RAM ends at 0x{ram_end:08x}, beyond the 128 KiB SRAM")
        ok = False
    if budget and text + data > BUDGET_FLASH:
        print(f"ERROR: {text + data} bytes of flash, over the budget of {BUDGET_FLASH}")
        ok = False
    if budget and data + bss > BUDGET_STATIC_RAM:
        print(f"ERROR: {data + bss} bytes of static RAM, over the budget of {BUDGET_STATIC_RAM}")
        ok = False
    return 0 if ok else 1


if __name__ == "__main__":
    args = sys.argv[1:]
    budget = "--budget" in args
    paths = [a for a in args if a != "--budget"]
    if len(paths) != 1:
        sys.exit(__doc__)
    sys.exit(main(paths[0], budget))
