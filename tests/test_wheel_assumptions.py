"""The wheel off the paper's ideal (issue 18): correlated noise, lost samples, a stopping or unbalanced
wheel, drifting offsets; the joint fit's start and its convergence checks; the bootstrap's progress.

Recordings come from accelrig.sim (the wheel's trajectory differentiated numerically, a sensor model
with coloured noise and drift), which shares no equation with the estimator.
"""

import contextlib

import numpy as np
import pytest

from accelrig.errors import CalibrationError
from accelrig.procedures.wheel import assumptions, paper, start
from accelrig.procedures.wheel import fit as wheel_fit
from accelrig.procedures.wheel import procedure as wheel_procedure
from accelrig.procedures.wheel.assumptions import check_residuals
from accelrig.procedures.wheel.checks import survey
from accelrig.procedures.wheel.fit import free_set, wheel_crb
from accelrig.procedures.wheel.model import TABLE_I_OMEGA, WheelState, model_and_jacobian
from accelrig.procedures.wheel.procedure import calibrate_wheel
from accelrig.recording import Recording
from accelrig.sim.device import simulate
from accelrig.sim.rigs.wheel import WheelRig
from accelrig.sim.sensor import SensorModel, SimClock

RATE = 200.0
SECONDS = 90.0
GAIN = np.array([0.98, 1.0, 1.02])
OFFSET = np.array([0.3, -0.2, 0.25])
OMEGA = TABLE_I_OMEGA * 6.0 / 9.0


def record(seed=0, rig_options=None, seconds=SECONDS, **sensor_options):
    rig = WheelRig(radius=0.28, duration=seconds, **({"omega": OMEGA} | (rig_options or {})))
    sensor = SensorModel(offset=OFFSET, gain=GAIN, range_g=4.0,
                         noise_density=SensorModel.noise_density_for_sd(0.08, RATE), **sensor_options)
    return simulate(rig, sensor, SimClock(RATE), seconds=seconds, seed=seed), rig


def z_scores(result, offset_truth=OFFSET):
    p = result.parameters
    z = (np.array(p["gain"].value) - GAIN) / np.array(p["gain"].uncertainty)
    return np.concatenate([z, (np.array(p["offset"].value) - offset_truth) / np.array(p["offset"].uncertainty)])


def exact_sd(rec, rig, result, walk_step=0.0):
    """The sd of the gains and offsets (offsets less the noise's mean over the run, which is part of the truth) of
    the model the checks ended with (the joint model and the structure they took in), linearised at the
    estimate, under the sensor's white noise (0.08) plus a random walk of ``walk_step`` per sample: the exact
    value u should be near, from the noise the simulation drew, not from residuals."""
    checks = result.quality["residual_checks"]
    p = result.parameters
    t = rec.t - rec.t[0]
    state = WheelState(np.deg2rad(p["theta0_deg"].value), [p[f"omega{k}"].value for k in range(4)],
                       np.deg2rad(p["tilt_deg"].value), 0.28, rig.rotation, np.array(p["gain"].value),
                       np.array(p["offset"].value))
    free = free_set(0.28, None)
    _, jac = model_and_jacobian(t, state, free, t[-1])
    added = assumptions._extra_columns(t, state, jac[:, :, 0], t[-1], 9.80665, segments=True)
    law, angle = assumptions.N_SPEED_LAW, assumptions.N_ANGLE
    causes = checks["angle_locked_causes"]
    taken = ((list(range(law)) if "speed law" in causes else []) + (list(range(law, angle)) if "wobble" in causes else [])
             + (list(range(angle, angle + 3)) + list(range(assumptions.N_EXTRA, assumptions.N_ALL))
                if "offset_drift_m_s2" in checks else []))
    x = np.concatenate([jac, added[:, :, taken]], axis=2)
    reported = [free.names.index(f"{kind}_{a}") for kind in ("gain", "offset") for a in "xyz"]
    # each estimate's weight on each sample's noise
    weights = np.einsum("ep,nkp->enk", np.linalg.inv(np.einsum("nkp,nkq->pq", x, x))[reported], x)
    weights[3:] -= np.eye(3)[:, None, :] / t.size
    walked = np.cumsum(weights[:, ::-1], axis=1)[:, ::-1]        # a walk's step counts in every later sample
    return np.sqrt(0.08**2 * np.sum(weights**2, axis=(1, 2)) + walk_step**2 * np.sum(walked**2, axis=(1, 2)))


