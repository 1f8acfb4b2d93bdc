"""Tilted-wheel benchmark: paper 002's Table I, our four steps, our joint fit, the CRB.

    python tests/benchmarks/bench_wheel.py            # 60 noise realisations per noise level
    python tests/benchmarks/bench_wheel.py --runs 10  # quicker
    python tests/benchmarks/bench_wheel.py --lengths 90,900,3600   # time and peak memory by record length

Truth: Table I of the paper.  The paper gives neither the radius nor the
duration of its synthetic runs; ours: r = 0.28 m (its real bench), 200 Hz,
90 s (18,000 samples), a +-4 g sensor (quantisation sd 0.35 mm/s^2, far below
the noise), no clock error.  Each realisation is a fresh noise draw through
accelrig.sim (seeds 0..N-1 at 0.08 m/s^2, 1000.. at 0.2, 2000.. for the non-cubic
friction, so the tables are independent draws).  Prints Markdown tables.
"""

from __future__ import annotations

import argparse
import gc
import json
import os
import subprocess
import sys
import time
import tracemalloc

# One core, as stated in the timing table (BLAS threads would blur CPU time on a shared machine).
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np  # noqa: E402

from accelrig.procedures.wheel.checks import check_capture, survey
from accelrig.procedures.wheel.fit import free_set, reported_names, reported_values, wheel_crb
from accelrig.procedures.wheel.model import (
    TABLE_I_GAIN,
    TABLE_I_MISALIGNMENT_DEG,
    TABLE_I_OFFSET,
    TABLE_I_OMEGA,
    TABLE_I_THETA0_DEG,
    TABLE_I_TILT_DEG,
    WheelState,
    rotation_from_euler,
)
from accelrig.procedures.wheel.paper import paper_calibrate
from accelrig.procedures.wheel.procedure import calibrate_wheel
from accelrig.sim.device import simulate
from accelrig.sim.rigs.wheel import WheelRig
from accelrig.sim.sensor import SensorModel, SimClock

RADIUS = 0.28
RATE = 200.0
SECONDS = 90.0

# Paper 002, Table I: "estimated (+- sigma)" at sigma_n = 0.08 and 0.2 m/s^2, in its display units.
PAPER_TABLE_I = {
    0.08: {"omega3": "2.000 ± .002", "omega2": "500.0 ± 0.3", "omega1": "-90.00 ± 0.01", "omega0": "9.000 ± .0001",
           "theta0": "29.99 ± 0.03", "tilt": "45.00 ± 0.01", "misalignment_theta": "29.99 ± 0.03",
           "misalignment_phi": "19.99 ± 0.02", "misalignment_psi": "25.00 ± 0.08", "gain_x": "0.8999 ± .0001",
           "gain_y": "1.0000 ± .0004", "gain_z": "1.1005 ± .0007", "offset_x": "1.001 ± 0.005",
           "offset_y": "-1.001 ± .014", "offset_z": "0.996 ± 0.009"},
    0.2: {"omega3": "2.000 ± .004", "omega2": "499.9 ± 0.5", "omega1": "-90.00 ± 0.02", "omega0": "9.000 ± .0002",
          "theta0": "29.94 ± 0.07", "tilt": "45.01 ± 0.03", "misalignment_theta": "29.93 ± 0.07",
          "misalignment_phi": "19.97 ± 0.03", "misalignment_psi": "25.04 ± 0.16", "gain_x": "0.8998 ± .0003",
          "gain_y": "0.9999 ± .0009", "gain_z": "1.1026 ± .0017", "offset_x": "1.006 ± 0.010",
          "offset_y": "-1.008 ± .027", "offset_z": "1.006 ± 0.019"},
}
# display unit: (label, factor from SI)
DISPLAY = {
    "theta0": ("deg", np.rad2deg(1.0)), "omega0": ("rad/s", 1.0), "omega1": ("mrad/s^2", 1e3),
    "omega2": ("urad/s^3", 1e6), "omega3": ("urad/s^4", 1e6), "tilt": ("deg", np.rad2deg(1.0)),
    "misalignment_theta": ("deg", np.rad2deg(1.0)), "misalignment_phi": ("deg", np.rad2deg(1.0)),
    "misalignment_psi": ("deg", np.rad2deg(1.0)),
}
ORDER = ["omega3", "omega2", "omega1", "omega0", "theta0", "tilt", "misalignment_theta", "misalignment_phi",
         "misalignment_psi", "gain_x", "gain_y", "gain_z", "offset_x", "offset_y", "offset_z"]
