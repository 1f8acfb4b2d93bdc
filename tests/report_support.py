"""Simulated results of all four procedures for the certificate tests and the example script."""

from __future__ import annotations

import html
import importlib.util
import re
from pathlib import Path

import numpy as np

from accelrig.acquisition.url import DeviceURL
from accelrig.sim.device import simulate
from accelrig.sim.rigs.slider_crank import SliderCrankRig
from accelrig.sim.rigs.static import StaticRig
from accelrig.sim.rigs.wheel import WheelRig
from accelrig.sim.sensor import SensorModel, SimClock

DEVICE = {"identity": "sim-0042", "chip": "mpu9250", "driver": "sim", "range_g": 4.0, "rate": 200.0}


def static_result(seed: int = 3, with_sensor: bool = False, **sensor_overrides):
    """A static calibration of a random part (``sensor_overrides`` fix some of its truth); with_sensor: the
    part's SensorModel too."""
    from accelrig.procedures.static.procedure import calibrate_static

    rig = StaticRig.from_url(DeviceURL.parse("sim://static"), np.random.default_rng(seed))
    sensor = SensorModel.random(np.random.default_rng(seed + 100), **sensor_overrides)
    rec = simulate(rig, sensor, SimClock(200.0), seed=seed)
    return (calibrate_static(rec), rec, sensor) if with_sensor else (calibrate_static(rec), rec)


BATCH_GOOD = 6
BATCH_OUTLIER_GAIN = 1.12   # a part 12 % off in x; the random ones are within 2 %


def write_batch_profiles(directory, start_time: str | None = None) -> dict:
    """Profiles of BATCH_GOOD random parts and one whose x gain is BATCH_OUTLIER_GAIN (its offsets zero, so
    nothing else about it stands out), as dev-1 ... dev-7.yaml; returns identity -> SensorModel (the truth).
    ``start_time``: the recordings' start (UTC, ISO 8601) instead of the clock's (the example report's)."""
    from pathlib import Path

    from accelrig.profiles import profile_from_result, save_profile

    truth = {}
    for i in range(BATCH_GOOD + 1):
        overrides = {"gain": [BATCH_OUTLIER_GAIN, 1.0, 1.0], "offset": [0.0, 0.0, 0.0]} if i == BATCH_GOOD else {}
        result, rec, sensor = static_result(20 + i, with_sensor=True, **overrides)
        if start_time is not None:
            rec.meta["start_time"] = start_time
        identity = f"dev-{i + 1}"
        save_profile(profile_from_result(result, rec, device={**DEVICE, "identity": identity}),
                     Path(directory) / f"{identity}.yaml")
        truth[identity] = sensor
    return truth


def wheel_result(seed: int = 11, seconds: float = 40.0):
    from accelrig.procedures.wheel.procedure import calibrate_wheel

    rig = WheelRig(duration=seconds, rest=5.0, push=2.0)   # as the wizard records: still, a push, the coast
    sensor = SensorModel(range_g=4.0, noise_density=SensorModel.noise_density_for_sd(0.08, 200.0))
    rec = simulate(rig, sensor, SimClock(200.0), seconds=rig.duration, seed=seed)
    return calibrate_wheel(rec, radius=rig.radius), rec


def slider_crank_result(seed: int = 1):
    from accelrig.procedures.slider_crank.procedure import verify_slider_crank

    rig = SliderCrankRig(steps=[2.5, 5.0, 8.0, 10.0], axis="1,0.1,0")
    sensor = SensorModel(range_g=8.0, noise_density=SensorModel.noise_density_for_sd(0.08, 2048.0))
    rec = simulate(rig, sensor, SimClock(2048.0, 0.003, 20e-6), seed=seed)
    return verify_slider_crank([("sim", rec)], 0.00635, 0.0353, clearance=0.0002), rec


def rotary_campaign_result(directory, seed: int = 7):
    from accelrig.procedures.rotary.campaign import run_campaign
    from accelrig.sim.campaign import write_sim_campaign

    truth = write_sim_campaign(directory, n_sensors=2, repeats=2, seconds=2.5, seed=seed,
                               plan=((5.0, 34.0), (5.0, 16.0)), orientations=(("x", "y"),))
    return run_campaign(truth["yaml"]), truth


EXAMPLES = Path(__file__).resolve().parents[1] / "docs" / "examples"


def example_script():
    """docs/examples/make_certificates.py as a module (what made the example certificates)."""
    spec = importlib.util.spec_from_file_location("make_certificates", EXAMPLES / "make_certificates.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def certificate_text(page: str) -> str:
    """What a certificate or batch report says, for comparing two renderings: its words without the markup,
    the figures (drawings of the same arrays; their section is cut), times of day, the software version and
    the fits' wall-clock seconds (which differ between two runs of the same code)."""
    page = re.sub(r"<h2>\d+\. Figures</h2>.*?(?=<h3>Authorisation|<h2>Appendix|<p class=\"note\">[^<]*</p></body>)", "", page,
                  flags=re.S)
    page = re.sub(r"<(style|svg)\b.*?</\1>", " ", page, flags=re.S)
    text = html.unescape(re.sub(r"<[^>]+>", " ", page))
    text = re.sub(r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d(\.\d+)?(Z|[+-]\d\d:?\d\d)?", "TIME", text)
    text = re.sub(r"\d{4}-\d\d-\d\d\s+\d\d:\d\d\s+UTC", "TIME", text)   # as the certificate prints a time
    text = re.sub(r"accelrig \d+\.\d+\S*", "accelrig VERSION", text)
    text = re.sub(r"\b(fit_seconds|time_s)\s+[-+0-9.e]+", r"\1 SECONDS", text)
    return " ".join(text.split())


def first_difference(stored: str, rendered: str, context: int = 120) -> str:
    """Where two texts part, with some words either side (for a test's message)."""
    i = next((k for k, (a, b) in enumerate(zip(stored, rendered, strict=False)) if a != b), min(len(stored), len(rendered)))
    start = max(i - context, 0)
    return f"stored:   ...{stored[start:i + context]}...\nrendered: ...{rendered[start:i + context]}..."