def u_of(result):
    return np.concatenate([result.parameters["gain"].uncertainty, result.parameters["offset"].uncertainty])


def test_correlated_noise_widens_u_with_the_sandwich_and_says_so():
    rec, rig = record(seed=3, ar1=0.9)
    result = calibrate_wheel(rec, radius=0.28)
    checks = result.quality["residual_checks"]
    assert checks["noise"] == "correlated"
    assert "sandwich" in result.quality["uncertainty"] and "correlated" in result.quality["uncertainty"]
    # AR(1) flattens below its knee: the residuals show no power law (p about 0.95 here), so none is carried
    # below the blocks (an insignificant fit's exponent, carried over decades, made u 5-400x the white one)
    assert not any(law["found"] for law in checks["low_frequency_noise"])
    assert "slower than blocks" not in result.quality["uncertainty"]
    # u is several times the white-noise bound at the estimate (AR(1) 0.9: about sqrt(19))
    t = rec.t - rec.t[0]
    state = WheelState(np.deg2rad(result.parameters["theta0_deg"].value),
                       [result.parameters[f"omega{k}"].value for k in range(4)],
                       np.deg2rad(result.parameters["tilt_deg"].value), 0.28, rig.rotation, GAIN, OFFSET)
    crb = np.sqrt(np.diag(wheel_crb(t, state, free_set(0.28, None), result.quality["noise_sd"])))
    gains = [result.parameter_names.index(f"gain_{a}") for a in "xyz"]
    assert np.all(np.array(result.parameters["gain"].uncertainty) > 2.0 * crb[gains])
    assert np.all(np.abs(z_scores(result)) < 4)
    # correlated noise is not a mounting problem: no "poorly determined ... mounting" warning
    assert not any("mounting hides" in w for w in result.warnings)


def test_noise_slower_than_the_record_is_refused_naming_the_cause():
    """AR(1) 0.999 at 200 Hz (a memory of 5 s) in a 90 s coast: the blocks its correlation asks for fit once in the
    record.  Batch means over so few blocks gave u of any size (held-out: errors of 26 u, warned "record longer");
    below residuals.MIN_HONEST_BLOCKS the wheel refuses, saying why and what to do."""
    rec, _ = record(seed=1, ar1=0.999)
    with pytest.raises(CalibrationError, match="wanders more slowly than the record can measure") as caught:
        calibrate_wheel(rec, radius=0.28)
    assert "times longer" in caught.value.hint and "settle" in caught.value.hint


def test_few_blocks_widen_the_coverage_factor_to_students_t():
    """AR(1) 0.997 leaves 5 batch-means blocks here: u stands, but its expanded form takes Student's t on their 4
    degrees of freedom (k 2.87, not 2), and the result says so in the uncertainty line, a warning and details."""
    rec, _ = record(seed=0, ar1=0.997)
    result = calibrate_wheel(rec, radius=0.28)
    blocks = result.quality["residual_checks"]["batch_means"]
    assert blocks["blocks"] == 5 and blocks["dof"] == 4
    assert result.details["coverage_factor"] == pytest.approx(2.87, abs=0.01)
    assert result.details["coverage_dof"] == 4
    assert "Student's t, k = 2.87" in result.quality["uncertainty"]
    assert any("only 5 independent blocks" in w and "k = 2.87" in w for w in result.warnings)
    assert np.all(np.abs(z_scores(result)) < result.details["coverage_factor"])
    # five blocks leave no room for the model's own tests (their p is NaN): said, not read as a pass
    (untested,) = [w for w in result.warnings if w.startswith("the model could not be tested")]
    assert "speed law" in untested and "wobble" in untested


