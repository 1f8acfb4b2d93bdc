"""Rotary bench (paper 001) against simulator truth: sampling rate, sensitivity, coverage.

    python tests/benchmarks/bench_rotary.py [--runs N] [--seconds S]

Each run: an LSM6DSR-like sensor at +-8 g (sensitivity near 423 counts per
m/s^2, noise 0.03 m/s^2 per sample), its clock 0.2-0.5 % off the nominal
1660 Hz, a test of the paper's plan (5 Hz 34/20 deg, 8 Hz 13/6 deg peak to
peak) with a random motor phase, the encoder log at 1 kHz on the accurate
clock.  The true radius of each mounting is drawn around the nominal 170 mm
with the stated 0.5 mm, so the reference part of the budget is exercised
too.  Both rate methods analyse the same data in the same process.
Prints Markdown tables.
"""

from __future__ import annotations

import os

# The estimators are tall-skinny QRs: OpenBLAS threads only fight each other on a shared 2-core box.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

from accelrig.estimation.sinefit import sine_crb  # noqa: E402
from accelrig.procedures.rotary.bench import EncoderLog, RotarySetup, analyse_test  # noqa: E402
from accelrig.procedures.rotary.campaign import Campaign, CampaignTest, analyse_campaign  # noqa: E402
from accelrig.procedures.rotary.settings import PAPER_PLAN  # noqa: E402
from accelrig.sim.campaign import paper_sensor  # noqa: E402
from accelrig.sim.device import simulate  # noqa: E402
from accelrig.sim.rigs.rotary import (  # noqa: E402
    PAPER_ORIENTATIONS,
    RotaryRig,
    encoder_samples,
    true_sensitivity,
)
from accelrig.sim.sensor import SimClock  # noqa: E402

NOMINAL_RATE = 1660.0
RADIUS = 0.170
RADIUS_SD = 0.0005
NOISE_SD = 0.03
U_RADIUS = RotarySetup().radius_uncertainty / RotarySetup().radius
U_GEOMETRY = RotarySetup().geometry_uncertainty


def one_run(rng: np.random.Generator, seconds: float) -> dict:
    frequency, amplitude = PAPER_PLAN[rng.integers(len(PAPER_PLAN))]
    sensor = paper_sensor(rng, noise_sd=NOISE_SD, rate=NOMINAL_RATE)
    clock = SimClock(NOMINAL_RATE, float(rng.uniform(0.002, 0.005)) * rng.choice([-1, 1]), 0.0)
    r_true = RADIUS + rng.normal(0.0, RADIUS_SD)
    rig = RotaryRig(radius=r_true, frequency=frequency, amplitude_deg=amplitude, duration=seconds,
                    phase=float(rng.uniform(-np.pi, np.pi)))
    rec = simulate(rig, sensor, clock, seconds=seconds, seed=int(rng.integers(2**31)), units="counts")
    truth = true_sensitivity(rec.meta["truth"])
    rec.t = np.arange(len(rec)) / NOMINAL_RATE  # the MEMS's own timestamps are not trusted
    enc = EncoderLog(**encoder_samples(rig, seconds, 1000.0))
    out = {"true_rate": clock.true_rate, "truth": truth, "frequency": frequency, "amplitude": amplitude,
           "radius_ratio": r_true / RADIUS, "n": len(rec)}
    cpu = {"fit": [], "scan": []}
    for _ in range(TIMING_REPEATS):   # alternating, CPU time: a shared box's load hits both alike
        for method in ("fit", "scan"):
            t0 = time.process_time()
            res = analyse_test(rec, enc, "x", "y", NOMINAL_RATE, rate_method=method)
            cpu[method].append(time.process_time() - t0)
            out[method] = {"seconds": min(cpu[method]), "rate": res.sample_rate.value,
                           "rate_u": res.sample_rate.uncertainty, "sens": res.sensitivity}
    out["rate_stage"] = rate_stage_times(rec, frequency)
    # CRB of the rate from the tangential axis alone (cycles per sample -> Hz)
    nu = frequency / clock.true_rate
    amp = truth["x"] * rig.tangential_amplitude
    crb = sine_crb(np.arange(len(rec)), nu, amp, 0.0, sensor.noise_sd(clock.true_rate) / sensor.scale)
    out["rate_crb"] = clock.true_rate * crb.frequency_sd / nu
    return out


