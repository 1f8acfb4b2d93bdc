"""The wheel at rest before the push (and after the stop) checks the coast's fit (issue 18, accelrig/procedures/wheel/rest.py).

The rest reads the offsets plus gravity at one unknown wheel angle: exact physics with no speed law in it, so a drift
of the offsets between the rest and the coast, or during the coast along the wheel's plane (where it looks like the
centripetal term), shows there."""

import numpy as np

from accelrig.geometry import rotation_xyz
from accelrig.procedures.wheel.fit import free_set
from accelrig.procedures.wheel.model import TABLE_I_OMEGA, WheelState
from accelrig.procedures.wheel.procedure import calibrate_wheel
from accelrig.procedures.wheel.rest import Rest, _at_rest, check_rests
from accelrig.recording import Recording, time_range
from accelrig.sim.device import simulate
from accelrig.sim.rigs.wheel import WheelRig
from accelrig.sim.sensor import SensorModel, SimClock

RATE = 200.0
GAIN = np.array([0.98, 1.0, 1.02])
OFFSET = np.array([0.3, -0.2, 0.25])
OMEGA = TABLE_I_OMEGA * 6.0 / 9.0


def _state() -> WheelState:
    return WheelState(0.3, OMEGA, np.deg2rad(45.0), 0.28, rotation_xyz(np.deg2rad([30.0, 20.0, 25.0])), GAIN, OFFSET)


def test_the_resting_angle_absorbs_one_direction_and_only_that_one():
    """A shift of the rest along gravity's tangent at the resting angle is the angle itself; along the wheel axis
    or gravity's own in-plane direction it is a miss the test sees."""
    state = _state()
    free = free_set(0.28, None)
    t = np.arange(0.0, 40.0, 1.0 / RATE)
    cov = np.eye(free.size) * 1e-12
    angle = np.deg2rad(40.0)
    at_rest = _at_rest(state, angle, 9.80665)
    tangent = _at_rest(state, angle + 1e-4, 9.80665) - _at_rest(state, angle - 1e-4, 9.80665)
    tangent /= np.linalg.norm(tangent)
    noise = np.random.default_rng(1).standard_normal((600, 3)) * 0.08
    t_rest = np.arange(600) / RATE
    sigma, tau = np.full(3, 0.08), np.ones(3)
    for shift, fires in ((0.0, False), (0.03, False), (-0.03, False)):
        rest = Rest("before the spin", t_rest, at_rest + noise + shift * tangent)
        found = check_rests([rest], t, state, cov, free, 1.0, sigma, tau)
        assert found.significant == fires
    axis = state.gain * state.rotation[:, 2]
    axis /= np.linalg.norm(axis)
    rest = Rest("before the spin", t_rest, at_rest + noise + 0.03 * axis)
    found = check_rests([rest], t, state, cov, free, 1.0, sigma, tau)
    assert found.significant and found.dof == 2
    assert abs(np.dot(found.rests[0]["read_off_m_s2"], axis) - 0.03) < 0.01
    assert abs(found.rests[0]["resting_angle_deg"] - 40.0) < 1.0