CUBIC_SPEED_SD: list[float] = []  # half-turn speed residual sd of the cubic runs at 0.08, for comparison
ANGLES = {"theta0", "misalignment_theta", "misalignment_phi", "misalignment_psi"}


def truth_state() -> WheelState:
    return WheelState(np.deg2rad(TABLE_I_THETA0_DEG), TABLE_I_OMEGA, np.deg2rad(TABLE_I_TILT_DEG), RADIUS,
                      rotation_from_euler(np.deg2rad(TABLE_I_MISALIGNMENT_DEG)), TABLE_I_GAIN, TABLE_I_OFFSET)


def make_recording(noise: float, seed: int, friction: str = "cubic"):
    rig = WheelRig(radius=RADIUS, tilt_deg=TABLE_I_TILT_DEG, duration=SECONDS, omega=TABLE_I_OMEGA,
                   friction=friction, misalignment_deg=TABLE_I_MISALIGNMENT_DEG, theta0_deg=TABLE_I_THETA0_DEG)
    sensor = SensorModel(offset=TABLE_I_OFFSET, gain=TABLE_I_GAIN, range_g=4.0,
                         noise_density=SensorModel.noise_density_for_sd(noise, RATE))
    return simulate(rig, sensor, SimClock(RATE), seconds=SECONDS, seed=seed)


def run_paper(rec):
    """The four steps alone (capture survey and checks included), timed (wall, CPU)."""
    start, cpu = time.perf_counter(), time.process_time()
    t = rec.t - rec.t[0]
    look = survey(t, rec.acc, rec.meta)
    check_capture(look, RADIUS)
    state = paper_calibrate(t, rec.acc, look, RADIUS, None).state
    return state, (time.perf_counter() - start, time.process_time() - cpu)


def run_joint(rec):
    start, cpu = time.perf_counter(), time.process_time()
    result = calibrate_wheel(rec, radius=RADIUS, method="joint")
    elapsed = (time.perf_counter() - start, time.process_time() - cpu)
    idx = {n: i for i, n in enumerate(result.parameter_names)}
    u = np.sqrt(np.diag(result.covariance))
    return result, elapsed, u, idx


def state_from_result(result) -> np.ndarray:
    p = result.parameters
    values = {"theta0": np.deg2rad(p["theta0_deg"].value), "tilt": np.deg2rad(p["tilt_deg"].value)}
    for k in range(4):
        values[f"omega{k}"] = p[f"omega{k}"].value
    for name, v in zip(("misalignment_theta", "misalignment_phi", "misalignment_psi"), p["misalignment_deg"].value, strict=True):
        values[name] = np.deg2rad(v)
    for axis, g, o in zip("xyz", p["gain"].value, p["offset"].value, strict=True):
        values[f"gain_{axis}"], values[f"offset_{axis}"] = g, o
    return values


def errors(values: np.ndarray, truth: np.ndarray, names: list[str]) -> np.ndarray:
    err = values - truth
    for i, n in enumerate(names):
        if n in ANGLES:
            err[..., i] = np.angle(np.exp(1j * err[..., i]))
    return err


def fmt(x: float, digits: int = 3) -> str:
    return f"{x:.{digits}g}"


def benchmark_noise(noise: float, runs: int, first_seed: int):
    free = free_set(RADIUS, None)
    names = reported_names(free)
    truth = truth_state()
    truth_vec = reported_values(truth, free)
    t = np.arange(int(SECONDS * RATE)) / RATE
    crb_sd = np.sqrt(np.diag(wheel_crb(t, truth, free, noise)))
    paper_est, joint_est, joint_u = [], [], []
    paper_times, joint_times = [], []
    for seed in range(first_seed, first_seed + runs):
        rec = make_recording(noise, seed)
        state, tp = run_paper(rec)
        paper_est.append(reported_values(state, free))
        paper_times.append(tp)
        result, tj, u, idx = run_joint(rec)
        v = state_from_result(result)
        joint_est.append([v[n] for n in names])
        joint_u.append([u[idx[n]] for n in names])
        joint_times.append(tj)
        if noise == 0.08:
            CUBIC_SPEED_SD.append(result.quality["speed_residual_sd"])
    paper_err = errors(np.array(paper_est), truth_vec, names)
    joint_err = errors(np.array(joint_est), truth_vec, names)
    joint_u = np.array(joint_u)
    if CUBIC_SPEED_SD:
        CUBIC_SPEED_SD[:] = [float(np.mean(CUBIC_SPEED_SD))]
    return names, truth_vec, crb_sd, paper_err, joint_err, joint_u, np.array(paper_times), np.array(joint_times)


