"""Stress conditions of the tilted wheel (issue 18), for bench_stress.py.

Each run simulates a 90 s coast-down at 200 Hz (radius 0.28 m given, tilt 45 deg estimated,
Table I's gains, offsets and mounting, noise sd 0.08 m/s^2 per sample) with accelrig.sim and
calibrates it with ``calibrate_wheel``, the code path of ``accelrig calibrate wheel REC
--radius 0.28``.  Judged: the three gains, the three offsets and the tilt.

    white         the paper's conditions: white noise, cubic speed law
    ar1           AR(1) noise, rho 0.9 (and 0.997: slower than a 90 s record measures), same sd per sample
    flicker       1/f noise (0.01 (m/s^2)/sqrt(Hz) at 1 Hz) on top of the white noise
    drift         the offsets drift by 0.01 m/s^2 over the run (truth: the mean offset)
    lossy         5 % of the samples lost at scattered points (the survivors keep their times)
    stops         Coulomb + viscous friction that stops the wheel at 75 s of the 90
    unbalanced    an unbalanced mass: 0.15 rad/s^2 peak, the speed swings once per turn
"""

from __future__ import annotations

import numpy as np
from bench_stress import Condition, Outcome

from accelrig.errors import AccelrigError
from accelrig.procedures.wheel.procedure import calibrate_wheel
from accelrig.recording import Recording
from accelrig.sim.device import simulate
from accelrig.sim.rigs.wheel import TABLE_I_MISALIGNMENT_DEG, TABLE_I_THETA0_DEG, WheelRig
from accelrig.sim.sensor import SensorModel, SimClock

RADIUS = 0.28
TILT_DEG = 45.0
RATE = 200.0
SECONDS = 90.0
NOISE = 0.08
GAIN = (0.98, 1.0, 1.02)
OFFSET = (0.3, -0.2, 0.25)
STOP_AT = 75.0
VISCOUS = 0.01


def _rig(**options) -> WheelRig:
    return WheelRig(radius=RADIUS, tilt_deg=TILT_DEG, duration=SECONDS, misalignment_deg=TABLE_I_MISALIGNMENT_DEG,
                    theta0_deg=TABLE_I_THETA0_DEG, **options)


def _sensor(**options) -> SensorModel:
    return SensorModel(offset=OFFSET, gain=GAIN, range_g=4.0,
                       noise_density=SensorModel.noise_density_for_sd(NOISE, RATE), **options)


def _lossy(rec: Recording, seed: int, share: float = 0.05) -> Recording:
    """Drop ``share`` of the samples at scattered points, as a lossy link does (times kept)."""
    rng = np.random.default_rng(10_000 + seed)
    keep = rng.random(rec.t.size) >= share
    keep[0] = keep[-1] = True
    return Recording(rec.t[keep], rec.acc[keep], rec.units, {k: v[keep] for k, v in rec.channels.items()}, rec.meta)


def _judge(rec: Recording, sensor: SensorModel) -> Outcome:
    offset_truth = sensor.offset + sensor.drift_rate * SECONDS / 2    # a drifting offset: its mean over the run
    out = Outcome()
    try:
        result = calibrate_wheel(rec, radius=RADIUS)
    except AccelrigError as exc:
        out.refused = str(exc)
        return out
    p = result.parameters
    for k, axis in enumerate("xyz"):
        out.errors[f"gain_{axis}"] = p["gain"].value[k] - sensor.gain[k]
        out.u[f"gain_{axis}"] = p["gain"].uncertainty[k]
        out.errors[f"offset_{axis}"] = p["offset"].value[k] - offset_truth[k]
        out.u[f"offset_{axis}"] = p["offset"].uncertainty[k]
    out.errors["tilt"] = p["tilt_deg"].value - TILT_DEG
    out.u["tilt"] = p["tilt_deg"].uncertainty
    if "coverage_factor" in result.details:   # the tool states its own k (Student's t on few batch-means blocks)
        out.k = dict.fromkeys(out.errors, float(result.details["coverage_factor"]))
    # the cross-axis prior is a statement about what the wheel cannot see, not a finding about this run
    out.warnings = [w for w in result.warnings if "does not observe cross-axis" not in w]
    return out


def _condition(name: str, rig_options: dict | None = None, sensor_options: dict | None = None,
               lossy: bool = False, refusal_must_say: tuple[str, ...] = (), note: str = "") -> Condition:
    def run(seed: int) -> Outcome:
        sensor = _sensor(**(sensor_options or {}))
        rec = simulate(_rig(**(rig_options or {})), sensor, SimClock(RATE), seconds=SECONDS, seed=seed)
        if lossy:
            rec = _lossy(rec, seed)
        return _judge(rec, sensor)

    return Condition("wheel", name, run, refusal_must_say, note)


# Coulomb + viscous: |w| = (w0 + c/k) e^{-kt} - c/k reaches 0 at t_stop = ln(1 + w0 k / c) / k
_W0 = 6.0
_COULOMB_STOP = _W0 * VISCOUS / np.expm1(VISCOUS * STOP_AT)

CONDITIONS = [
    _condition("white"),
    _condition("ar1 rho 0.9", sensor_options={"ar1": 0.9}),
    # noise slower than the record: 2-4 batch-means blocks (refused below residuals.MIN_HONEST_BLOCKS)
    _condition("ar1 rho 0.997", sensor_options={"ar1": 0.997}, refusal_must_say=("wanders more slowly",)),
    _condition("1/f", sensor_options={"flicker": 0.01}),
    _condition("drift 0.01 m/s^2", sensor_options={"drift_rate": np.full(3, 0.01 / SECONDS)}),
    _condition("5 % lost", lossy=True),
    _condition("stops at 75 s", rig_options={"friction": "coulomb-viscous", "omega": np.array([_W0, 0, 0, 0]),
                                             "coulomb": _COULOMB_STOP, "viscous": VISCOUS},
               refusal_must_say=("stop", "stopped", "model does not fit")),
    _condition("unbalanced", rig_options={"imbalance": 0.15, "imbalance_deg": 40.0},
               refusal_must_say=("imbalance", "unbalanced", "model does not fit")),
]