def test_scattered_lost_samples_only_cost_data():
    rec, _ = record(seed=4)
    keep = np.random.default_rng(4).random(rec.t.size) >= 0.05
    keep[0] = keep[-1] = True
    lossy = Recording(rec.t[keep], rec.acc[keep], rec.units, {}, rec.meta)
    result = calibrate_wheel(lossy, radius=0.28)
    assert np.all(np.abs(z_scores(result)) < 4)
    assert any("gap(s) in the timestamps" in w for w in result.warnings)


def test_a_wheel_that_stops_is_fitted_on_its_spin_and_the_result_says_so():
    viscous = 0.01
    coulomb = 6.0 * viscous / np.expm1(viscous * 75.0)       # stops at 75 s of the 90
    rec, _ = record(seed=5, rig_options={"friction": "coulomb-viscous", "omega": np.array([6.0, 0, 0, 0]),
                                         "coulomb": coulomb, "viscous": viscous})
    result = calibrate_wheel(rec, radius=0.28)
    # a stop is what friction does: said with the checks (quality.coast), not as a warning
    assert not any("stood still" in w or "stopped turning" in w for w in result.warnings)
    assert "stood still" in result.quality["coast"]["note"]
    assert 70.0 < result.quality["duration_s"] < 76.0


def test_a_record_that_starts_at_rest_and_pushed_is_fitted_on_its_free_coast():
    """The wizard's record: the wheel rests 3 s, a hand spins it up over 2 s, then it coasts.  The speed law holds
    only for the coast, so the fit starts after the push and says so; --start there calibrates alike."""
    from accelrig.recording import time_range

    rig = WheelRig(radius=0.28, duration=40.0, omega=OMEGA, rest=3.0, push=2.0)
    sensor = SensorModel(offset=OFFSET, gain=GAIN, range_g=4.0,
                         noise_density=SensorModel.noise_density_for_sd(0.08, RATE))
    rec = simulate(rig, sensor, SimClock(RATE), seed=3)
    result = calibrate_wheel(rec, radius=0.28)
    # the record the wizard asks for: the cut is said with the checks, not as a warning
    from accelrig.report.checks import check_lines

    assert not any("pushed by hand" in w for w in result.warnings)
    coast = result.quality["coast"]
    start = coast["from_s"]
    assert 5.0 <= start <= 8.0   # the push ends at 5 s; the cut leaves a margin of a turn and half a window
    assert ("coast", coast["note"]) in check_lines(result.to_json_dict()) and "pushed by hand" in coast["note"]
    assert np.all(np.abs(z_scores(result)) < 4)
    quiet = calibrate_wheel(time_range(rec, start, None), radius=0.28)
    assert "coast" not in quiet.quality
    assert np.allclose(quiet.parameters["gain"].value, result.parameters["gain"].value, rtol=1e-9)


def test_a_drift_taken_in_by_a_false_alarm_keeps_its_move_in_u():
    """Stress audit: on a clean wheel that stops, the drift test fires in about 1 run in 100 (its level), and the
    drift taken in then moves every estimate by 2-3 of the larger model's u, along the direction a drift on the
    radius shares with the gains: the take-in happens exactly when the drift's estimate is large.  Seed 100003
    (the stress benchmark's first run) moved them by 2.4 u; u now includes the move."""
    viscous = 0.01
    coulomb = 6.0 * viscous / np.expm1(viscous * 75.0)
    rec, _ = record(seed=100003, rig_options={"friction": "coulomb-viscous", "omega": np.array([6.0, 0, 0, 0]),
                                              "coulomb": coulomb, "viscous": viscous})
    result = calibrate_wheel(rec, radius=0.28)
    checks = result.quality["residual_checks"]
    assert checks["offset_drift_test"]["significant"] and checks["offset_drift_move_over_u"] > 2
    assert "u includes the move taking the drift in made" in result.quality["uncertainty"]
    assert np.all(np.abs(z_scores(result)) < 2)


