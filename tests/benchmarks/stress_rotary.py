"""Stress conditions of the rotary bench (issue 18), for bench_stress.py.

Each run: paper 001's bench simulated (accelrig.sim: the disk's motion differentiated
numerically, an LSM6DSR-like sensor at +-8 g with 0.03 m/s^2 white noise per sample, its clock
0.2-0.5 % off the nominal 1660 Hz), one test of the paper's plan with a random motor phase,
20 s, the encoder log at 1 kHz on the accurate clock; then ``analyse_test`` on the MEMS
recording as ``accelrig calibrate rotary --mems M.csv --encoder E.csv`` loads it (a file without
a ``t`` column: times k / nominal rate).  The radius is known to 1 um and the bench's geometry
is perfect here (its own 0.3 % radius and 0.035 % geometry terms would hide every noise effect);
the true radius is the nominal.

Judged: the sample rate (truth: the clock's true rate; not in the loss conditions, where the
"rate" of a record with holes is not one number) and the sensitivities of the tangential and
radial axes (truth: the sensor's true response, sim.rigs.rotary.true_sensitivity).
"""

from __future__ import annotations

import numpy as np
from bench_stress import Condition, Outcome

from accelrig.errors import AccelrigError
from accelrig.procedures.rotary.bench import EncoderLog, RotarySetup, analyse_test
from accelrig.procedures.rotary.settings import PAPER_PLAN
from accelrig.recording import Recording
from accelrig.sim.campaign import paper_sensor
from accelrig.sim.device import simulate
from accelrig.sim.rigs.rotary import RotaryRig, encoder_samples, true_sensitivity
from accelrig.sim.sensor import SimClock

NOMINAL_RATE = 1660.0
SECONDS = 20.0
NOISE_SD = 0.03


def _lose(rec: Recording, rng: np.random.Generator, share: float, burst: int, trace: str = "") -> Recording:
    """Drop ``share`` of the samples, in runs of 1..burst.  ``trace``: "" forgets where (times
    k / nominal rate of the kept samples), "times" keeps each kept sample's time on the nominal
    grid, "gaps" writes the recorder's gap list into the metadata."""
    n = len(rec)
    lost = np.zeros(n, dtype=bool)
    while lost.mean() < share:
        start = int(rng.integers(n))
        lost[start: start + int(rng.integers(1, burst + 1))] = True
    keep = ~lost
    m = int(keep.sum())
    meta = dict(rec.meta)
    t = np.arange(m) / NOMINAL_RATE
    if trace == "times":
        t = np.flatnonzero(keep) / NOMINAL_RATE
    elif trace == "gaps":
        starts = np.flatnonzero(np.diff(np.concatenate([[0], lost.astype(int)])) == 1)
        ends = np.flatnonzero(np.diff(np.concatenate([lost.astype(int), [0]])) == -1) + 1
        before = np.cumsum(keep) - keep      # kept samples before each position
        meta["gaps"] = [{"index": int(before[a]), "missing": int(b - a)} for a, b in zip(starts, ends, strict=True)]
    return Recording(t, rec.acc[keep], rec.units, {k: v[keep] for k, v in rec.channels.items()}, meta)


def _lose_every(rec: Recording, every: int) -> Recording:
    """Drop every ``every``-th sample (a steady link loss), without a trace: times k / nominal rate."""
    keep = np.arange(len(rec)) % every != every - 1
    return Recording(np.arange(int(keep.sum())) / NOMINAL_RATE, rec.acc[keep], rec.units,
                     {k: v[keep] for k, v in rec.channels.items()}, dict(rec.meta))


def _run(seed: int, sensor_options: dict | None = None, loss: tuple | None = None, every: int | None = None,
         clock_error: float | None = None) -> Outcome:
    rng = np.random.default_rng(seed)
    frequency, amplitude = PAPER_PLAN[rng.integers(len(PAPER_PLAN))]
    sensor = paper_sensor(rng, noise_sd=NOISE_SD, rate=NOMINAL_RATE)
    for name, value in (sensor_options or {}).items():
        setattr(sensor, name, value)
    drawn = float(rng.uniform(0.002, 0.005)) * rng.choice([-1, 1])
    clock = SimClock(NOMINAL_RATE, drawn if clock_error is None else clock_error, 0.0)
    rig = RotaryRig(radius=0.170, frequency=frequency, amplitude_deg=amplitude, duration=SECONDS,
                    phase=float(rng.uniform(-np.pi, np.pi)))
    rec = simulate(rig, sensor, clock, seconds=SECONDS, seed=int(rng.integers(2**31)), units="counts")
    truth = true_sensitivity(rec.meta["truth"])
    if loss is not None:
        rec = _lose(rec, rng, *loss)
    elif every is not None:
        rec = _lose_every(rec, every)
    else:
        rec.t = np.arange(len(rec)) / NOMINAL_RATE   # a file without timestamps
    rec.channels = {}
    enc = EncoderLog(**encoder_samples(rig, SECONDS, 1000.0))
    outcome = Outcome()
    try:
        test = analyse_test(rec, enc, "x", "y", NOMINAL_RATE,
                            setup=RotarySetup(radius_uncertainty=1e-6, geometry_uncertainty=0.0))
    except AccelrigError as exc:
        outcome.refused = str(exc)
        return outcome
    if (loss is None or loss[2:]) and every is None:
        outcome.errors["rate"] = test.sample_rate.value - clock.true_rate
        outcome.u["rate"] = test.sample_rate.uncertainty
    for axis, s in test.sensitivity.items():
        outcome.errors[f"S_{axis}"] = s.value - truth[axis]
        outcome.u[f"S_{axis}"] = s.uncertainty
    outcome.warnings = list(test.warnings)
    return outcome


CONDITIONS = [
    Condition("rotary", "white", lambda s: _run(s)),
    Condition("rotary", "AR(1) rho 0.9", lambda s: _run(s, {"ar1": 0.9})),
    Condition("rotary", "1/f (0.003 at 1 Hz)", lambda s: _run(s, {"flicker": 0.003})),
    Condition("rotary", "5 % samples lost, scattered, no timestamps", lambda s: _run(s, loss=(0.05, 1)),
              refusal_must_say=("lost", "missing")),
    Condition("rotary", "5 % samples lost in bursts, no timestamps", lambda s: _run(s, loss=(0.05, 40)),
              refusal_must_say=("lost", "missing")),
    Condition("rotary", "5 % lost in bursts, with the recorder's gap list", lambda s: _run(s, loss=(0.05, 40, "gaps")),
              refusal_must_say=("lost", "missing")),
    Condition("rotary", "5 % lost, scattered, with timestamps", lambda s: _run(s, loss=(0.05, 1, "times")),
              refusal_must_say=("lost", "missing")),
    Condition("rotary", "every 20th sample lost (steady), no timestamps", lambda s: _run(s, every=20),
              refusal_must_say=("lost", "missing")),
    Condition("rotary", "clock 0.4 % slow, nothing lost", lambda s: _run(s, clock_error=-0.004)),
]