def print_table(noise, runs, names, truth_vec, crb_sd, paper_err, joint_err, joint_u):
    print(f"\n### sigma_n = {noise} m/s^2, {runs} noise realisations, r = {RADIUS} m, {RATE:g} Hz, {SECONDS:g} s\n")
    print("| parameter | unit | true | paper Table I (mean ± sd) | our paper sd | our joint sd | CRB | joint sd / CRB "
          "| paper mean err | joint mean err | joint mean err / sd | joint ±2u coverage |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    idx = {n: i for i, n in enumerate(names)}
    within = np.abs(joint_err) <= 2 * joint_u
    for name in ORDER:
        i = idx[name]
        unit, f = DISPLAY.get(name, ("m/s^2" if name.startswith("offset") else "1", 1.0))
        sd_p = paper_err[:, i].std(ddof=1)
        sd_j = joint_err[:, i].std(ddof=1)
        print(f"| {name} | {unit} | {fmt(truth_vec[i] * f, 4)} | {PAPER_TABLE_I[noise][name]} | {fmt(sd_p * f)} "
              f"| {fmt(sd_j * f)} | {fmt(crb_sd[i] * f)} | {sd_j / crb_sd[i]:.2f} | {fmt(paper_err[:, i].mean() * f)} "
              f"| {fmt(joint_err[:, i].mean() * f)} | {joint_err[:, i].mean() / sd_j:+.2f} "
              f"| {100 * within[:, i].mean():.0f} % |")
    ratio = joint_err.std(axis=0, ddof=1) / crb_sd
    print(f"\nmax joint sd / CRB {ratio.max():.2f}; max |joint mean err| / sd "
          f"{np.max(np.abs(joint_err.mean(axis=0)) / joint_err.std(axis=0, ddof=1)):.2f}; "
          f"pooled ±2u coverage {100 * within.mean():.1f} % ({within.size} intervals); "
          f"paper-method sd / CRB from {np.min(paper_err.std(axis=0, ddof=1) / crb_sd):.1f} "
          f"to {np.max(paper_err.std(axis=0, ddof=1) / crb_sd):.1f}")


def benchmark_friction(runs: int, noise: float = 0.08):
    """Bias of each method when the wheel's friction is coulomb + viscous (no cubic is exact)."""
    free = free_set(RADIUS, None)
    names = reported_names(free)
    sensor_names = ["tilt", "misalignment_theta", "misalignment_phi", "misalignment_psi",
                    "gain_x", "gain_y", "gain_z", "offset_x", "offset_y", "offset_z"]
    truth_vec = reported_values(truth_state(), free)
    paper_est, joint_est, joint_u, speed_sd, rms = [], [], [], [], []
    for seed in range(runs):
        rec = make_recording(noise, 2000 + seed, friction="coulomb-viscous")
        state, _ = run_paper(rec)
        paper_est.append(reported_values(state, free))
        result, _, u, idx = run_joint(rec)
        speed_sd.append(result.quality["speed_residual_sd"])
        rms.append(result.quality["residual_rms"])
        v = state_from_result(result)
        joint_est.append([v[n] for n in names])
        joint_u.append([u[idx[n]] for n in names])
    paper_err = errors(np.array(paper_est), truth_vec, names)
    joint_err = errors(np.array(joint_est), truth_vec, names)
    joint_u = np.median(np.array(joint_u), axis=0)
    rig = WheelRig(friction="coulomb-viscous", omega=TABLE_I_OMEGA)
    speeds = rig.motion(np.array([0.0, SECONDS]))[1]
    print(f"\n### Non-cubic friction: coulomb {rig.coulomb} rad/s^2 + viscous {rig.viscous} 1/s "
          f"(speed {speeds[0]:.2f} -> {speeds[1]:.2f} rad/s over {SECONDS:g} s), sigma_n = {noise}, {runs} realisations\n")
    print("| parameter | unit | paper mean err | paper sd | joint mean err | joint sd | joint median u | joint bias / u |")
    print("|---|---|---|---|---|---|---|---|")
    idx = {n: i for i, n in enumerate(names)}
    for name in sensor_names:
        i = idx[name]
        unit, f = DISPLAY.get(name, ("m/s^2" if name.startswith("offset") else "1", 1.0))
        print(f"| {name} | {unit} | {fmt(paper_err[:, i].mean() * f)} | {fmt(paper_err[:, i].std(ddof=1) * f)} "
              f"| {fmt(joint_err[:, i].mean() * f)} | {fmt(joint_err[:, i].std(ddof=1) * f)} | {fmt(joint_u[i] * f)} "
              f"| {joint_err[:, i].mean() / joint_u[i]:+.1f} |")
    print(f"\nWhat the operator sees: joint residual rms {np.mean(rms):.4f} m/s^2 (noise {noise}), "
          f"half-turn speed residual sd about the cubic {np.mean(speed_sd) * 1e3:.1f} mrad/s "
          f"(cubic friction: {CUBIC_SPEED_SD[0] * 1e3:.1f} mrad/s)")


def long_recording(seconds: float, seed: int = 0):
    """Table I's coast-down stretched over ``seconds`` (as ``accelrig plan wheel`` does), from 6 rad/s."""
    stretch = 90.0 / seconds
    omega = TABLE_I_OMEGA * (6.0 / 9.0) * stretch ** np.arange(4)
    rig = WheelRig(radius=RADIUS, tilt_deg=TABLE_I_TILT_DEG, duration=seconds, omega=omega,
                   misalignment_deg=TABLE_I_MISALIGNMENT_DEG, theta0_deg=TABLE_I_THETA0_DEG)
    sensor = SensorModel(offset=TABLE_I_OFFSET, gain=TABLE_I_GAIN, range_g=4.0,
                         noise_density=SensorModel.noise_density_for_sd(0.08, RATE))
    return simulate(rig, sensor, SimClock(RATE), seconds=seconds, seed=seed)


def _rss_mb() -> tuple[float, float]:
    """(resident MB now, peak resident MB since the last reset) of this process (Linux /proc)."""
    fields = {}
    with open("/proc/self/status") as status:
        for line in status:
            if line.startswith(("VmRSS", "VmHWM")):
                name, value = line.split(":")
                fields[name] = int(value.split()[0]) / 1024
    return fields.get("VmRSS", float("nan")), fields.get("VmHWM", float("nan"))


def _reset_peak_rss() -> None:
    """Start the peak resident size afresh (Linux: writing 5 to clear_refs resets VmHWM)."""
    try:
        with open("/proc/self/clear_refs", "w") as refs:
            refs.write("5")
    except OSError:
        pass


def one_length(seconds: float, method: str, memory: bool = True) -> dict:
    """Whole command path (calibrate_wheel) on one record: CPU, wall and the peak resident size above what
    the process held with the recording loaded, then peak traced memory in a second run."""
    rec = long_recording(seconds)
    gc.collect()
    _reset_peak_rss()
    rss_before, _ = _rss_mb()

    def run():
        if method == "four-steps":        # the paper's steps alone, no uncertainties (run_paper)
            return run_paper(rec)[0].gain, [float("nan")] * 3
        result = calibrate_wheel(rec, radius=RADIUS, method=method, bootstrap=5)
        return result.parameters["gain"].value, result.parameters["gain"].uncertainty

    start, cpu = time.perf_counter(), time.process_time()
    gain, u_gain = run()
    out = {"seconds": seconds, "samples": int(rec.t.size), "method": method,
           "cpu_s": time.process_time() - cpu, "wall_s": time.perf_counter() - start,
           "gain": list(map(float, gain)), "u_gain": list(map(float, u_gain)),
           "rss_peak_mb": _rss_mb()[1] - rss_before}
    out["peak_mb"] = float("nan")
    if memory:
        tracemalloc.start()
        run()
        out["peak_mb"] = tracemalloc.get_traced_memory()[1] / 1e6
        tracemalloc.stop()
    out["data_mb"] = (rec.t.nbytes + rec.acc.nbytes) / 1e6
    return out


def benchmark_lengths(lengths: list[float], methods: list[str], memory_methods: list[str]) -> None:
    """Each length and method in a fresh process (memory and caches of one do not blur the next)."""
    print("\n### Time and peak memory by record length (200 Hz, noise 0.08 m/s^2, one thread; "
          "whole calibrate_wheel: checks, start, fit, uncertainties)\n")
    print("| record | samples | method | CPU s | wall s | peak traced memory MB | peak RSS above the data MB "
          "| data MB | gain u (x, y, z) |")
    print("|---|---|---|---|---|---|---|---|---|")
    for seconds in lengths:
        for method in methods:
            command = [sys.executable, __file__, "--one-length", str(seconds), "--method", method]
            if method not in memory_methods:
                command.append("--no-memory")
            proc = subprocess.run(command, capture_output=True, text=True, check=False)
            if proc.returncode != 0:
                print(f"| {seconds:g} s | - | {method} | failed: {proc.stderr.strip().splitlines()[-1:]} |")
                continue
            r = json.loads(proc.stdout.strip().splitlines()[-1])
            peak = "-" if np.isnan(r["peak_mb"]) else f"{r['peak_mb']:.0f}"
            print(f"| {seconds:g} s | {r['samples']} | {method} | {r['cpu_s']:.1f} | {r['wall_s']:.1f} "
                  f"| {peak} | {r['rss_peak_mb']:.0f} | {r['data_mb']:.0f} | {' '.join(f'{u:.2g}' for u in r['u_gain'])} |",
                  flush=True)
    print("\njoint: the default method, whole (capture checks, closed-form start, chunked fit, residual checks, "
          "covariance); four-steps: the paper's steps A-D alone (capture checks included, no uncertainties); "
          "paper: --method paper, whose uncertainties are a parametric bootstrap (5 runs here, 20 by default).")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=60, help="noise realisations per noise level (default 60)")
    parser.add_argument("--friction-runs", type=int, default=20, help="realisations with non-cubic friction")
    parser.add_argument("--lengths", help="comma-separated record lengths, s: only the time and memory table")
    parser.add_argument("--methods", default="joint,four-steps",
                        help="for --lengths: joint, four-steps (the paper's steps alone) and/or paper "
                             "(the paper method with a 5-run bootstrap); default joint,four-steps")
    parser.add_argument("--memory-methods", default="joint,four-steps,paper",
                        help="for --lengths: methods whose peak memory is measured (a second, traced run)")
    parser.add_argument("--no-memory", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--one-length", type=float, help=argparse.SUPPRESS)
    parser.add_argument("--method", default="joint", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.one_length:
        print(json.dumps(one_length(args.one_length, args.method, memory=not args.no_memory)))
        return
    if args.lengths:
        benchmark_lengths([float(x) for x in args.lengths.split(",")], args.methods.split(","),
                          args.memory_methods.split(","))
        return
    print("## Tilted wheel (paper 002): Table I reproduced, four steps vs joint ML vs CRB")
    timing = []
    CUBIC_SPEED_SD.clear()
    for noise, first_seed in ((0.08, 0), (0.2, 1000)):
        names, truth_vec, crb_sd, paper_err, joint_err, joint_u, tp, tj = benchmark_noise(noise, args.runs, first_seed)
        print_table(noise, args.runs, names, truth_vec, crb_sd, paper_err, joint_err, joint_u)
        timing.append((noise, tp, tj))
    print("\n### Time per calibration of one 18,000-sample recording (one thread; CPU time, and wall time on this shared machine)\n")
    print("| sigma_n | paper four steps: CPU median (max) | wall median | joint (four-step start + ML refinement + covariance): CPU median (max) | wall median |")
    print("|---|---|---|---|---|")
    for noise, tp, tj in timing:
        print(f"| {noise} | {np.median(tp[:, 1]):.2f} s ({tp[:, 1].max():.2f} s) | {np.median(tp[:, 0]):.2f} s "
              f"| {np.median(tj[:, 1]):.2f} s ({tj[:, 1].max():.2f} s) | {np.median(tj[:, 0]):.2f} s |")
    if args.friction_runs > 0:
        benchmark_friction(args.friction_runs)


if __name__ == "__main__":
    main()
