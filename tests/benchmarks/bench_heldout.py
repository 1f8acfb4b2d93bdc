"""Held-out audit (issue 18): the static, wheel, slider-crank and rotary commands on recordings from a simulator
that shares no code with accelrig.sim (``heldout_sim.py``), under conditions the stress benchmark
does not have (other noise colours, drift shapes, friction laws, rig imperfections).

    python tests/benchmarks/bench_heldout.py [--runs 25] [--procedure static] [--condition walk] [--seed 7]

Each run writes the recording as a CSV file (what a person hands accelrig) and runs the command:
``accelrig calibrate static FILE --json`` and ``accelrig calibrate wheel FILE --radius R --json``
through ``accelrig.cli.main`` in this process, and ``accelrig verify slider-crank FILE --crank-radius R
--rod-length L --clearance C --json`` likewise (one file with a ``step`` column); the rotary test through ``load_test_inputs`` and
``analyse_test`` (what ``accelrig calibrate rotary --mems M.csv --encoder E.csv`` runs) with the
radius known to 1 um and no bench-geometry term, so that the noise and timing effects are not hidden
under the 0.3 % radius term.  The table has the shape of bench_stress.py's and the same targets:
coverage 90-98 % wherever the tool neither warns nor refuses, a warning in >= 95 % of runs wherever
coverage would be lower, no refusal that blames the wrong cause.

Judged: static, the 12 entries of C and b (calibrated = C (raw - b)); wheel, the three gains, three
offsets and the tilt; slider-crank, each step's radius (truth: the effective crank radius) and mean
speed (truth: the crank angle gained between the step's first and last sample over that time) and the
combined radius, with a verdict other than "holds" counted as a warning (the sensor is perfect);
rotary, the sample rate and the tangential and radial sensitivities.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import re
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_stress import Condition, Outcome, print_table, summarise  # noqa: E402
from heldout_sim import (  # noqa: E402
    Drift,
    Noise,
    RotaryCase,
    SliderCase,
    StaticCase,
    WheelCase,
    simulate_rotary,
    simulate_slider,
    simulate_static,
    simulate_wheel,
    write_csv,
)

PROCEDURES = ("static", "wheel", "slider_crank", "rotary")
# what a right refusal of noise slower than the record can measure says
SLOW = ("correlated", "wanders", "slow")


def _command(argv: list[str]) -> tuple[dict | None, str]:
    """Run ``accelrig ARGV --json`` in this process: (the JSON, or None when refused; stderr)."""
    from accelrig.cli import main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(argv)
    if code != 0 and not (code == 1 and out.getvalue().lstrip().startswith("{")):   # verify: 1 = not "holds"
        return None, err.getvalue().strip() or f"exit {code}"
    return json.loads(out.getvalue()), err.getvalue()


def _refusal(text: str) -> str:
    return text.removeprefix("accelrig: error: ")


# ---------------------------------------------------------------------------------------------- static

def _static(case: StaticCase):
    def run(seed: int) -> Outcome:
        rng = np.random.default_rng(seed)
        t, raw, truth = simulate_static(case, rng)
        out = Outcome()
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / "static.csv"
            write_csv(path, t, {"ax": raw[:, 0], "ay": raw[:, 1], "az": raw[:, 2]},
                      meta={"units": "m/s^2", "range_g": case.range_g, "rate": case.rate})
            argv = ["calibrate", "static", str(path), "--json", "--no-store",
                    "--pose-flatness-deg", str(max(case.tilt_deg, 0.1))]
            # g known to 1e-5 (a surveyed g): the gains are judged on the noise, not on the default g's u.
            # (--g 9.80665 alone would not do: it equals the default and gets the anywhere-on-Earth u)
            argv += ["--g", f"{case.g:.5f}", "--g-u", "1e-5"]
            result, err = _command(argv)
        if result is None:
            out.refused = _refusal(err)
            return out
        corr = result["correction"]
        est = np.concatenate([np.ravel(corr["matrix"]), corr["bias"]])
        u = np.concatenate([np.ravel(corr["matrix_uncertainty"]), corr["bias_uncertainty"]])
        true = np.concatenate([truth["C"].ravel(), truth["b"]])
        names = [f"C_{r}{c}" for r in "xyz" for c in "xyz"] + ["b_x", "b_y", "b_z"]
        for name, e, tr, s in zip(names, est, true, u, strict=True):
            out.errors[name] = float(e - tr)
            out.u[name] = float(s)
        out.warnings = list(result["warnings"])
        return out
    return run


def static_conditions() -> list[Condition]:
    s = 0.03
    rows = [
        ("white, holds 4.5-6 s (simulator check)", StaticCase(), ()),
        ("pink 1/f^0.5, corner 1 Hz", StaticCase(noise=Noise("power", s, beta=0.5, corner=1.0)), ("correlated",)),
        ("red 1/f^1.5, corner 0.3 Hz", StaticCase(noise=Noise("power", s, beta=1.5, corner=0.3)),
         ("correlated", "drift")),
        ("random walk 0.002/sqrt(s) + white", StaticCase(noise=Noise("walk", s, walk=0.002)),
         ("correlated", "drift")),
        ("AR(2) peak 3 Hz, r 0.95", StaticCase(noise=Noise("ar2", s, peak=3.0, r=0.95)), ("correlated",)),
        ("vibration 8-12 Hz, 0.03 + white", StaticCase(noise=Noise("band", s, band=(8.0, 12.0), band_sd=0.03)),
         ("correlated", "vibrat")),
        ("offset step 0.01 mid-run", StaticCase(drift=Drift("step", 0.01)), ("drift",)),
        ("warm-up 0.015, tau 1/4 run", StaticCase(drift=Drift("warmup", 0.015, at=0.25)), ("drift",)),
        ("thermal cycle 0.01 p-p, period 0.8 run", StaticCase(drift=Drift("thermal", 0.01, at=0.8)), ("drift",)),
        # very slow noise (issue 18): its correlation time is seconds to tens of seconds, a hold's length or more
        ("AR(1) rho 0.99", StaticCase(noise=Noise("ar1", s, r=0.99)), SLOW),
        ("AR(1) rho 0.997", StaticCase(noise=Noise("ar1", s, r=0.997)), SLOW),
        ("AR(1) rho 0.999", StaticCase(noise=Noise("ar1", s, r=0.999)), SLOW),
        ("random walk 0.01/sqrt(s) dominates", StaticCase(noise=Noise("walk", s, walk=0.01)), SLOW + ("drift",)),
        # a slow wander under a white floor: tau within the holds reads white (1.1-1.3 samples), only the halves of
        # the poses see it
        ("white 0.03 + AR(1) 0.01, rho 0.9998 (25 s)", StaticCase(noise=Noise("white+ar1", s, r=0.9998, ar_sd=0.01)),
         SLOW),
    ]
    return [Condition("static", name, _static(case), must) for name, case, must in rows]


# ----------------------------------------------------------------------------------------------- wheel

def _wheel(case: WheelCase):
    def run(seed: int) -> Outcome:
        rng = np.random.default_rng(seed)
        t, raw, truth = simulate_wheel(case, rng)
        out = Outcome()
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / "wheel.csv"
            write_csv(path, t, {"ax": raw[:, 0], "ay": raw[:, 1], "az": raw[:, 2]},
                      meta={"units": "m/s^2", "range_g": case.range_g})
            result, err = _command(["calibrate", "wheel", str(path), "--radius", str(case.radius), "--json",
                                    "--no-store", "--g", "9.80665", "--g-u", "1e-5"])
        if result is None:
            out.refused = _refusal(err)
            return out
        p = result["parameters"]
        for k, axis in enumerate("xyz"):
            out.errors[f"gain_{axis}"] = p["gain"]["value"][k] - truth["gain"][k]
            out.u[f"gain_{axis}"] = p["gain"]["uncertainty"][k]
            out.errors[f"offset_{axis}"] = p["offset"]["value"][k] - truth["offset"][k]
            out.u[f"offset_{axis}"] = p["offset"]["uncertainty"][k]
        out.errors["tilt"] = p["tilt_deg"]["value"] - truth["tilt_deg"]
        out.u["tilt"] = p["tilt_deg"]["uncertainty"]
        k = result.get("details", {}).get("coverage_factor")
        if k is not None:   # the tool states its own k (Student's t on few batch-means blocks)
            out.k = dict.fromkeys(out.errors, float(k))
        # the cross-axis prior is a statement about what the wheel cannot see, not a finding about this run
        out.warnings = [w for w in result["warnings"] if "does not observe cross-axis" not in w]
        return out
    return run


def wheel_conditions() -> list[Condition]:
    s = 0.08
    lack = ("model does not fit", "speed", "friction", "lack of fit")
    rows = [
        ("cubic speed law, white (simulator check)", WheelCase(), ()),
        ("viscous + Coulomb friction", WheelCase(law="viscous+coulomb"), lack),
        ("air drag (w^2) + Coulomb", WheelCase(law="quadratic+coulomb", slow_to=0.45), lack),
        ("pink 1/f^0.5, corner 1 Hz", WheelCase(noise=Noise("power", s, beta=0.5, corner=1.0)), ("correlated",)),
        ("red 1/f^1.5, corner 0.3 Hz", WheelCase(noise=Noise("power", s, beta=1.5, corner=0.3)),
         ("correlated", "drift")),
        ("random walk 0.005/sqrt(s) + white", WheelCase(noise=Noise("walk", s, walk=0.005)), ("correlated", "drift")),
        ("AR(2) peak 2 Hz, r 0.95", WheelCase(noise=Noise("ar2", s, peak=2.0, r=0.95)), ("correlated",)),
        ("AR(1) rho 0.99", WheelCase(noise=Noise("ar1", s, r=0.99)), SLOW),
        ("AR(1) rho 0.997", WheelCase(noise=Noise("ar1", s, r=0.997)), SLOW),
        ("AR(1) rho 0.999", WheelCase(noise=Noise("ar1", s, r=0.999)), SLOW),
        ("random walk 0.03/sqrt(s) dominates", WheelCase(noise=Noise("walk", s, walk=0.03)), SLOW + ("drift",)),
        ("offset step 0.02 mid-run", WheelCase(drift=Drift("step", 0.02)), ("drift",)),
        ("warm-up 0.02, tau 1/4 run", WheelCase(drift=Drift("warmup", 0.02, at=0.25)), ("drift",)),
        ("tilt creeps 0.3 deg over the run", WheelCase(tilt_wander_deg=0.3), lack + ("tilt",)),
        # a refusal may also name the nod itself: at 0.1 deg its unseen half can move the estimates by about 2 u, the
        # limit the wheel refuses beyond ("the wheel wobbles by 0.05 deg ...: what an axis that nods ... (bearing play)")
        ("bearing play: axis nods 0.1 deg per turn", WheelCase(wobble_deg=0.1), lack + ("tilt", "nods", "bearing")),
        # larger play: the nod's first order is a wobble at twice the wheel angle the fit can take in, but the
        # bearing's own shape is not known (issue 18): warned or refused "the wheel's axis nods"
        ("bearing play: axis nods 0.5 deg per turn", WheelCase(wobble_deg=0.5), ("nods", "bearing")),
        ("bearing play: axis nods 1.5 deg per turn", WheelCase(wobble_deg=1.5), ("nods", "bearing")),
        # the axis moving in other ways (the wheel's attitude built from rotations, its acceleration differentiated,
        # the nod's plane drawn at random): a refusal must name the axis or the bearing
        ("moving axis: nods 0.2 deg once per turn, any plane", WheelCase(axis_deg=0.2), ("nods", "bearing", "axis")),
        ("moving axis: nods 0.05 deg twice per turn", WheelCase(axis_deg=0.05, axis_per_turn=2),
         ("nods", "bearing", "axis")),
        ("moving axis: nods 0.2 deg twice per turn", WheelCase(axis_deg=0.2, axis_per_turn=2),
         ("nods", "bearing", "axis")),
        ("moving axis: nods 0.2 deg once per turn above 7 rad/s", WheelCase(axis_deg=0.2, axis_above=7.0),
         ("nods", "bearing", "axis")),
        ("moving axis: nods 0.5 deg once per turn above 7 rad/s", WheelCase(axis_deg=0.5, axis_above=7.0),
         ("nods", "bearing", "axis")),
        ("moving axis: cones 0.3 deg against the wheel", WheelCase(axis_deg=0.3, axis_motion="cone", axis_sense=-1),
         ("nods", "bearing", "axis", "cone")),
        ("moving axis: cones 0.3 deg with the wheel", WheelCase(axis_deg=0.3, axis_motion="cone", axis_sense=1),
         ("nods", "bearing", "axis", "cone")),
        # the operator's record: the wizard says "spin the wheel by hand, then let it coast; keep the recording
        # running", so the wheel rests, is pushed, then coasts: no refusal is right
        ("rest 5 s then a 2 s push", WheelCase(rest_s=5.0, push_s=2.0), ()),
        ("rest 3 s then two pushes over 3 s", WheelCase(rest_s=3.0, push_s=3.0, pushes=2), ()),
        # a sensor powered up with the recording: it warms up from the first sample, through the rest and the
        # push, so the rest before the spin reads the offset before the coast's (issue 18: the rest is what shows
        # a drift along the wheel's plane that the coast alone confounds with the centripetal term)
        ("warm-up 0.02, tau 1/4 run, rest 5 s then a 2 s push",
         WheelCase(drift=Drift("warmup", 0.02, at=0.25), rest_s=5.0, push_s=2.0), ("drift",)),
    ]
    return [Condition("wheel", name, _wheel(case), must) for name, case, must in rows]


# ---------------------------------------------------------------------------------------- slider-crank

def _slider(case: SliderCase):
    def run(seed: int) -> Outcome:
        rng = np.random.default_rng(seed)
        t, acc, step, truth = simulate_slider(case, rng)
        out = Outcome()
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / "slider.csv"
            write_csv(path, t, {"ax": acc[:, 0], "ay": acc[:, 1], "az": acc[:, 2], "step": step},
                      meta={"units": "m/s^2", "range_g": case.range_g, "rate": case.rate})
            result, err = _command(["verify", "slider-crank", str(path), "--crank-radius", str(case.radius),
                                    "--rod-length", str(case.rod), "--clearance", str(case.clearance), "--json"])
        if result is None:
            out.refused = _refusal(err)
            return out
        details = result["details"]
        for s in details["steps"]:
            if s["motor_limited"]:
                continue
            i = s["index"]
            out.errors[f"radius_{i + 1}"] = s["radius_m"]["value"] - truth["radius"]
            out.u[f"radius_{i + 1}"] = s["radius_m"]["uncertainty"]
            out.errors[f"speed_{i + 1}"] = s["frequency_hz"]["value"] - truth["speed"][i]
            out.u[f"speed_{i + 1}"] = s["frequency_hz"]["uncertainty"]
        radius = details["radius_m"]
        if radius["value"] is not None and np.isfinite(radius["value"]):
            out.errors["radius"] = radius["value"] - truth["radius"]
            out.u["radius"] = radius["uncertainty"]
        out.warnings = list(result["warnings"])
        if details["verdict"] != "holds":   # the sensor is perfect and the clearance covers the pin: explain it
            out.warnings.append(f"verdict: {details['verdict']}")
        return out
    return run


def slider_rows() -> list[tuple[str, SliderCase, tuple[str, ...]]]:
    """(name, case, what a refusal must say) per slider-crank condition."""
    s = 0.08
    speed = ("speed", "wander", "motor")
    play = ("play", "backlash", "knock")
    lack = ("not a crank", "model", "misses", "lack of fit")
    rows = [
        ("white (simulator check)", SliderCase(), ()),
        ("pink 1/f^0.5, corner 20 Hz", SliderCase(noise=Noise("power", s, beta=0.5, corner=20.0)), ("correlated",)),
        ("red 1/f^1.5, corner 5 Hz", SliderCase(noise=Noise("power", s, beta=1.5, corner=5.0)), ("correlated",)),
        ("AR(1) rho 0.99", SliderCase(noise=Noise("ar1", s, r=0.99)), SLOW),
        ("AR(1) rho 0.997", SliderCase(noise=Noise("ar1", s, r=0.997)), SLOW),
        ("AR(1) rho 0.999", SliderCase(noise=Noise("ar1", s, r=0.999)), SLOW),
        ("random walk 0.05/sqrt(s) dominates", SliderCase(noise=Noise("walk", s, walk=0.05)), SLOW),
        ("sensor misaligned 2 deg on the slider", SliderCase(misalign_deg=2.0), ()),
        ("crank pin eccentric 50 um", SliderCase(eccentric=5e-5), ()),
        ("speed wobble 1 % at 5 Hz", SliderCase(wobble=0.01, wobble_hz=5.0), speed),
        ("speed wander 0.5 % sd, below 1.5 Hz", SliderCase(wander=0.005, wander_hz=1.5), speed),
        ("cogging 6 per turn, 5 rad/s^2", SliderCase(cogging=5.0, cogging_n=6), speed + lack),
        ("pin dead zone 10 um, impact at 450 Hz", SliderCase(dead_zone=1e-5), play),
        ("pin dead zone 30 um, impact at 450 Hz", SliderCase(dead_zone=3e-5), play),
        ("compliant link, resonance 300 Hz", SliderCase(link_hz=300.0), lack),
        # a preloaded (braked) slide: its friction outweighs the slider's inertia at every step, so play is
        # crossed where the velocity reverses, at the dead centres, and knocks there; on a long rod (160 mm: the
        # two dead centres alike) the knock is the same at both, so the flexing-link trend judges those steps.
        # The impact clips 8 g at 10 Hz: the operator chooses 16 g
        ("braked slide, long rod, pin dead zone 10 um at the dead centres",
         SliderCase(dead_zone=1e-5, friction=5.0, rod=0.16, range_g=16.0), play),
        ("braked slide, long rod, pin dead zone 30 um at the dead centres",
         SliderCase(dead_zone=3e-5, friction=5.0, rod=0.16, range_g=16.0), play),
        ("braked slide, long rod, dead zone 20 um, contact 300 Hz",
         SliderCase(dead_zone=2e-5, friction=5.0, contact_hz=300.0, rod=0.16, range_g=16.0), play),
        # a soft contact (a polymer bush, 150 Hz) and little play: the trend is precise enough to admit the contact's
        # ring, so the event's growth and timing with speed decide
        ("braked slide, long rod, dead zone 3 um, soft contact 150 Hz",
         SliderCase(dead_zone=3e-6, friction=5.0, contact_hz=150.0, rod=0.16, range_g=16.0), play),
        # a compliant link on a rail whose friction turns over a broad band of speed (Stribeck: 1.5 times the
        # sliding friction at rest): at slow steps the slider crosses the band too slowly to ring the link
        ("link 200 Hz, Stribeck friction turning over 10 mm/s",
         SliderCase(link_hz=200.0, breakaway=1.5, stribeck_v=0.005, reversal_v=0.01), lack),
        ("link 300 Hz, Stribeck friction turning over 3 mm/s",
         SliderCase(link_hz=300.0, breakaway=1.5, stribeck_v=0.005, reversal_v=0.003), lack),
        ("link 300 Hz, Stribeck friction turning over 10 mm/s",
         SliderCase(link_hz=300.0, breakaway=1.5, stribeck_v=0.005, reversal_v=0.01), lack),
        ("link 300 Hz, Stribeck friction turning over 30 mm/s",
         SliderCase(link_hz=300.0, breakaway=1.5, stribeck_v=0.01, reversal_v=0.03), lack),
        # a sharp band: the slider sticks at each dead centre until the stretched link breaks it free (about
        # 0.5 um of lost motion), a fixed crank angle after the dead centre, as play is crossed
        ("link 450 Hz, Stribeck friction turning over 3 mm/s",
         SliderCase(link_hz=450.0, breakaway=1.5, stribeck_v=0.005, reversal_v=0.003), lack),
        ("link 450 Hz, Stribeck friction turning over 10 mm/s",
         SliderCase(link_hz=450.0, breakaway=1.5, stribeck_v=0.005, reversal_v=0.01), lack),
        ("link 450 Hz, Stribeck friction turning over 30 mm/s",
         SliderCase(link_hz=450.0, breakaway=1.5, stribeck_v=0.01, reversal_v=0.03), lack),
    ]
    return rows


def slider_conditions() -> list[Condition]:
    return [Condition("slider_crank", name, _slider(case), must) for name, case, must in slider_rows()]


# ---------------------------------------------------------------------------------------------- rotary

def _rotary(case: RotaryCase):
    def run(seed: int) -> Outcome:
        from accelrig.errors import AccelrigError
        from accelrig.procedures.rotary.bench import RotarySetup, analyse_test, load_test_inputs

        rng = np.random.default_rng(seed)
        counts, te, theta, truth = simulate_rotary(case, rng)
        out = Outcome()
        with tempfile.TemporaryDirectory() as tmp:
            mems, enc = Path(tmp) / "mems.csv", Path(tmp) / "encoder.csv"
            write_csv(mems, None, {"ax": counts[:, 0], "ay": counts[:, 1], "az": counts[:, 2]}, fmt="%d")
            write_csv(enc, te, {"theta": theta}, fmt="%.9f")
            try:
                rec, log = load_test_inputs(mems, enc, case.nominal_rate, units="counts")
                test = analyse_test(rec, log, "x", "y", case.nominal_rate,
                                    setup=RotarySetup(radius=case.radius, radius_uncertainty=1e-6,
                                                      geometry_uncertainty=0.0))
            except AccelrigError as exc:
                out.refused = str(exc)
                return out
        out.errors["rate"] = test.sample_rate.value - truth["rate"]
        out.u["rate"] = test.sample_rate.uncertainty
        for axis, s in test.sensitivity.items():
            out.errors[f"S_{axis}"] = s.value - truth[f"S_{axis}"]
            out.u[f"S_{axis}"] = s.uncertainty
        out.warnings = list(test.warnings)
        return out
    return run


def rotary_conditions() -> list[Condition]:
    s = 0.03
    timing = ("lost", "missing", "clock", "timing", "jitter")
    rows = [
        ("white (simulator check)", RotaryCase(), ()),
        ("pink 1/f^0.5, corner 1 Hz", RotaryCase(noise=Noise("power", s, beta=0.5, corner=1.0)), ("correlated",)),
        ("red 1/f^1.5, corner 1 Hz", RotaryCase(noise=Noise("power", s, beta=1.5, corner=1.0)), ("correlated",)),
        ("random walk 0.01/sqrt(s) + white", RotaryCase(noise=Noise("walk", s, walk=0.01)), ("correlated",)),
        ("AR(2) peak 50 Hz, r 0.98", RotaryCase(noise=Noise("ar2", s, peak=50.0, r=0.98)), ("correlated",)),
        ("AR(1) rho 0.99", RotaryCase(noise=Noise("ar1", s, r=0.99)), SLOW),
        ("AR(1) rho 0.997", RotaryCase(noise=Noise("ar1", s, r=0.997)), SLOW),
        ("AR(1) rho 0.999", RotaryCase(noise=Noise("ar1", s, r=0.999)), SLOW),
        ("random walk 0.05/sqrt(s) dominates", RotaryCase(noise=Noise("walk", s, walk=0.05)), SLOW),
        ("vibration 3-12 Hz, 0.02 + white", RotaryCase(noise=Noise("band", s, band=(3.0, 12.0), band_sd=0.02)),
         ("correlated",)),
        ("encoder 0.1 deg steps", RotaryCase(encoder_step_deg=0.1), ("encoder",)),
        ("encoder eccentric 1e-4 rad", RotaryCase(eccentric_rad=1e-4), ("encoder",)),
        ("2nd harmonic 1 % in the motion", RotaryCase(harmonic2=0.01), ("harmonic", "motion")),
        ("sample-time jitter 20 us", RotaryCase(jitter_s=20e-6), timing),
        ("clock rate wander 1e-4/sqrt(s)", RotaryCase(clock_wander=1e-4), timing),
    ]
    return [Condition("rotary", name, _rotary(case), must) for name, case, must in rows]


def load_conditions(procedure: str | None = None) -> list[Condition]:
    found = []
    for name, make in (("static", static_conditions), ("wheel", wheel_conditions),
                       ("slider_crank", slider_conditions), ("rotary", rotary_conditions)):
        if procedure in (None, name):
            found += make()
    return found


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=25)
    parser.add_argument("--seed", type=int, default=7)
    parser.add_argument("--procedure", choices=PROCEDURES)
    parser.add_argument("--condition", help="run only conditions whose name contains this")
    parser.add_argument("--details", action="store_true", help="per parameter: coverage and u/sd")
    args = parser.parse_args(argv)
    conditions = [c for c in load_conditions(args.procedure) if not args.condition or args.condition in c.name]
    if not conditions:
        print("no condition matches", file=sys.stderr)
        return 2
    rows = []
    for condition in conditions:
        outcomes = []
        for i in range(args.runs):
            start = time.perf_counter()
            outcome = condition.run(args.seed * 100003 + i)
            outcome.seconds = time.perf_counter() - start
            outcomes.append(outcome)
        rows.append(summarise(condition, outcomes))
        print(f"{condition.procedure} / {condition.name}: done", file=sys.stderr, flush=True)
        if args.details:
            kept = [o for o in outcomes if not o.refused]
            # the unwarned runs are the ones the 90-98 % target judges: their coverage per parameter, and each
            # miss with its run (seed index), so a few runs under a threshold can be told from a pattern
            clean = [(i, o) for i, o in enumerate(outcomes) if not o.refused and not o.warnings]
            for k in (kept[0].errors if kept else {}):
                z = np.array([o.errors[k] / o.u[k] for o in kept if o.u.get(k)])
                zc = np.array([o.errors[k] / o.u[k] for _, o in clean if o.u.get(k)])
                unwarned = f"  unwarned {np.mean(np.abs(zc) <= 2):.2f} of {zc.size}" if zc.size else ""
                print(f"    {k:10s} cover {np.mean(np.abs(z) <= 2):.2f}  z mean {z.mean():+.2f} sd {z.std():.2f}"
                      f"  max |z| {np.max(np.abs(z)):.1f}{unwarned}", file=sys.stderr)
            misses = [f"run {i}: " + ", ".join(f"{k} {o.errors[k] / o.u[k]:+.1f} u" for k in o.errors
                                              if o.u.get(k) and abs(o.errors[k] / o.u[k]) > 2)
                      for i, o in clean if any(o.u.get(k) and abs(o.errors[k] / o.u[k]) > 2 for k in o.errors)]
            for miss in misses:
                print(f"    unwarned, not covered: {miss}", file=sys.stderr)
            # what the warnings say, by kind (the text after the step's name, up to its first digit), in runs
            kinds = Counter(kind for o in kept for kind in {re.split(r"[0-9]", w.split("): ", 1)[-1])[0][:60]
                                                             for w in o.warnings})
            for kind, count in kinds.most_common(6):
                print(f"    warned in {count:2d} runs: {kind}", file=sys.stderr)
    print_table(rows)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
