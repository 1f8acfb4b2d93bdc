"""Start-up: how long a command takes to start, against ``python -c "import numpy"``.

Run: python tests/benchmarks/bench_startup.py [--runs N]
Prints a Markdown table: command, wall time (median of N fresh interpreters),
modules imported.  For ``accelrig record`` the time is to its first sample
(the recorder stamps it), not to the end of the recording.  Wall times
depend on the machine and its load: compare rows of one run, not runs.
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

# Runs in the child: count the modules a command imported once it is done, and
# for `record` report the wall-clock time of the first sample the recorder takes.
PROBE = """
import atexit, sys, time
atexit.register(lambda: print(f"MODULES {len(sys.modules)}", file=sys.stderr))
if sys.argv[1] == "record":
    from accelrig.acquisition import recorder
    keep = recorder.Recorder._keep
    def first(self, chunk):
        if chunk.n and not self.samples:
            print(f"FIRST {time.time()}", file=sys.stderr)
        keep(self, chunk)
    recorder.Recorder._keep = first
from accelrig.cli import main
sys.argv = ["accelrig"] + sys.argv[1:]
try:
    main()
except SystemExit:
    pass
"""

BASELINE = 'import sys, numpy; print(f"MODULES {len(sys.modules)}", file=sys.stderr)'


def run_once(args: list[str]) -> tuple[float, int]:
    """(seconds from spawn to the end, or to the first sample of a recording; modules imported)."""
    t0 = time.time()
    done = subprocess.run([sys.executable, "-c", *args], capture_output=True, text=True, timeout=120)
    t1 = time.time()
    fields = dict(line.split(" ", 1) for line in done.stderr.splitlines() if line.startswith(("FIRST ", "MODULES ")))
    if "MODULES" not in fields:
        raise RuntimeError(f"{args} failed: {done.stderr[-2000:]}")
    end = float(fields["FIRST"]) if "FIRST" in fields else t1
    return end - t0, int(fields["MODULES"])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=5)
    runs = parser.parse_args().runs
    with tempfile.TemporaryDirectory() as tmp:
        out = str(Path(tmp) / "x.csv")
        cases = [
            ('python -c "import numpy"', [BASELINE]),
            ("accelrig --help", [PROBE, "--help"]),
            ("accelrig calibrate static --help", [PROBE, "calibrate", "static", "--help"]),
            ("accelrig record 'sim://still?pace=fast' --seconds 0.1 -o x.csv (to first sample)",
             [PROBE, "record", "sim://still?pace=fast", "--seconds", "0.1", "-o", out]),
        ]
        print(f"| command | wall s (median of {runs}) | modules imported |")
        print("|---|---|---|")
        for label, args in cases:
            results = [run_once(args) for _ in range(runs)]
            wall = statistics.median(r[0] for r in results)
            print(f"| `{label}` | {wall:.3f} | {results[-1][1]} |")


if __name__ == "__main__":
    main()
