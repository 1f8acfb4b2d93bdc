"""Slider-crank benchmark: sine fits against the CRB and the paper's method, radius against simulator truth.

Run: python tests/benchmarks/bench_slider_crank.py [--trials 1000] [--runs 30]

Table 1: records of N = 2048 samples at fs = 2048 Hz (the paper's), exact
slider-crank acceleration (r = 6.35 mm, lambda = 0.18) plus white noise
0.08 m/s^2, random crank phase.  For each speed:
  * ours: interpolated-DFT start, variable projection with 4 harmonics sharing
    the frequency (what the procedure runs);
  * one-sine 4-parameter fit by variable projection from the same start;
  * the paper's method: FFT arg-max start, Nelder-Mead (fminsearch) on the
    one-sine variable projection functional.
Frequency error in units of the exact CRB of the 4-harmonic model; converged
= reported converged and within 10 CRB of the truth (the global minimum).
The one-sine fits are biased by an amount that depends on the crank phase, so
their error is shown as an rms over the random phases.

Table 2: the whole procedure on simulated stands (clock 0.3 % off nominal,
20 us timestamp jitter), steps 2.5-11 Hz plus 12 and 13 Hz beyond the motor's
limit, radius error of the combined estimate against the effective radius.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # a shared 2-core box: BLAS threads only contend

import argparse  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402
from scipy.optimize import minimize  # noqa: E402

from accelrig.errors import DataError  # noqa: E402
from accelrig.estimation.sinefit import fit_sine, interpolated_dft_frequency, sine_crb  # noqa: E402
from accelrig.procedures.slider_crank.analysis import fft_peak_frequency  # noqa: E402
from accelrig.procedures.slider_crank.procedure import verify_slider_crank  # noqa: E402
from accelrig.sim import kinematics  # noqa: E402
from accelrig.sim.device import simulate  # noqa: E402
from accelrig.sim.rigs.slider_crank import SliderCrankRig, slider_position  # noqa: E402
from accelrig.sim.sensor import SensorModel, SimClock  # noqa: E402

FS, N, SIGMA = 2048.0, 2048, 0.08
RADIUS, ROD = 0.00635, 0.0353
T = np.arange(N) / FS
PAPER_TRIALS = 200


def acceleration(f, phase):
    def position(t):
        x = slider_position(2 * np.pi * f * t + phase, RADIUS, ROD)
        return np.column_stack([x, np.zeros_like(x), np.zeros_like(x)])

    return kinematics.acceleration(position, T)[:, 0]


def paper_method(y):
    """FFT arg-max start, Nelder-Mead on the one-sine VP functional (paper eq. 40-52, fminsearch)."""
    start = fft_peak_frequency(T, y)

    def cost(w):
        phi = np.column_stack([np.ones(N), np.cos(w[0] * T), np.sin(w[0] * T)])
        c, *_ = np.linalg.lstsq(phi, y, rcond=None)
        r = y - phi @ c
        return r @ r

    res = minimize(cost, [2 * np.pi * start], method="Nelder-Mead", options={"xatol": 1e-10, "fatol": 1e-12})
    return res.x[0] / (2 * np.pi), bool(res.success)


def table_fits(trials, rng):
    rows = [("1.0", lambda: 1.0), ("1.6", lambda: 1.6), ("2.5", lambda: 2.5),
            ("2.5-3.5", lambda: rng.uniform(2.5, 3.5))]
    rows += [(f"{f:g}", (lambda f=f: f)) for f in (4.3, 6.7, 8.5, 10.2, 12.0, 13.0)]
    print(f"### Sine fits: N = {N}, fs = {FS:g} Hz, noise {SIGMA} m/s^2, lambda = {RADIUS / ROD:.2f}, "
          f"{trials} records per row\n")
    print("| f / Hz | CRB sd(f) / Hz | ours: mean err / CRB | ours: sd / CRB | ours: stated u / CRB | ours: converged | "
          "ours: ms/fit | ours: iters | IpDFT max abs err / bin | 1-sine VP: rms err / CRB | "
          f"paper (FFT + Nelder-Mead, first {PAPER_TRIALS}): rms err / CRB | paper: reached its minimum | paper: ms/fit | "
          "FFT peak mean abs err / Hz |")
    print("|" + "---|" * 14)
    for label, draw in rows:
        ours, stated, conv, iters, ip, one, paper, paper_ok, fft_err, t_ours, t_paper = ([] for _ in range(11))
        refused = 0
        crbs = []
        for _ in range(trials):
            f = draw()
            phase = rng.uniform(-np.pi, np.pi)
            clean = acceleration(f, phase)
            y = clean + SIGMA * rng.standard_normal(N)
            try:
                t0 = time.perf_counter()
                fit = fit_sine(T, y, harmonics=4)
                t_ours.append(time.perf_counter() - t0)
            except DataError:
                refused += 1
                continue
            truth = fit_sine(T, clean, frequency=f, harmonics=4, fit_frequency=False)
            crb = sine_crb(T, f, truth.amplitude, truth.phase, SIGMA).frequency_sd
            crbs.append(crb)
            ours.append((fit.frequency - f) / crb)
            stated.append(fit.frequency_uncertainty / crb)
            conv.append(fit.converged and abs(fit.frequency - f) < 10 * crb)
            iters.append(fit.n_iterations)
            ip.append(abs(interpolated_dft_frequency(T, y) - f) * N / FS)
            one_sine = fit_sine(T, y, harmonics=1).frequency
            one.append((one_sine - f) / crb)
            if len(paper) < PAPER_TRIALS:  # Nelder-Mead is slow: a smaller sample says enough
                t0 = time.perf_counter()
                pf, ok = paper_method(y)
                t_paper.append(time.perf_counter() - t0)
                paper.append((pf - f) / crb)
                # it cannot beat the one-sine model it minimises: judge whether it found that minimum
                paper_ok.append(ok and abs(pf - one_sine) < 0.1 * crb)
            fft_err.append(abs(fft_peak_frequency(T, y) - f))
        if not ours:
            print(f"| {label} | - | refused: {refused}/{trials} records hold < 1.5 cycles (DataError) |" + " |" * 11)
            continue
        ours, one, paper = np.array(ours), np.array(one), np.array(paper)
        print(
            f"| {label} | {np.mean(crbs):.2e} | {ours.mean():+.2f} | {ours.std():.2f} | {np.mean(stated):.2f} | "
            f"{100 * np.mean(conv):.2f} % | {1e3 * np.mean(t_ours):.1f} | {np.mean(iters):.1f} | {np.max(ip):.3f} | "
            f"{np.sqrt(np.mean(one**2)):.1f} | {np.sqrt(np.mean(paper**2)):.1f} | "
            f"{100 * np.mean(paper_ok):.1f} % | {1e3 * np.mean(t_paper):.1f} | {np.mean(fft_err):.3f} |"
        )
    print()


def table_radius(runs):
    scenarios = [
        ("ideal stand", dict(clearance=0.0, backlash=0.0)),
        ("clearance 0.2 mm", dict(clearance=0.0002, backlash=0.0)),
        ("backlash 0.1 mm", dict(clearance=0.0, backlash=0.0001)),
        ("clearance 0.2 mm + backlash 0.1 mm", dict(clearance=0.0002, backlash=0.0001)),
    ]
    steps = [2.5, 3.5, 5.0, 6.5, 8.0, 9.5, 11.0, 12.0, 13.0]
    print(f"### Crank radius against simulator truth: {runs} stands per row, steps {steps} Hz "
          f"(motor limit 11.5 Hz), 1 s per step at {FS:g} Hz, noise {SIGMA} m/s^2\n")
    print("| scenario | mean error / um | sd error / um | mean stated u / um | rms(error / u) | verdict holds | "
          "backlash flagged (steps) | steps beyond limit flagged | steady steps wrongly flagged | roll-off / Hz | s/run |")
    print("|" + "---|" * 11)
    for name, opts in scenarios:
        err, u, z, holds, knock, limited_ok, false_limited, rolloff, secs = ([] for _ in range(9))
        for seed in range(runs):
            rng = np.random.default_rng(1000 + seed)
            offset = float(rng.uniform(-opts["clearance"], opts["clearance"])) if opts["clearance"] else 0.0
            rig = SliderCrankRig(steps=steps, radius_offset=offset, axis=np.array([1.0, rng.normal(0, 0.03), rng.normal(0, 0.03)]),
                                 **opts)
            sensor = SensorModel(range_g=8.0, noise_density=SensorModel.noise_density_for_sd(SIGMA, FS))
            rec = simulate(rig, sensor, SimClock(FS, 0.003, 20e-6), seed=seed)
            t0 = time.perf_counter()
            res = verify_slider_crank([("sim", rec)], RADIUS, ROD, clearance=opts["clearance"])
            secs.append(time.perf_counter() - t0)
            radius, v = res.parameters["radius"], res.details
            e = radius.value - rig.effective_radius
            err.append(e * 1e6)
            u.append(radius.uncertainty * 1e6)
            z.append(e / radius.uncertainty)
            holds.append(v["verdict"] == "holds")
            knock.append(np.mean([s["backlash"] for s in v["steps"]]))
            beyond = [s for s, c in zip(v["steps"], steps, strict=True) if c > rig.max_speed]
            below = [s for s, c in zip(v["steps"], steps, strict=True) if c <= rig.max_speed]
            limited_ok.append(np.mean([s["motor_limited"] for s in beyond]))
            false_limited.append(np.mean([s["motor_limited"] for s in below]))
            rolloff.append(v["rolloff_hz"] if v["rolloff_hz"] is not None else np.nan)
        print(
            f"| {name} | {np.mean(err):+.2f} | {np.std(err):.2f} | {np.mean(u):.2f} | {np.sqrt(np.mean(np.square(z))):.2f} | "
            f"{100 * np.mean(holds):.0f} % | {100 * np.mean(knock):.0f} % | {100 * np.mean(limited_ok):.0f} % | "
            f"{100 * np.mean(false_limited):.1f} % | {np.nanmean(rolloff):.2f} | {np.mean(secs):.2f} |"
        )
    print()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=1000, help="records per row of the sine-fit table")
    parser.add_argument("--runs", type=int, default=30, help="simulated stands per row of the radius table")
    parser.add_argument("--tables", default="fits,radius", help="which tables: fits, radius or both (default)")
    args = parser.parse_args()
    tables = set(args.tables.split(","))
    if "fits" in tables:
        table_fits(args.trials, np.random.default_rng(2026))
    if "radius" in tables:
        table_radius(args.runs)


if __name__ == "__main__":
    main()