def test_an_unbalanced_wheel_is_seen_and_taken_in():
    rec, rig = record(seed=6, rig_options={"imbalance": 0.15, "imbalance_deg": 40.0})
    result = calibrate_wheel(rec, radius=0.28)
    assert any("did not follow the model's smooth speed law" in w for w in result.warnings)
    assert result.quality["residual_checks"]["speed_law_test"]["significant"]
    assert "speed swings" in result.quality["uncertainty"]
    # taken in fully (fitted with the model, not one linearised step), the structure leaves white residuals:
    # it is not mistaken for correlated noise, and the gains and offsets lose its bias
    assert result.quality["residual_checks"]["noise"] == "white"
    assert np.all(np.abs(z_scores(result)) < 3)
    # u is what the model with the swing in costs, not more: the residuals before the take-in held the swing, and
    # batch means over them counted it once more as noise (u up to 3.2x the exact sd here, stress u/sd 3.99)
    ratio = u_of(result) / exact_sd(rec, rig, result)
    assert np.all((ratio > 0.7) & (ratio < 1.4)), ratio


def test_a_grossly_unbalanced_wheel_is_refused_with_the_cause():
    rec, _ = record(seed=7, rig_options={"imbalance": 1.5, "imbalance_deg": 40.0})
    with pytest.raises(CalibrationError) as err:
        calibrate_wheel(rec, radius=0.28)
    assert "speed law" in str(err.value) and "balance the wheel" in str(err.value)


def air_drag_coast(sd, seed, seconds=90.0, rate=RATE, omega0=9.0, slow_to=0.45, tilt_deg=45.0):
    """A coast under air drag and dry friction, w' = -a - b w^2, half of each at the start, in closed form (no
    cubic speed law can follow it), read by a sensor of white noise ``sd``."""
    t = np.arange(int(seconds * rate)) / rate
    # with a = b w0^2: w = w0 tan(pi/4 - k t), k = a / w0, and w(seconds) = slow_to w0
    k = (np.pi / 4 - np.arctan(slow_to)) / seconds
    b = k / omega0
    w = omega0 * np.tan(np.pi / 4 - k * t)
    theta = 0.5 + np.log(np.cos(np.pi / 4 - k * t) / np.cos(np.pi / 4)) / b
    dw = -k * omega0 - b * w**2
    ga, gz = 9.80665 * np.sin(np.radians(tilt_deg)), 9.80665 * np.cos(np.radians(tilt_deg))
    bench = np.stack([0.28 * w**2 + ga * np.cos(theta), 0.28 * dw + ga * np.sin(theta), np.full(t.size, gz)], axis=1)
    rotation = WheelRig().rotation
    raw = OFFSET + bench @ rotation.T * GAIN + np.random.default_rng(seed).normal(0.0, sd, (t.size, 3))
    return Recording(t, raw, meta={"range_g": 4.0})


def test_a_quiet_sensor_on_an_air_drag_coast_is_taken_in_not_refused():
    """Held-out audit: the speed law under air drag was refused for a quiet sensor (0.02 m/s^2, 10 runs of 10) and
    accepted for a noisier one (0.03), because the refusal compared the structure with the fitted noise sd, which
    holds the structure too (for a quiet sensor the ratio tends to one).  The take-in holds this structure (its
    second-order remainder is a small share of u), so the result stands, warned, with its errors within u."""
    result = calibrate_wheel(air_drag_coast(0.02, seed=31), radius=0.28)
    checks = result.quality["residual_checks"]
    assert "speed law" in checks["angle_locked_causes"]
    assert any("smooth speed law" in w for w in result.warnings)
    assert checks["angle_locked_second_order_over_u"] < 0.5
    assert np.all(np.abs(z_scores(result)) < 3)