TIMING_REPEATS = 3


def rate_stage_times(rec, frequency: float) -> dict:
    """CPU seconds of the rate stage alone (min of TIMING_REPEATS): the fit (the sample-index sine fit and
    its noise check) against the paper's scan (filter, whole periods, scan, refilter), on the same samples."""
    from accelrig.procedures.rotary.bench import (
        filter_and_trim,
        sample_rate_by_fit,
        sample_rate_by_scan,
    )

    y = rec.acc[:, 0]
    nu_start = frequency / NOMINAL_RATE   # the same start for both
    out = {"fit": [], "scan": []}
    for _ in range(TIMING_REPEATS):
        t0 = time.process_time()
        sample_rate_by_fit(y, nu_start, frequency, 1e-6)
        out["fit"].append(time.process_time() - t0)
        t0 = time.process_time()
        sos, filtered, seg, _ = filter_and_trim(rec.acc, 0, frequency, NOMINAL_RATE, 40.0, NOMINAL_RATE, "bench")
        sample_rate_by_scan(rec.acc, filtered, seg, 0, frequency, NOMINAL_RATE, sos, 40.0)
        out["scan"].append(time.process_time() - t0)
    return {k: min(v) for k, v in out.items()}


def command_times(rng: np.random.Generator, seconds: float, directory) -> dict:
    """Whole command, ``accelrig calibrate rotary --mems M.csv --encoder E.csv``, in this process: CPU seconds
    per method (min of TIMING_REPEATS), CSV parsing included."""
    import contextlib
    import io

    from accelrig.cli import main as cli_main
    from accelrig.recording import write_csv
    from accelrig.sim.rigs.rotary import write_encoder_csv

    frequency, amplitude = PAPER_PLAN[0]
    sensor = paper_sensor(rng, noise_sd=NOISE_SD, rate=NOMINAL_RATE)
    clock = SimClock(NOMINAL_RATE, 0.003, 0.0)
    rig = RotaryRig(radius=RADIUS, frequency=frequency, amplitude_deg=amplitude, duration=seconds)
    rec = simulate(rig, sensor, clock, seconds=seconds, seed=int(rng.integers(2**31)), units="counts")
    rec.channels = {}
    mems, encoder = directory / "mems.csv", directory / "encoder.csv"
    write_csv(rec, mems)
    write_encoder_csv(encoder, encoder_samples(rig, seconds, 1000.0))
    out = {"fit": [], "scan": []}
    for _ in range(TIMING_REPEATS):
        for method in ("fit", "scan"):
            t0 = time.process_time()
            with contextlib.redirect_stdout(io.StringIO()):
                code = cli_main(["calibrate", "rotary", "--mems", str(mems), "--encoder", str(encoder), "--radius",
                                 str(RADIUS), "--tangential", "x", "--radial", "y", "--nominal-rate",
                                 str(NOMINAL_RATE), "--rate-method", method, "--json"])
            out[method].append(time.process_time() - t0)
            assert code == 0
    return {k: min(v) for k, v in out.items()}