def test_a_record_with_a_rest_is_checked_against_it_and_a_drift_from_the_rest_is_warned_with_its_size():
    rig = WheelRig(radius=0.28, duration=40.0, omega=OMEGA, rest=3.0, push=2.0)
    sensor = SensorModel(offset=OFFSET, gain=GAIN, range_g=4.0,
                         noise_density=SensorModel.noise_density_for_sd(0.08, RATE))
    rec = simulate(rig, sensor, SimClock(RATE), seed=3)
    clean = calibrate_wheel(rec, radius=0.28)
    check = clean.quality["rest_check"]
    assert check["made"] and not check["significant"]
    assert check["rests"][0]["where"] == "before the spin" and check["rests"][0]["to_s"] < 3.0
    assert "checked against the wheel at rest before the spin" in clean.quality["uncertainty"]
    assert not any("wheel at rest read off" in w for w in clean.warnings)

    # the sensor's offsets moved by 0.04 m/s^2 between the rest and the push
    moved = rec.acc.copy()
    moved[rec.t - rec.t[0] < 3.0] -= 0.04 / np.sqrt(3.0)
    drifted = calibrate_wheel(Recording(rec.t, moved, rec.units, {}, rec.meta), radius=0.28)
    warning = [w for w in drifted.warnings if "wheel at rest read off" in w]
    assert len(warning) == 1 and "before the spin (0.0-" in warning[0]
    assert drifted.quality["rest_check"]["significant"]
    # the coast is the same, so the estimates are; u grows by the bias such a drift would make
    assert np.allclose(drifted.parameters["gain"].value, clean.parameters["gain"].value, rtol=1e-6)
    assert np.all(np.array(drifted.parameters["gain"].uncertainty) > 1.5 * np.array(clean.parameters["gain"].uncertainty))

    # calibrated from the coast alone there is no rest to check: said in the uncertainty line, not warned
    start = float(clean.settings["time_origin"].split("first sample of the free coast, ")[1].split(" s")[0])
    quiet = calibrate_wheel(time_range(rec, start, None), radius=0.28)
    assert quiet.quality["rest_check"]["made"] is False
    assert "not checked against the wheel at rest: the recording holds no rest" in quiet.quality["uncertainty"]
    assert not any("at rest" in w for w in quiet.warnings)


def test_the_papers_four_steps_are_checked_against_the_rest_too():
    """``--method paper`` has the same rest before the spin: the four steps' coast is set against it with their
    bootstrap covariance, and a drift from the rest is warned and taken into u as for the joint fit."""
    rig = WheelRig(radius=0.28, duration=15.0, omega=OMEGA, rest=3.0, push=2.0)
    sensor = SensorModel(offset=OFFSET, gain=GAIN, range_g=4.0,
                         noise_density=SensorModel.noise_density_for_sd(0.08, RATE))
    rec = simulate(rig, sensor, SimClock(RATE), seed=3)
    clean = calibrate_wheel(rec, radius=0.28, method="paper", bootstrap=5)
    check = clean.quality["rest_check"]
    assert check["made"] and not check["significant"]
    assert "checked against the wheel at rest before the spin" in clean.quality["uncertainty"]
    assert not any("wheel at rest read off" in w for w in clean.warnings)

    moved = rec.acc.copy()
    moved[rec.t - rec.t[0] < 3.0] -= 0.04 / np.sqrt(3.0)
    drifted = calibrate_wheel(Recording(rec.t, moved, rec.units, {}, rec.meta), radius=0.28, method="paper",
                              bootstrap=5)
    assert drifted.quality["rest_check"]["significant"]
    assert len([w for w in drifted.warnings if "wheel at rest read off" in w]) == 1
    assert np.allclose(drifted.parameters["gain"].value, clean.parameters["gain"].value, rtol=1e-6)
    # the same coast and bootstrap draws: u grows by the allowance alone
    ratio = np.array(drifted.parameters["gain"].uncertainty) / np.array(clean.parameters["gain"].uncertainty)
    assert np.all(ratio > 1.1)


def test_a_coast_given_with_start_is_still_checked_against_the_rest_before_it():
    """``--start`` at the coast (where quality.coast says it begins) leaves the rest out of the fit, not out of the check:
    the part before the start is handed over and its rest read."""
    rig = WheelRig(radius=0.28, duration=30.0, omega=OMEGA, rest=3.0, push=2.0)
    sensor = SensorModel(offset=OFFSET, gain=GAIN, range_g=4.0,
                         noise_density=SensorModel.noise_density_for_sd(0.08, RATE))
    rec = simulate(rig, sensor, SimClock(RATE), seed=4)
    moved = rec.acc.copy()
    moved[rec.t - rec.t[0] < 3.0] -= 0.04 / np.sqrt(3.0)
    drifted = Recording(rec.t, moved, rec.units, {}, rec.meta)
    start = 5.5
    alone = calibrate_wheel(time_range(drifted, start, None), radius=0.28)
    assert alone.quality["rest_check"]["made"] is False
    given = calibrate_wheel(time_range(drifted, start, None), radius=0.28, before=time_range(drifted, None, start))
    check = given.quality["rest_check"]
    assert check["made"] and check["significant"]
    assert check["rests"][0]["where"] == "before the spin" and check["rests"][0]["to_s"] < 3.0
    assert any("wheel at rest read off" in w for w in given.warnings)
    assert np.allclose(given.parameters["gain"].value, alone.parameters["gain"].value, rtol=1e-9)


