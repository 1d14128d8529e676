#!/usr/bin/env python3
"""Runs the reference client (clients/python/rlg_client.py) against a simulated board.

Usage: python3 .ci/reference_client.py RLG_CAL [--rate DEG_H]

Writes a fresh random key to a temporary file, starts `RLG_CAL serve-sim --tcp 127.0.0.1:0
--rate DEG_H --board-key-file FILE` (default 15 deg/h), runs `rlg_client.py check` against the
address it prints, and stops the server. Exits with the client's status (0: every check passed).
Standard library only.
"""
import argparse
import os
import secrets
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
CLIENT = os.path.join(HERE, "..", "clients", "python", "rlg_client.py")


def main():
    ap = argparse.ArgumentParser(prog="python3 .ci/reference_client.py", description=__doc__.split("\n\n")[0])
    ap.add_argument("rlg_cal", metavar="RLG_CAL", help="the rlg-cal binary")
    ap.add_argument("--rate", type=float, default=15.0, metavar="DEG_H")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        key_file = os.path.join(tmp, "key.txt")
        with open(key_file, "w") as f:
            f.write(secrets.token_hex(16) + "\n")
        server = subprocess.Popen(
            [args.rlg_cal, "serve-sim", "--tcp", "127.0.0.1:0", "--rate", str(args.rate),
             "--board-key-file", key_file],
            stdout=subprocess.PIPE, text=True)
        try:
            address = server.stdout.readline().strip()
            if not address:
                sys.exit("reference-client: serve-sim printed no address")
            print(f"reference-client: serve-sim on {address}, {args.rate} deg/h", flush=True)
            status = subprocess.call(
                [sys.executable, CLIENT, "--tcp", address, "--key-file", key_file, "check",
                 "--rate", str(args.rate)])
        finally:
            server.terminate()
            server.wait(timeout=10)
    return status


if __name__ == "__main__":
    sys.exit(main())