def test_drifting_offsets_are_taken_in_and_reported():
    drift = np.array([0.02, -0.01, 0.015])
    rec, _ = record(seed=8, drift_rate=drift / SECONDS)
    result = calibrate_wheel(rec, radius=0.28)
    assert any("offsets drifted" in w for w in result.warnings)
    found = np.array(result.quality["residual_checks"]["offset_drift_m_s2"])
    assert np.allclose(found, drift, atol=0.012)
    assert np.all(np.abs(z_scores(result, OFFSET + drift / 2)) < 4)


def test_an_offset_that_settles_is_taken_in_whatever_its_shape():
    """Held-out audit: an offset warming up (exponential settling) is no straight line; what a fitted line leaves
    changes slowly, like the centripetal term, and moved the gains by 3-5 u.  A drift found is taken in as a line
    and an offset per segment of the run, so u of the gains holds it."""
    rec, _ = record(seed=12)
    x = (rec.t - rec.t[0]) / SECONDS
    size = np.array([0.02, -0.015, 0.01])
    settle = size[None, :] * (-np.expm1(-x / 0.25) / -np.expm1(-1 / 0.25))[:, None]
    warmed = Recording(rec.t, rec.acc + settle, rec.units, dict(rec.channels), dict(rec.meta))
    result = calibrate_wheel(warmed, radius=0.28)
    assert any("offsets drifted" in w and "8 parts of the run" in w for w in result.warnings)
    assert "8 parts of the run" in result.quality["uncertainty"]
    assert np.all(np.abs(z_scores(result, OFFSET + settle.mean(axis=0))) < 3)


def test_a_random_walk_taken_in_as_drift_keeps_the_noise_in_u():
    """Held-out audit: a random walk in the offsets passes for a drift; taken in as an offset per segment, what
    is left looks white at short lags, and the white covariance after it left the gains 3-4 u off (coverage 55 %
    over 25 runs).  Correlated residuals before the take-in keep the sandwich and the power law below its blocks."""
    rec, rig = record(seed=4)
    steps = np.random.default_rng(1004).normal(0.0, 0.005 / np.sqrt(RATE), rec.acc.shape)
    walk = np.cumsum(steps, axis=0)          # 0.005 m/s^2 per sqrt(s)
    walked = Recording(rec.t, rec.acc + walk, rec.units, dict(rec.channels), dict(rec.meta))
    result = calibrate_wheel(walked, radius=0.28)
    assert any("offsets drifted" in w for w in result.warnings)
    assert "were correlated in time before the structure was taken in" in result.quality["uncertainty"]
    assert np.all(np.abs(z_scores(result, OFFSET + walk.mean(axis=0))[:3]) < 3)
    # u of the gains is the walk's own effect on them (the sandwich and the power law below its blocks, from the
    # residuals of the model reported), not that of the residuals before the offsets per segment took part of it
    ratio = (u_of(result) / exact_sd(rec, rig, result, 0.005 / np.sqrt(RATE)))[:3]
    assert np.all((ratio > 0.7) & (ratio < 1.6)), ratio


def test_a_wobbling_wheel_is_named_as_play_not_as_the_speed_law():
    """Held-out audit: a wheel whose axis nods once per turn (bearing play) was warned as a speed law the wheel did
    not follow, and its gains were covered in 27 % of runs.  Gravity tipping towards the axis with the wheel angle is
    no speed law: the check names the wobble, says how large, and takes it in."""
    rec, _ = record(seed=21, rig_options={"wobble_deg": 0.1})
    result = calibrate_wheel(rec, radius=0.28)
    checks = result.quality["residual_checks"]
    assert checks["angle_locked_causes"] == ["wobble"]
    said = [w for w in result.warnings if "locked to the wheel angle" in w]
    assert len(said) == 1 and "bearing play" in said[0] and "smooth speed law" not in said[0]
    # the nod's twice-per-turn part, seen from the wheel: about half the nod, rms
    assert 0.02 < checks["wobble_deg_rms"] < 0.1
    assert "wobble" in result.quality["uncertainty"]
    assert np.all(np.abs(z_scores(result)) < 3)


