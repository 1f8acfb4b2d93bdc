"""A simulated rotary-bench campaign on disk (paper 001's batch): MEMS recordings, encoder logs, campaign.yaml.

Sits above the rigs and the device simulation, which it drives; tests and benchmarks use it to make
campaigns whose truth is known.
"""

from __future__ import annotations

import os

import numpy as np
import yaml

from accelrig.files import atomic_write
from accelrig.recording import save_recording
from accelrig.sim.device import simulate
from accelrig.sim.rigs.rotary import (
    PAPER_ORIENTATIONS,
    PAPER_PLAN,
    RotaryRig,
    encoder_samples,
    true_sensitivity,
    write_encoder_csv,
)
from accelrig.sim.sensor import SensorModel, SimClock
from accelrig.units import STANDARD_GRAVITY

PAPER_SENSITIVITY = 423.0  # counts per m/s^2, paper 001's batch mean (nominal 4096 / 9.80665 = 417.7)


def paper_sensor(rng: np.random.Generator, noise_sd: float = 0.03, rate: float = 1660.0):
    """An LSM6DSR-like part at +-8 g: sensitivity near 423 counts per m/s^2 (paper 001, 1.3 %
    above the nominal 417.7), per-axis spread 0.3 %, sub-degree misalignment, offsets of a few mg."""
    nominal = 2**15 / (8.0 * STANDARD_GRAVITY)
    gain = PAPER_SENSITIVITY / nominal * (1.0 + rng.normal(0.0, 0.003, 3))
    return SensorModel(
        offset=rng.uniform(-0.1, 0.1, 3), gain=gain, misalignment=np.deg2rad(rng.uniform(-0.1, 0.1, 3)),
        noise_density=SensorModel.noise_density_for_sd(noise_sd, rate), range_g=8.0,
    )


def write_sim_campaign(
    directory: str | os.PathLike,
    n_sensors: int = 2,
    repeats: int = 2,
    seconds: float = 10.0,
    seed: int = 0,
    plan=PAPER_PLAN,
    orientations=PAPER_ORIENTATIONS,
    nominal_rate: float = 1660.0,
    rate_error: tuple[float, float] = (0.002, 0.005),
    radius: float = 0.170,
    true_radius_sd: float = 0.0,
    ref: bool = True,
    rate_method: str = "fit",
) -> dict:
    """Write a simulated campaign (MEMS CSVs in counts, encoder logs, campaign.yaml) into ``directory``.

    Each sensor gets its own clock (rate error drawn in ``rate_error``) and, with
    ``true_radius_sd`` > 0, each mounting its own true radius around the nominal
    one given to the procedure (what the reference uncertainty must cover).
    Returns the truth: {"sensors": {name: {axis: counts per m/s^2}}, "rates": ..., "yaml": path}.
    """
    directory = os.fspath(directory)
    os.makedirs(directory, exist_ok=True)
    rng = np.random.default_rng(seed)
    tests, truth = [], {"sensors": {}, "rates": {}, "radius": {}}
    for s in range(n_sensors):
        name = f"S{s + 1}"
        sensor = paper_sensor(rng, rate=nominal_rate)
        clock = SimClock(nominal_rate, float(rng.uniform(*rate_error)), 0.0)
        truth["rates"][name] = clock.true_rate
        for tangential, radial in orientations:
            r_true = radius + rng.normal(0.0, true_radius_sd) if true_radius_sd > 0 else radius
            truth["radius"][f"{name}-{tangential}{radial}"] = r_true
            for frequency, amplitude in plan:
                for rep in range(repeats):
                    rig = RotaryRig(radius=r_true, frequency=frequency, amplitude_deg=amplitude,
                                    tangential=tangential, radial=radial, duration=seconds, ref=ref,
                                    phase=float(rng.uniform(-np.pi, np.pi)),
                                    ref_gain_error=float(rng.normal(0.0, 1e-3)))
                    label = f"{name}_{tangential}{radial}_{frequency:g}hz_{amplitude:g}deg_r{rep + 1}"
                    rec = simulate(rig, sensor, clock, seconds=seconds, seed=int(rng.integers(2**31)), units="counts")
                    truth["sensors"][name] = true_sensitivity(rec.meta["truth"])
                    # the MEMS file carries no timestamps of its own: t = k / nominal rate
                    rec.t = rec.t[0] + np.arange(len(rec)) / nominal_rate
                    rec.channels = {}
                    rec.meta.pop("truth")
                    save_recording(rec, os.path.join(directory, label + ".csv"))
                    enc = encoder_samples(rig, seconds, 1000.0, ref_noise=0.02, rng=rng)
                    write_encoder_csv(os.path.join(directory, label + "_enc.csv"), enc)
                    tests.append({"sensor": name, "label": label, "mems": label + ".csv",
                                  "encoder": label + "_enc.csv", "tangential": tangential, "radial": radial,
                                  "frequency": frequency})
    doc = {
        "name": f"simulated LSM6DSR batch (seed {seed})",
        "nominal_rate": nominal_rate, "radius": radius, "radius_uncertainty": 0.0005,
        "ref_radius": 0.145, "rate_method": rate_method, "units": "counts",
        "components": ["tangential", "centripetal"], "correlation": 1.0, "coverage_factor": 2,
        "tests": tests,
    }
    path = os.path.join(directory, "campaign.yaml")
    atomic_write(path, lambda fh: yaml.safe_dump(doc, fh, sort_keys=False), text=True)
    truth["yaml"] = path
    return truth
