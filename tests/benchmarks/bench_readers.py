"""Recording readers: time and peak memory (max RSS of a fresh process) against file size.

Run: python tests/benchmarks/bench_readers.py [--rows N,N,...]
Prints a Markdown table.  The CSV reader streams into a float64 buffer, so its memory is the
numbers' (32 bytes a row of t,ax,ay,az) plus the interpreter, whatever the text's size; the .npz
reader checks declared sizes before inflating and loads at memory speed.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from accelrig.recording import Recording, save_native

READ = """
import resource, sys, time
from accelrig.recording import load_recording
start = time.perf_counter()
rec = load_recording(sys.argv[1])
print(len(rec), time.perf_counter() - start, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024)
"""

BASELINE = """
import resource
import accelrig.recording
print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024)
"""


def measure(path: Path) -> tuple[int, float, float]:
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1")
    out = subprocess.run([sys.executable, "-c", READ, str(path)], capture_output=True, text=True, check=True,
                         env=env).stdout.split()
    return int(out[0]), float(out[1]), float(out[2])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--rows", default="100000,1000000,4000000")
    args = parser.parse_args()
    base = float(subprocess.run([sys.executable, "-c", BASELINE], capture_output=True, text=True,
                                check=True).stdout)
    print(f"interpreter with accelrig.recording imported: {base:.0f} MiB max RSS")
    print("| format | rows | file MB | read s | max RSS MiB | RSS above interpreter / numbers |")
    print("|---|---:|---:|---:|---:|---:|")
    with tempfile.TemporaryDirectory() as folder:
        for rows in (int(r) for r in args.rows.split(",")):
            t = np.arange(rows) / 200.0
            rec = Recording(t, np.column_stack([np.zeros(rows), np.zeros(rows), np.full(rows, 9.81)]))
            csv_path = Path(folder) / "r.csv"
            np.savetxt(csv_path, np.column_stack([t, rec.acc]), delimiter=",", fmt="%.6f", header="t,ax,ay,az",
                       comments="")
            npz_path = Path(folder) / "r.npz"
            save_native(rec, npz_path)
            numbers = rows * 4 * 8 / 2**20
            for name, path in (("CSV", csv_path), (".npz", npz_path)):
                n, seconds, rss = measure(path)
                assert n == rows
                print(f"| {name} | {rows} | {path.stat().st_size / 1e6:.0f} | {seconds:.2f} | {rss:.0f} | "
                      f"{(rss - base) / numbers:.1f} |")


if __name__ == "__main__":
    main()