def one_campaign(rng: np.random.Generator, seconds: float, repeats: int = 2) -> dict:
    """One sensor, the paper's three supports (each mounting its own true radius), the plan, repeats."""
    sensor = paper_sensor(rng, noise_sd=NOISE_SD, rate=NOMINAL_RATE)
    clock = SimClock(NOMINAL_RATE, float(rng.uniform(0.002, 0.005)), 0.0)
    tests, results, truth = [], [], None
    for tangential, radial in PAPER_ORIENTATIONS:
        r_true = RADIUS + rng.normal(0.0, RADIUS_SD)
        for frequency, amplitude in PAPER_PLAN:
            for _ in range(repeats):
                rig = RotaryRig(radius=r_true, frequency=frequency, amplitude_deg=amplitude, tangential=tangential,
                                radial=radial, duration=seconds, phase=float(rng.uniform(-np.pi, np.pi)))
                rec = simulate(rig, sensor, clock, seconds=seconds, seed=int(rng.integers(2**31)), units="counts")
                truth = true_sensitivity(rec.meta["truth"])
                enc = EncoderLog(**encoder_samples(rig, seconds, 1000.0))
                results.append(analyse_test(rec, enc, tangential, radial, NOMINAL_RATE))
                tests.append(CampaignTest(len(tests), "S1", f"{tangential}{radial}", "", None, {}, RotarySetup()))
    report = analyse_campaign(Campaign("bench", tests), results).details
    return {"report": report, "truth": truth}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--runs", type=int, default=300)
    ap.add_argument("--seconds", type=float, default=10.0)
    ap.add_argument("--seed", type=int, default=2025)
    ap.add_argument("--campaigns", type=int, default=20)
    args = ap.parse_args()
    rng = np.random.default_rng(args.seed)
    runs = [one_run(rng, args.seconds) for _ in range(args.runs)]
    n = len(runs)
    print(f"# Rotary bench: {n} simulated tests of {args.seconds:g} s at a nominal {NOMINAL_RATE:g} Hz "
          f"(true rate 0.2-0.5 % off), noise {NOISE_SD} m/s^2 per sample, true radius "
          f"{RADIUS * 1e3:g} +- {RADIUS_SD * 1e3:g} mm\n")

    print("## Sampling rate: error against the true rate\n")
    print("| method | mean error (Hz) | sd (Hz) | RMS (Hz) | mean stated u (Hz) | sd / CRB | |error| <= 2u | "
          "CPU per test (ms, median) |")
    print("|---|---|---|---|---|---|---|---|")
    crb = np.array([r["rate_crb"] for r in runs])
    for method in ("fit", "scan"):
        err = np.array([r[method]["rate"] - r["true_rate"] for r in runs])
        u = np.array([r[method]["rate_u"] for r in runs])
        cover = np.mean(np.abs(err) <= 2 * u) * 100
        ms = np.median([r[method]["seconds"] for r in runs]) * 1e3
        print(f"| {method} | {err.mean():.2e} | {err.std(ddof=1):.2e} | {np.sqrt(np.mean(err**2)):.2e} | "
              f"{u.mean():.2e} | {np.std(err / crb, ddof=1):.2f} | {cover:.1f} % | {ms:.0f} |")
    print(f"\nCRB of the rate from the tangential axis alone: RMS {np.sqrt(np.mean(crb**2)):.2e} Hz. "
          "The time is the CPU time of the whole test analysis (encoder fit, rate, filter, amplitudes, "
          f"residual and sample-timing checks), min of {TIMING_REPEATS} alternating repeats.\n")

    print("## Speed: the rate fit against the paper's 1 Hz scan, same data (CPU ms per test, median over runs)\n")
    print("| stage | fit | scan | fit / scan |")
    print("|---|---|---|---|")
    import tempfile
    from pathlib import Path

    with tempfile.TemporaryDirectory() as directory:
        command = [command_times(rng, args.seconds, Path(directory)) for _ in range(3)]
    for label, rows in (("rate stage alone", [r["rate_stage"] for r in runs]),
                        ("whole analysis (analyse_test)", [{m: r[m]["seconds"] for m in ("fit", "scan")}
                                                           for r in runs]),
                        ("whole command, CSV files in (3 runs)", command)):
        fit = float(np.median([r["fit"] for r in rows])) * 1e3
        scan = float(np.median([r["scan"] for r in rows])) * 1e3
        print(f"| {label} | {fit:.0f} | {scan:.0f} | {fit / scan:.2f} |")
    print()

    print("## Sensitivity against truth (counts per m/s^2)\n")
    print("Bias and sd of (S - S_true) / S_true.  'stat z sd' is the sd of (S - S_true') / u_stat with "
          "S_true' the truth scaled by the drawn radius error and u_stat the stated u without the radius and "
          "geometry parts (MEMS noise, encoder fit and resolution, frequency): 1 when u_stat is right; "
          "the estimator's own bias and sd are against S_true'; coverage uses the full stated u (noise and reference: radius, geometry, encoder).\n")
    print("| method | component | bias (%) | sd (%) | mean stated u (%) | estimator's own bias (ppm) | own sd (ppm) "
          "| stat z sd | |z| <= 2 | |S - S_true| <= 2u |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for method in ("fit", "scan"):
        for axis, component in (("x", "tangential"), ("y", "centripetal")):
            rel, z, cover, u_rel, own, cover_stat = [], [], [], [], [], []
            for r in runs:
                s = r[method]["sens"][axis]
                true = r["truth"][axis]
                rel.append(s.value / true - 1)
                # the procedure uses the nominal radius: its estimate scales with r_true / r_nominal
                true_seen = true * r["radius_ratio"]
                own.append(s.value / true_seen - 1)
                # statistical part of u: everything but the radius and the bench geometry
                u_stat = np.sqrt(s.noise_uncertainty**2 + s.reference_uncertainty**2 - U_RADIUS**2 - U_GEOMETRY**2)
                z.append((s.value - true_seen) / (s.value * u_stat))
                cover_stat.append(abs(z[-1]) <= 2)
                cover.append(abs(s.value - true) <= 2 * s.uncertainty)
                u_rel.append(s.uncertainty / s.value)
            rel, z = np.array(rel) * 100, np.array(z)
            print(f"| {method} | {component} | {rel.mean():+.4f} | {rel.std(ddof=1):.4f} | "
                  f"{np.mean(u_rel) * 100:.4f} | {np.mean(own) * 1e6:+.1f} | {np.std(own, ddof=1) * 1e6:.1f} | "
                  f"{z.std(ddof=1):.2f} | {np.mean(cover_stat) * 100:.1f} % | {np.mean(cover) * 100:.1f} % |")
    print(f"\nMonte Carlo check of the stated uncertainties: target coverage of +-2u is 93-97 % ({n} runs: "
          f"binomial sd {100 * np.sqrt(0.95 * 0.05 / n):.1f} %).")
    if args.campaigns:
        campaign_table(args, rng)




def campaign_table(args, rng) -> None:
    camps = [one_campaign(rng, args.seconds) for _ in range(args.campaigns)]
    print(f"\n## Campaigns: {len(camps)} simulated sensors, 3 supports x {len(PAPER_PLAN)} amplitudes x 2 repeats "
          "(24 tests each), paper budget (full correlation)\n")
    print("| group | mean stated u (%) | mean U, k = 2 (%) | RMS error against truth (%) | |error| <= 2u |")
    print("|---|---|---|---|---|")
    rows = {"case 1 (axis)": ([], []), "case 2 (sensor)": ([], [])}
    for c in camps:
        truth = c["truth"]
        for axis, e in c["report"]["per_axis"]["S1"].items():
            err = e["mean_sensitivity"] / truth[axis] - 1
            rows["case 1 (axis)"][0].append(err)
            rows["case 1 (axis)"][1].append(e["overall_relative_uncertainty"])
        e = c["report"]["per_sensor"]["S1"]
        err = e["mean_sensitivity"] / np.mean(list(truth.values())) - 1
        rows["case 2 (sensor)"][0].append(err)
        rows["case 2 (sensor)"][1].append(e["overall_relative_uncertainty"])
    for name, (err, u) in rows.items():
        err, u = np.array(err), np.array(u)
        print(f"| {name} | {u.mean() * 100:.3f} | {2 * u.mean() * 100:.3f} | {np.sqrt(np.mean(err**2)) * 100:.3f} | "
              f"{np.mean(np.abs(err) <= 2 * u) * 100:.1f} % |")
    budgets = [e["budget"] for c in camps for e in c["report"]["per_axis"]["S1"].values()]
    parts = {}
    for b in budgets:
        for item in b["contributions"]:
            parts.setdefault(item["symbol"], []).append(item["uncertainty"])
    print("\nMean budget lines (Table 2): " + ", ".join(f"{k} {np.mean(v) * 100:.4f} %" for k, v in parts.items())
          + f", u_c {np.mean([b['combined_standard_uncertainty'] for b in budgets]) * 100:.3f} %.")


if __name__ == "__main__":
    main()
