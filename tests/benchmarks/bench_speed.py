"""Speed against the papers' methods on the same data (issue 18): static calibration.

    python tests/benchmarks/bench_speed.py [--recordings 5] [--repeats 3] [--seed 1]

Each recording: sim://static as bench_static.py simulates it (six faces, 4 s each at 200 Hz,
handling between), written as the CSV interchange a person hands the command.  On the same
recordings, the default (``--model auto``: the six-face model, tilt of each pose a nuisance,
MAP fit) against the paper's method (``--model paper --method paper``: 9 parameters, Nelder-Mead
over the angles as in Listing 2):

* fit alone: CPU time inside the fit function (``fit_six_face`` / ``fit_model(.., "paper", "paper")``),
  timed by wrapping it where the procedure calls it;
* analysis: ``calibrate_static`` on the loaded recording (pose detection, noise checks, fit, result);
* whole command: ``accelrig calibrate static FILE --json --no-store`` as a subprocess, wall time and
  the child's CPU time (start-up, imports, CSV parsing included).

Median over recordings x repeats, the two methods alternating (a shared box's load hits both alike),
and the median of the paired ratios (the two methods back to back on one recording).
Prints a Markdown table.
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from accelrig.procedures.static import procedure as static_procedure
from accelrig.recording import load_recording, write_csv
from accelrig.sim.device import simulate
from accelrig.sim.rigs.static import StaticRig
from accelrig.sim.sensor import SensorModel, SimClock

RATE, SIGMA = 200.0, 0.05
METHODS = {"default (auto: six-face, MAP)": [], "paper (--model paper --method paper)": ["--model", "paper",
                                                                                        "--method", "paper"]}
SETTINGS = {"default (auto: six-face, MAP)": {}, "paper (--model paper --method paper)": {"model": "paper",
                                                                                          "method": "paper"}}


def recordings(directory: Path, count: int, seed: int) -> list[Path]:
    paths = []
    for k in range(count):
        sensor = SensorModel(range_g=8.0, noise_density=SensorModel.noise_density_for_sd(SIGMA, RATE))
        rig = StaticRig(np.random.default_rng(seed + k + 10_000))
        rec = simulate(rig, sensor, SimClock(RATE), seed=seed + k)
        path = directory / f"static_{k}.csv"
        write_csv(rec, path)
        paths.append(path)
    return paths


class FitTimer:
    """CPU seconds spent inside the procedure's fit functions (the fit alone)."""

    def __init__(self):
        self.seconds = 0.0
        self._saved = {}

    def __enter__(self):
        for name in ("fit_six_face", "fit_model", "fit_multiposition"):
            original = getattr(static_procedure, name)
            self._saved[name] = original

            def timed(*args, _original=original, **kwargs):
                t0 = time.process_time()
                try:
                    return _original(*args, **kwargs)
                finally:
                    self.seconds += time.process_time() - t0
            setattr(static_procedure, name, timed)
        return self

    def __exit__(self, *exc):
        for name, original in self._saved.items():
            setattr(static_procedure, name, original)


def in_process(path: Path, settings: dict) -> tuple[float, float]:
    """(fit alone, whole analysis) CPU seconds for one recording already on disk (loaded first)."""
    rec = load_recording(path)
    with FitTimer() as fit:
        t0 = time.process_time()
        static_procedure.calibrate_static(rec, **settings)
        analysis = time.process_time() - t0
    return fit.seconds, analysis


def command(path: Path, flags: list[str]) -> tuple[float, float]:
    """(wall, CPU of the child) seconds of the whole command."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "accelrig", "calibrate", "static", str(path), "--json",
                           "--no-store", *flags], capture_output=True, text=True,
                          env={**os.environ, "CI": "1"})
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode != 0:
        raise SystemExit(f"the command failed on {path}: {done.stderr}")
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--recordings", type=int, default=5)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    rows = {name: {"fit": [], "analysis": [], "wall": [], "cpu": []} for name in METHODS}
    with tempfile.TemporaryDirectory() as directory:
        paths = recordings(Path(directory), args.recordings, args.seed)
        for path in paths:
            for _ in range(args.repeats):
                for name, flags in METHODS.items():
                    fit, analysis = in_process(path, SETTINGS[name])
                    wall, cpu = command(path, flags)
                    for key, value in zip(("fit", "analysis", "wall", "cpu"), (fit, analysis, wall, cpu), strict=True):
                        rows[name][key].append(value)
    print(f"## Static: the default against the paper's method, same recordings ({args.recordings} recordings x "
          f"{args.repeats} repeats, medians, ms; load average {os.getloadavg()[0]:.1f})\n")
    print("| method | fit alone (CPU) | analysis in process (CPU) | whole command (CPU) | whole command (wall) |")
    print("|---|---|---|---|---|")
    med = {name: {k: float(np.median(v)) * 1e3 for k, v in r.items()} for name, r in rows.items()}
    for name, m in med.items():
        print(f"| {name} | {m['fit']:.1f} | {m['analysis']:.0f} | {m['cpu']:.0f} | {m['wall']:.0f} |")
    default, paper = (rows[name] for name in METHODS)
    # paired: the two methods ran back to back on the same recording, so the load drifts out of each ratio
    ratio = {k: float(np.median(np.array(default[k]) / np.array(paper[k]))) for k in default}
    print(f"| default / paper (median of paired ratios) | {ratio['fit']:.2f} | {ratio['analysis']:.2f} | "
          f"{ratio['cpu']:.2f} | {ratio['wall']:.2f} |")


if __name__ == "__main__":
    main()
