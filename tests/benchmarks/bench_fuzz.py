"""Long fuzzing of the recording reader (CSV, .npz), the YAML loader and the wire-protocol frame parser.

Run: python tests/benchmarks/bench_fuzz.py [--seconds S]   (S per target, default 60)
Prints a Markdown table: examples tried, rate, and findings (any exception other than an
AccelrigError, or a broken invariant), each finding with the input that caused it, shrunk.
The same targets run for a few seconds in every test run (tests/hostile/test_fuzz.py).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from hypothesis import HealthCheck, given, seed, settings

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))   # tests/: the hostile package

from hostile.fuzz_targets import TARGETS  # noqa: E402

BATCH = 500


def fuzz(name: str, seconds: float) -> tuple[int, float, list[str]]:
    target, strategy = TARGETS[name]
    tried = 0
    findings: list[str] = []
    start = time.monotonic()
    batch = 0
    while time.monotonic() - start < seconds:
        batch += 1

        def counted(data: bytes) -> None:
            nonlocal tried
            tried += 1
            target(data)

        run = seed(batch)(settings(max_examples=BATCH, deadline=None, database=None,
                                   suppress_health_check=list(HealthCheck))(given(strategy)(counted)))
        try:
            run()
        except Exception as exc:   # noqa: BLE001 - a finding, reported with its shrunk input
            findings.append(f"{type(exc).__name__}: {str(exc).splitlines()[0][:160] if str(exc) else ''}")
    return tried, time.monotonic() - start, findings


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--seconds", type=float, default=60.0, help="seconds per target")
    args = parser.parse_args()
    rows = []
    for name in TARGETS:
        tried, elapsed, findings = fuzz(name, args.seconds)
        rows.append((name, tried, elapsed, findings))
    print("| target | examples | seconds | examples/s | findings |")
    print("|---|---:|---:|---:|---|")
    for name, tried, elapsed, findings in rows:
        print(f"| {name} | {tried} | {elapsed:.0f} | {tried / elapsed:.0f} | {len(findings) or 'none'} |")
    for name, _, _, findings in rows:
        for finding in findings:
            print(f"- {name}: {finding}")


if __name__ == "__main__":
    main()
