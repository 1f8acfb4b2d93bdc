"""Stress conditions of the static calibration (issue 18), for bench_stress.py.

Each run: a random imperfect sensor (``SensorModel.random``) at the simulator's defaults (200 Hz, the
MPU-9250's 300 ug/sqrt(Hz): about 0.03 m/s^2 per sample), the six faces held 4 s each (hand tilt 0.1 deg per component, stated
flatness 0.1 deg) with handling
between them (``accelrig.sim.rigs.static``, as sim://static), then the procedure's own code path as
``accelrig calibrate static`` runs it (``calibrate_static``: pose detection, the checks, the default
model).  Judged: the 12 entries of the canonical correction C, b against the simulator's truth, with
the u the result states.  Under a drifting offset the truth's b is the offset at the middle of the
used still samples (what any average over the run estimates); the drift itself must be warned.
"""

from __future__ import annotations

import numpy as np
from bench_stress import Condition, Outcome

from accelrig.errors import AccelrigError

RATE = 200.0
HOLD = 4.0
SIGMA = 0.03                      # m/s^2 per sample, the simulator's default density at 200 Hz
# The hand's tilt (sd per component, degrees) and the flatness the operator states: a careful placement
# against a square, so that the noise conditions are judged where the noise, not the flatness, sets u.
TILT = 0.1
# 1/f noise with its corner (where it equals the white density, SIGMA / sqrt(RATE / 2)) at 1 Hz: a poor MEMS
# part (Allan floor about 3.5 mm/s^2); the MPU-9250's corner is nearer 0.01 Hz.
FLICKER = 0.003
# The other rows follow the wizard's sequence (the rig's default: six faces, then one of each axis
# again); these hold each face once, as a recording made without the wizard may.
SIX_ONCE = ("+z", "-z", "+x", "-x", "+y", "-y")


def _run(seed: int, sensor_options: dict | None = None, rig_options: dict | None = None,
         rig_g: float | None = None, drift_total: float = 0.0, values: dict | None = None) -> Outcome:
    from accelrig.procedures.static.procedure import calibrate_static
    from accelrig.sim.device import simulate
    from accelrig.sim.rigs.static import StaticRig
    from accelrig.sim.sensor import SensorModel, SimClock
    from accelrig.units import STANDARD_GRAVITY

    rng = np.random.default_rng(seed)
    options = {"noise_density": SensorModel.noise_density_for_sd(SIGMA, RATE), **(sensor_options or {})}
    sensor = SensorModel.random(rng, **options)
    rig = StaticRig(rng, hold=HOLD, g=rig_g or STANDARD_GRAVITY, **{"tilt_deg": TILT, **(rig_options or {})})
    if drift_total:
        direction = rng.normal(size=3)
        sensor.drift_rate = drift_total / rig.duration * direction / np.linalg.norm(direction)
    seed_noise = int(rng.integers(2**31))
    # one block, so that the same seed draws the same white noise with or without the 1/f part
    rec = simulate(rig, sensor, SimClock(RATE), seed=seed_noise, block_size=10**7)
    outcome = Outcome()
    try:
        result = calibrate_static(rec, **{"pose_flatness_deg": TILT, **(values or {})})
    except AccelrigError as exc:
        outcome.refused = str(exc)
        return outcome
    c_true = sensor.correction()
    bias_true = c_true.bias
    times = result.arrays["pose_times"]
    if drift_total:
        bias_true = bias_true + sensor.drift_rate * float(np.mean(times))
    if sensor.flicker:
        # 1/f noise has components slower than the run (corners down to 1e-4 Hz): over the run they are an
        # offset, the sensor's offset during this calibration.  The truth is the offset plus the mean of the
        # 1/f part over the still samples used (the same run without it gives the white part to remove).
        from dataclasses import replace

        white = simulate(rig, replace(sensor, flicker=0.0), SimClock(RATE), seed=seed_noise, block_size=10**7)
        used = np.zeros(len(rec.t), dtype=bool)
        for start, stop in times:
            used |= (rec.t >= start) & (rec.t <= stop)
        bias_true = bias_true + (rec.acc[used] - white.acc[used]).mean(axis=0)
    corr = result.correction
    est = np.concatenate([corr.matrix.ravel(), corr.bias])
    truth = np.concatenate([c_true.matrix.ravel(), bias_true])
    u = np.sqrt(np.clip(np.diag(corr.covariance), 0.0, None))
    names = [f"C_{r}{c}" for r in "xyz" for c in "xyz"] + ["b_x", "b_y", "b_z"]
    for name, e, t, s in zip(names, est, truth, u, strict=True):
        outcome.errors[name] = float(e - t)
        outcome.u[name] = float(s)
    outcome.warnings = list(result.warnings)
    return outcome


CONDITIONS = [
    Condition("static", "white (baseline)", lambda s: _run(s)),
    Condition("static", "AR(1) rho 0.9", lambda s: _run(s, {"ar1": 0.9}),
              refusal_must_say=("correlated",)),
    Condition("static", "1/f noise", lambda s: _run(s, {"flicker": FLICKER}),
              refusal_must_say=("correlated", "drift")),
    Condition("static", "axis noise 0.03/0.04/0.08", lambda s: _run(s, {"axis_noise": [1.0, 4 / 3, 8 / 3]})),
    Condition("static", "local g 9.81, default --g", lambda s: _run(s, rig_g=9.81)),
    Condition("static", "local g 9.81, --g 9.81", lambda s: _run(s, rig_g=9.81, values={"g": 9.81})),
    Condition("static", "drift 0.01 m/s^2 over the run", lambda s: _run(s, drift_total=0.01),
              refusal_must_say=("drift",)),
    Condition("static", "white, every face held once", lambda s: _run(s, rig_options={"order": SIX_ONCE})),
    Condition("static", "drift 0.01, every face held once", lambda s: _run(
        s, drift_total=0.01, rig_options={"order": SIX_ONCE}), refusal_must_say=("drift",)),
    Condition("static", "drift 0.01, ends on the first face only", lambda s: _run(
        s, drift_total=0.01, rig_options={"order": ("+z", "-z", "+x", "-x", "+y", "-y", "+z")}),
              refusal_must_say=("drift",)),
    Condition("static", "hand tilt 1 deg", lambda s: _run(s, rig_options={"tilt_deg": 1.0},
                                                       values={"pose_flatness_deg": 1.0})),
]