def test_a_coast_without_a_rest_states_the_drift_it_could_miss_and_three_times_that_is_found():
    """No rest: the result states the in-plane drift the drift tests would miss half the time, and what it would do
    to the estimates (not added to u); a steady in-plane drift three times the stated size is found."""
    rig = WheelRig(radius=0.28, duration=30.0, omega=OMEGA)
    sensor = SensorModel(offset=OFFSET, gain=GAIN, range_g=4.0,
                         noise_density=SensorModel.noise_density_for_sd(0.08, RATE))
    rec = simulate(rig, sensor, SimClock(RATE), seed=3)
    bare = calibrate_wheel(rec, radius=0.28)
    unseen = bare.quality["rest_check"]["unseen_drift"]
    assert bare.quality["rest_check"]["made"] is False
    steady, settling = unseen["steady"], unseen["settling"]
    assert 0 < settling["size_m_s2"] < steady["size_m_s2"] < 1.0
    assert steady["largest_move_over_u"] > 3.0
    assert "u does not include it" in bare.quality["uncertainty"]
    # warned too: u leaves out a move the record cannot rule out, so the result must not read "no warnings"
    (no_rest,) = [w for w in bare.warnings if "drift" in w or "rest" in w]
    assert no_rest.startswith("the recording holds no rest before the push") and "record 5 s" in no_rest
    assert f"{steady['largest_move_over_u']:.2g} u" in no_rest or f"{settling['largest_move_over_u']:.2g} u" in no_rest

    # along the wheel's radius as the sensor sees it (Gamma R's first column)
    radial = GAIN * rotation_xyz(np.deg2rad(bare.parameters["misalignment_deg"].value))[:, 0]
    radial /= np.linalg.norm(radial)
    x = (rec.t - rec.t[0]) / (rec.t[-1] - rec.t[0])
    drifting = rec.acc + 3.0 * steady["size_m_s2"] * x[:, None] * radial[None, :]
    found = calibrate_wheel(Recording(rec.t, drifting, rec.units, {}, rec.meta), radius=0.28)
    assert any("offsets drifted" in w for w in found.warnings)


def test_a_speed_law_that_dips_below_its_last_speed_is_not_read_as_a_push():
    """Paper 002's Table I cubic slows to about 5.4 rad/s near 65 s and speeds up again to the end: the turns'
    circle centre passes the last turns' one and comes back.  A distance from it read that return as a push,
    and the fit dropped the first 43.5 s of a pure coast (5 of 30 bench draws lost their CRB).  Its speed-up over
    the last turns rises as fast as a late stroke: on draw 60 the last window read as a push, leaving a coast of one
    sample ("the recording holds 1 samples"); a push needs a coast after it."""
    from accelrig.procedures.wheel.checks import coasting_from
    from accelrig.procedures.wheel.model import (
        TABLE_I_GAIN,
        TABLE_I_MISALIGNMENT_DEG,
        TABLE_I_OFFSET,
        TABLE_I_THETA0_DEG,
        TABLE_I_TILT_DEG,
    )

    rig = WheelRig(radius=0.28, tilt_deg=TABLE_I_TILT_DEG, duration=90.0, omega=TABLE_I_OMEGA, friction="cubic",
                   misalignment_deg=TABLE_I_MISALIGNMENT_DEG, theta0_deg=TABLE_I_THETA0_DEG)
    sensor = SensorModel(offset=TABLE_I_OFFSET, gain=TABLE_I_GAIN, range_g=4.0,
                         noise_density=SensorModel.noise_density_for_sd(0.08, 200.0))
    # two of the bench's draws the unsigned height cut; on draw 60 the cubic's rise in the last turns read as a late
    # stroke and left a coast of one sample
    for seed in (13, 26, 60):
        rec = simulate(rig, sensor, SimClock(200.0), seconds=90.0, seed=seed)
        assert coasting_from(rec.t, rec.acc, 0.08, 1 / 200.0) is None
