#!/usr/bin/env python3
"""`rlg-sim allan` against allantools' overlapping ADEV (issue 14 item 2).

Generates a record in `rlg-sim record`'s columns (2^20 samples at 400 Hz: white rate noise,
a rate random walk, quantisation and a 10 deg/h bias; seeded), runs `rlg-sim allan --csv` on
it, computes allantools.oadev on the same numbers (the angles as printed in the file, over the
sample period) and requires the same octave taus and every deviation equal to 1e-9 relative.

usage: allantools_check.py PATH/TO/rlg-sim [WORKDIR]
       allantools_check.py --write-record PATH SAMPLES   (only the record, e.g. 15000000 for
                                                          docs/results.md's 15 M-sample timing)
"""
import csv
import os
import subprocess
import sys
import tempfile

import allantools
import numpy as np

TOLERANCE = 1e-9
PERIOD_S = 0.0025
SAMPLES = 1 << 20


def record(path, samples=SAMPLES):
    rng = np.random.default_rng(14)
    white = 60 * 0.003 / np.sqrt(PERIOD_S) * rng.standard_normal(samples)  # ARW 0.003 deg/rt(h)
    walk = np.cumsum(0.05 / 60 * np.sqrt(PERIOD_S) * rng.standard_normal(samples))  # RRW
    e = 0.3 * rng.standard_normal(samples + 1)  # quantisation, arcsec
    rate = 10.0 + white + walk + np.diff(e) / PERIOD_S  # deg/h = arcsec/s
    with open(path, "w") as f:
        f.write("t_s,delta_angle_arcsec,true_delta_angle_arcsec,valid\n")
        for start in range(0, samples, 1 << 20):
            chunk = rate[start:start + (1 << 20)] * PERIOD_S
            f.write("".join(f"{(start + k) * PERIOD_S:.6f},{d:.9f},{d:.9f},1\n"
                            for k, d in enumerate(chunk)))


def rates(path):
    """The numbers both implementations see: the file's angles over the period."""
    with open(path) as f:
        rows = csv.DictReader(f)
        return np.array([float(row["delta_angle_arcsec"]) for row in rows]) / PERIOD_S


def main():
    if sys.argv[1] == "--write-record":
        record(sys.argv[2], int(sys.argv[3]))
        return
    binary = sys.argv[1]
    work = sys.argv[2] if len(sys.argv) > 2 else tempfile.mkdtemp(prefix="allan-check-")
    os.makedirs(work, exist_ok=True)
    data, out = os.path.join(work, "record.csv"), os.path.join(work, "adev.csv")
    record(data)
    rate = rates(data)
    subprocess.run([binary, "allan", "--input", data, "--csv", out], check=True,
                   stdout=subprocess.DEVNULL)
    with open(out) as f:
        ours = [(float(r["tau_s"]), float(r["adev_deg_h"])) for r in csv.DictReader(f)]
    taus, adev, _, _ = allantools.oadev(rate, rate=1 / PERIOD_S, data_type="freq", taus="octave")
    print(f"{len(ours)} taus from rlg-sim, {len(taus)} from allantools "
          f"{getattr(allantools, '__version__', '?')}")
    if len(ours) != len(taus):
        sys.exit(f"different tau sets: {[t for t, _ in ours]} vs {list(taus)}")
    worst = 0.0
    for (tau, ours_adev), their_tau, their_adev in zip(ours, taus, adev):
        rel_tau = abs(tau / their_tau - 1)
        rel = abs(ours_adev / their_adev - 1)
        worst = max(worst, rel)
        print(f"tau {tau:12.4f} s  rlg-sim {ours_adev:.12e}  allantools {their_adev:.12e}  "
              f"rel {rel:.1e}")
        if rel_tau > 1e-9 or not rel <= TOLERANCE:
            sys.exit(f"FAIL at tau {tau} s: relative difference {rel:.3e} (tau {rel_tau:.1e})")
    print(f"allantools check: {len(ours)} taus equal, worst relative difference {worst:.2e} "
          f"(tolerance {TOLERANCE:g})")


if __name__ == "__main__":
    main()
