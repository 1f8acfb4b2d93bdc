"""WheelProcedure.speed_trace(): the speed the operator sees while the wheel coasts, against the
simulator's true cubic speed law; and nothing before the wheel turns."""

import numpy as np
import pytest

from accelrig.procedures.wheel.procedure import WheelProcedure
from accelrig.procedures.wheel.settings import SETTINGS
from accelrig.recording import Recording
from accelrig.settings import values_from_texts
from accelrig.sim.device import simulate
from accelrig.sim.rigs.wheel import WheelRig
from accelrig.sim.sensor import SensorModel, SimClock

CHUNK = 37  # samples per feed, as a ring-buffer reader hands them over


def wheel_procedure() -> WheelProcedure:
    return WheelProcedure.create(values_from_texts(SETTINGS, {"radius": "0.28"}), {})


def test_speed_trace_follows_the_true_coast_down_as_the_data_come_in():
    rig = WheelRig(duration=40.0)
    rec = simulate(rig, SensorModel(), SimClock(), 40.0, seed=5)
    procedure = wheel_procedure()
    errors, said = [], []
    for i in range(0, len(rec), CHUNK):
        events = procedure.feed(rec.slice(i, i + CHUNK))
        said += [e.data["speed"] for e in events if "speed" in e.data]
        times, speeds = procedure.speed_trace()
        if times.size:
            true = np.abs(rig.motion(times)[1])
            errors.append((times[-1], np.max(np.abs(speeds / true - 1))))
        if procedure.done:
            break
    assert procedure.done
    # early looks see few turns (the circle's centre is rough): under 8 %; at the end, 0.5 %
    assert errors[0][0] > 2.0 and all(err < 0.08 for _, err in errors)
    assert errors[-1][1] < 0.005
    # the speed said in the events is the newest point of the trace at that look, and it decays
    assert said[-1] == pytest.approx(speeds[-1]) and said[-1] < said[0]
    assert np.all(np.diff(times) > 0)


def test_no_speed_trace_before_the_wheel_turns():
    procedure = wheel_procedure()
    t = np.arange(400) / 200.0
    still = np.tile([0.0, 0.0, 9.81], (t.size, 1)) + np.random.default_rng(1).normal(0, 0.02, (t.size, 3))
    events = procedure.feed(Recording(t, still))
    times, speeds = procedure.speed_trace()
    assert times.size == 0 and speeds.size == 0
    assert not [e for e in events if "speed" in e.data or "turns" in e.data]