def test_a_gross_wobble_is_refused_naming_the_bearing():
    rec, _ = record(seed=22, rig_options={"wobble_deg": 1.5})
    with pytest.raises(CalibrationError) as err:
        calibrate_wheel(rec, radius=0.28)
    assert "bearing play" in str(err.value) and "bearing" in err.value.hint


def nodding_coast(nod_deg, seed, sd=0.08, seconds=90.0, rate=RATE, tilt_deg=45.0, swing=0.0):
    """A coast whose axis nods in space once per turn (bearing play): the tilt swings by ``nod_deg`` cos(theta),
    so gravity's share along the axis and across it changes with the wheel angle while the centripetal and
    tangential terms stay where they are; a slowing spin w = 9 - 0.045 t, white noise ``sd``.  With ``swing``, the
    wheel is also unbalanced: its angle runs ahead and behind by ``swing`` (9 / w)^2 cos(theta) rad (a steady
    torque locked to the angle moves it by more as the wheel slows), its speed and acceleration with it."""
    t = np.arange(int(seconds * rate)) / rate
    w = 9.0 - 0.045 * t
    theta = 1.0 + 9.0 * t - 0.0225 * t**2
    tangential = np.full(t.size, -0.045)
    if swing:
        theta = theta + swing * (9.0 / w) ** 2 * np.cos(theta)
        w = np.gradient(theta, t, edge_order=2)
        tangential = np.gradient(w, t, edge_order=2)
    alpha = np.radians(tilt_deg + nod_deg * np.cos(theta))
    bench = np.stack([0.28 * w**2 + 9.80665 * np.sin(alpha) * np.cos(theta),
                      0.28 * tangential + 9.80665 * np.sin(alpha) * np.sin(theta), 9.80665 * np.cos(alpha)], axis=1)
    raw = OFFSET + bench @ WheelRig().rotation.T * GAIN + np.random.default_rng(seed).normal(0.0, sd, (t.size, 3))
    return Recording(t, raw, meta={"range_g": 4.0})


@pytest.mark.parametrize("nod_deg", [0.5, 1.5])
def test_an_axis_that_nods_is_refused_naming_the_bearing(nod_deg):
    """Held-out audit: an axis nodding 0.5 deg per turn was taken in as a wobble and the offsets were covered in 79 %
    of runs (the nod's other half turns gravity as the mounting does and was left in the offsets); at 1.5 deg the
    nod read as correlated noise, whose long blocks left no test to find it (covered in 34 %, not warned)."""
    with pytest.raises(CalibrationError) as err:
        calibrate_wheel(nodding_coast(nod_deg, seed=41), radius=0.28)
    said = str(err.value)
    # what was seen (a wobble turning with the wheel at twice its angle), then what it would be as a nod
    assert "turning with it at twice its angle" in said and "an axis that nods about" in said
    assert "deg once per turn" in said and "cones round against the wheel" in said
    seen = float(said.split("an axis that nods about ")[1].split(" deg")[0])
    assert abs(seen - nod_deg) < 0.15 * nod_deg
    assert "check the bearing" in err.value.hint


def test_a_slight_nod_widens_u_by_its_unseen_half():
    """A nod of 0.1 deg is taken in: the half the wobble shows in the model, the other half's possible move in u."""
    result = calibrate_wheel(nodding_coast(0.1, seed=42), radius=0.28)
    checks = result.quality["residual_checks"]
    assert "wobble" in checks["angle_locked_causes"]
    assert 0.06 < checks["axis_nod_deg"] < 0.15
    assert 0.1 < checks["axis_nod_move_over_u"] < assumptions.MAX_NOD_MOVE
    assert any("turns with the wheel at twice its angle, as an axis that nods about" in w and "once per turn" in w
               for w in result.warnings)
    assert np.all(np.abs(z_scores(result)) < 3)


