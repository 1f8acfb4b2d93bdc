"""Noise figures against the datasheet densities (REFERENCES.md) on simulated still recordings.

A simulated MPU-9250 (300 ug/sqrt(Hz)) and ICM-20948 (230 ug/sqrt(Hz)) lie
still for a few record lengths; ``accelrig noise``'s estimator
(accelrig.estimation.allan.noise_figures) must recover the density.  For each
case: the mean estimate over runs and axes, its error, the spread of the
estimates against the stated uncertainty (sd / mean stated u close to 1 means
the uncertainty is honest), and the time per recording.

    python tests/benchmarks/bench_noise.py [--runs N]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from accelrig.estimation.allan import noise_figures
from accelrig.geometry import AXES
from accelrig.sim.device import simulate
from accelrig.sim.rigs.still import StillRig
from accelrig.sim.sensor import SensorModel, SimClock
from accelrig.units import STANDARD_GRAVITY

UG = 1e6 / STANDARD_GRAVITY
CHIPS = [("MPU-9250", 300.0), ("ICM-20948", 230.0)]
CASES = [(200.0, 60.0), (200.0, 600.0), (1000.0, 600.0)]   # (rate Hz, seconds)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=10, help="simulated recordings per case (default 10)")
    args = parser.parse_args()

    print("| chip | datasheet ug/sqrt(Hz) | rate Hz | record s | runs x axes | mean estimate ug/sqrt(Hz) "
          "| error % | max abs error % | sd / stated u | s per recording |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for chip, density_ug in CHIPS:
        for rate, seconds in CASES:
            estimates, stated, times = [], [], []
            for run in range(args.runs):
                sensor = SensorModel.random(np.random.default_rng(run), noise_density=density_ug * 1e-6 * STANDARD_GRAVITY)
                rec = simulate(StillRig(up=["+z", "-x", "+y"][run % 3]), sensor,
                               SimClock(rate, 0.004, 20e-6), seconds=seconds, seed=1000 + run + 100 * int(density_ug))
                t0 = time.perf_counter()
                report = noise_figures(rec)
                times.append(time.perf_counter() - t0)
                for axis in AXES:
                    d = report.axes[axis].density
                    estimates.append(d.value * UG)
                    stated.append(d.uncertainty * UG)
            est = np.asarray(estimates)
            err = est / density_ug - 1.0
            print(f"| {chip} | {density_ug:.0f} | {rate:.0f} | {seconds:.0f} | {args.runs} x 3 | {est.mean():.2f} "
                  f"| {100 * err.mean():+.2f} | {100 * np.max(np.abs(err)):.2f} | "
                  f"{est.std(ddof=1) / np.mean(stated):.2f} | {np.mean(times):.3f} |")
    print()
    print("density one-sided (datasheet convention): sigma(tau) = N / sqrt(2 tau); per-sample sd = N sqrt(rate / 2).")
    print("sd / stated u: spread of the estimates over the mean stated standard uncertainty "
          "(the stated u is that of the best single Allan point, so it is conservative: expect <= 1).")


if __name__ == "__main__":
    main()
