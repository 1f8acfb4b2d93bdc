"""Slider-crank per-step u against the exact value, under coloured noise (issue 18).

    python tests/benchmarks/bench_slider_noise.py [--runs 100] [--condition 1/f]

The stress benchmark's stand (stress_slider_crank.py: five 1-s steps at 2.5-10 Hz, 2048 Hz).  For each
kept step the stated u of the radius and of the mean speed is compared with the exact sd of the same
least-squares estimate under the simulator's true noise: g' J+ Sigma J+' g, J the step's crank-motion
Jacobian, Sigma the Toeplitz covariance of the sensor's noise (white, AR(1), and the flicker
model's relaxation processes, summed; accelrig.sim.sensor).  The exact value does not include the
timestamp jitter's share (20 us at the 10 Hz step's jerk adds about a tenth of the noise variance), so
u/exact a little above 1 at the fast steps is expected.  Coverage: |error| <= k u against the
simulator's truth, k the coverage factor the tool states for that step and quantity (t on the effective
dof of u^2, 2 at large dof; ``radius_k``, ``frequency_k``).  Prints per condition and step: median u/exact
with its 10-90 % range, coverage, and the median k stated for the radius.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from scipy.linalg import toeplitz

sys.path.insert(0, str(Path(__file__).resolve().parent))

from stress_slider_crank import RADIUS, ROD, simulate_stand  # noqa: E402

from accelrig.procedures.slider_crank.procedure import SliderCrankProcedure  # noqa: E402

CONDITIONS = {
    "white": {},
    "AR(1) rho 0.9": {"ar1": 0.9},
    "1/f (0.01 at 1 Hz)": {"flicker": 0.01},
    "1/f^0.5 (held out)": {"flicker": 0.01, "flicker_slope": 0.5},
    "1/f^1.5 (held out)": {"flicker": 0.01, "flicker_slope": 1.5},
}


def noise_autocovariance(sensor, rate: float, n: int) -> np.ndarray:
    """The true autocovariance of one axis of the simulated sensor's noise, lags 0..n-1."""
    k = np.arange(n)
    white = sensor.noise_sd(rate) ** 2
    gamma = white * (sensor.ar1**k if sensor.ar1 else (k == 0).astype(float))
    if sensor.flicker > 0:
        for corner in sensor._flicker_corners(rate):
            gamma = gamma + sensor.flicker_variance(corner) * np.exp(-2 * np.pi * corner / rate) ** k
    return gamma


def one_run(seed: int, sensor_options: dict):
    """Per kept step: (place, u/exact radius, u/exact speed, radius covered, speed covered, k radius)."""
    rig, sensor, rec = simulate_stand(seed, sensor_options=sensor_options)
    rate = float(rec.meta.get("delivered_rate", rec.meta.get("nominal_rate")))
    values = {"crank_radius": RADIUS, "rod_length": ROD, "clearance": 0.0, "speeds": None,
              "harmonics": 4, "profile": None}
    procedure = SliderCrankProcedure(values, {})
    procedure.open_source("sim", rec.meta)
    procedure.feed(rec.to_si())
    procedure.finish()
    procedure.result()
    rows = []
    for place, step in enumerate(procedure.steps):
        if step.motor_limited or step.state is None:
            continue
        motion = step.state.motion
        pinv = np.linalg.pinv(motion.jacobian)
        sigma = toeplitz(noise_autocovariance(sensor, rate, step.n_samples))
        _, g_radius = motion.radius_gradient()
        _, g_speed = motion.mean_frequency_gradient()
        exact = [float(np.sqrt(a @ sigma @ a)) for a in (g_radius @ pinv, g_speed @ pinv)]
        t = rec.t[rec.channels["step"] == step.index]
        phi = rig.crank_angle(t[[0, -1]])[0]
        f_true = (phi[1] - phi[0]) / (2 * np.pi * (t[-1] - t[0]))
        rows.append((place, step.radius_m.uncertainty / exact[0], step.frequency_hz.uncertainty / exact[1],
                     abs(step.radius_m.value - rig.effective_radius) <= step.radius_k * step.radius_m.uncertainty,
                     abs(step.frequency_hz.value - f_true) <= step.frequency_k * step.frequency_hz.uncertainty,
                     step.radius_k))
    return rows


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=100)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--condition", help="only conditions whose name contains this")
    args = parser.parse_args(argv)
    print("| condition | step | runs | u/exact radius (10-90 %) | u/exact speed (10-90 %) | cover radius | cover speed "
          "| k radius (10-90 %) |")
    print("|---|---|---|---|---|---|---|---|")
    for name, options in CONDITIONS.items():
        if args.condition and args.condition not in name:
            continue
        rows = [row for i in range(args.runs) for row in one_run(args.seed * 100003 + i, options)]
        for place in sorted({r[0] for r in rows}):
            mine = np.array([r[1:] for r in rows if r[0] == place], dtype=float)
            q = np.percentile(mine[:, :2], [10, 50, 90], axis=0)
            print(f"| {name} | {place + 1} | {mine.shape[0]} | {q[1, 0]:.2f} ({q[0, 0]:.2f}-{q[2, 0]:.2f}) | "
                  f"{q[1, 1]:.2f} ({q[0, 1]:.2f}-{q[2, 1]:.2f}) | {100 * mine[:, 2].mean():.0f} % | "
                  f"{100 * mine[:, 3].mean():.0f} % | {np.median(mine[:, 4]):.2f} "
                  f"({np.percentile(mine[:, 4], 10):.2f}-{np.percentile(mine[:, 4], 90):.2f}) |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