def test_a_steady_nod_on_an_unbalanced_wheel_is_not_read_as_changing(monkeypatch):
    """A steady nod's unseen half (gravity turned, the centripetal term spared) leaves in the residuals what changes
    with w^2; with the speed law taken in beside the wobble, the test of the nod's change read it as a nod growing
    over the run, and refused steady nods as play that opens above some speed (held-out steady 0.1 deg nods: 8 of
    120 refused at 1 %, the nod 0.05 deg larger at the end on average).  The unseen half is now projected out of
    that test.  Here (quiet, so what the test reads is the structure, not the noise) main read 0.09 -> 0.16 deg,
    p = 3e-5; the checks are read directly, since the steady nod itself is refused on its size at this noise."""
    checks = checks_read(monkeypatch, nodding_coast(0.1, seed=2, sd=0.03, swing=0.003))
    assert checks.causes == ["speed law", "wobble"]
    assert not checks.nod_change.significant
    start, end = checks.nod_ends_deg
    assert abs(end - start) < 0.03 and 0.07 < 0.5 * (start + end) < 0.15


def checks_read(monkeypatch, record):
    """The assumption checks the wheel calibration read on ``record`` at radius 0.28 (whether it then refused or
    not): for tests of a check itself, where the record is refused on another ground."""
    seen = {}

    def spy(*args, **kwargs):
        seen["checks"] = checks = check_residuals(*args, **kwargs)
        return checks

    monkeypatch.setattr(wheel_procedure, "check_residuals", spy)
    with contextlib.suppress(CalibrationError):
        calibrate_wheel(record, radius=0.28)
    return seen["checks"]


def test_a_steady_nod_is_not_read_as_an_offset_drift(monkeypatch):
    """A steady nod's unseen half (gravity turned, the centripetal term spared) is no column of the fit; left in the
    residuals it changes with w^2, slowly, and the drift tests read it as the offsets drifting: held-out steady 0.1
    deg nods took a drift in on 14 % of records, each warned as offsets that drifted.  The drift tests now project
    the unseen half out once a wobble is found.  Quiet (0.03 m/s^2), so what the test reads is the nod: main read a
    drift at p = 0.003; the checks are read directly, since the nod itself is refused on its size at this noise (on
    main it was accepted: the drift taken in had widened u)."""
    checks = checks_read(monkeypatch, nodding_coast(0.1, seed=1, sd=0.03))
    assert checks.causes == ["wobble"]
    assert checks.drift.p_value > 0.05 and checks.drift_shape.p_value > 0.05
    assert checks.drift_per_axis is None


def test_white_noise_keeps_the_crb_and_stays_quiet():
    rec, _ = record(seed=9)
    result = calibrate_wheel(rec, radius=0.28)
    assert result.quality["residual_checks"]["noise"] == "white"
    assert "CRB" in result.quality["uncertainty"]
    # the cross-axis prior is stated with the checks (quality.cross_axis); the one warning is that the record has
    # no rest (what the coast alone cannot see)
    assert [w for w in result.warnings if not w.startswith("the recording holds no rest")] == []
    assert "axis_nod_deg" not in result.quality["residual_checks"]


def test_start_is_closed_form_and_failures_are_checked(monkeypatch):
    rec, rig = record(seed=10)
    t, v = rec.t - rec.t[0], rec.acc

    def no_search(*args, **kwargs):
        raise AssertionError("the joint start ran the four-step search")

    monkeypatch.setattr(start, "paper_calibrate", no_search)
    steps = start.joint_start(t, v, survey(t, v), 0.28, None)
    assert np.allclose(steps.state.gain, GAIN, atol=0.01)
    assert abs(np.rad2deg(steps.state.tilt) - 45.0) < 1.0
    # the speed-law fit of step B checks its own success
    real = paper.least_squares

    def failing(*args, **kwargs):
        sol = real(*args, **kwargs)
        sol.success, sol.message = False, "maximum number of function evaluations exceeded"
        return sol

    monkeypatch.setattr(paper, "least_squares", failing)
    with pytest.raises(CalibrationError, match="speed law could not be fitted"):
        start.joint_start(t, v, survey(t, v), 0.28, None)
    monkeypatch.setattr(paper, "least_squares", real)
    # and the joint fit says when it did not converge
    monkeypatch.setattr(wheel_fit, "MAX_ITERATIONS", 1)
    with pytest.raises(CalibrationError, match="did not converge"):
        wheel_fit.joint_fit(t, v, steps.state, free_set(0.28, None))


def test_the_paper_bootstrap_reports_its_progress():
    rec, _ = record(seed=12, seconds=30.0)
    heard = []
    calibrate_wheel(rec, radius=0.28, method="paper", bootstrap=5, on_progress=heard.append)
    assert heard[-1] == "bootstrap run 5 of 5" and len(heard) == 5


def test_unbalanced_rig_swings_its_speed_once_per_turn():
    rig = WheelRig(duration=20.0, omega=OMEGA, imbalance=0.2, imbalance_deg=0.0)
    smooth = WheelRig(duration=20.0, omega=OMEGA)
    t = np.linspace(0.0, 20.0, 4001)
    theta, rate = rig.motion(t)
    swing = rate - smooth.motion(t)[1]
    # energy: w dw = -b sin(theta) dtheta, so the speed swings by about +-b / w around the smooth law
    assert 0.5 * 0.2 / 6.0 < np.max(np.abs(swing)) < 3 * 0.2 / 4.0
    assert np.corrcoef(swing[1000:], np.cos(theta[1000:]))[0, 1] > 0.8


def test_an_axis_that_nods_twice_per_turn_is_named_and_taken_in():
    """An axis that nods twice per turn (a bearing worn out of round) is, seen from the wheel, a wobble at once and
    three times its angle.  Harmonic 3 was outside the wobble family: its structure leaked into harmonics 1-2 and
    was warned as a speed swing and a wobble of 0.8 deg rms "as an axis nodding about 0.04 deg once per turn" (a
    0.1 deg nod twice per turn, with the sensor's own axial motion).  Now the wobble at 3x is tested with the rest
    projected out, named with its size, and taken in with the wobble."""
    rec, _ = record(seed=23, rig_options={"wobble_deg": 0.1, "wobble_turns": 2})
    result = calibrate_wheel(rec, radius=0.28)
    said = [w for w in result.warnings if "three times its angle" in w]
    assert len(said) == 1 and "nods twice per turn" in said[0]
    checks = result.quality["residual_checks"]
    assert checks["wobble_3x_test"]["significant"]
    assert "wobble at 3x" in checks["angle_locked_causes"]
    # half the nod turns at three times the wheel angle
    assert 0.03 < checks["wobble_3x_deg"] < 0.07
    assert "three times" in result.quality["uncertainty"]
    assert np.all(np.abs(z_scores(result)) < 3)



def test_a_nod_that_appears_only_above_some_speed_is_refused_as_such():
    """Play that opens only when the wheel runs fast: the nod's unseen half then changes with the speed as the
    centripetal term does, which no steady allowance holds (held-out nod of 0.2 deg above 7 rad/s: warned as a
    speed swing and a drift, covered in 85 %, u/sd 0.72).  The wobble's change over the run is tested once the
    structure is in, and the refusal names it."""
    rec, _ = record(seed=31, rig_options={"wobble_deg": 0.1, "wobble_above": 4.5})
    with pytest.raises(CalibrationError) as err:
        calibrate_wheel(rec, radius=0.28)
    said = str(err.value)
    assert "changes its size over the run" in said and "above some speed" in said
    start, end = (float(said.split(k)[1].split(" deg")[0]) for k in ("a nod of about ", "at the start, "))
    assert start > 2 * end
    assert "below the speed where the wobble appears" in err.value.hint
