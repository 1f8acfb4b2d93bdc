"""The static drift terms' Jacobian from the six-face fit's own response (issue 18, speed as promised).

The drift's rates and curvatures shift the pose means linearly, so the fit's derivative in them is its
derivative in the pose means along those shifts: ``fit_six_face(..., mean_shifts=...)`` gives it from its own
Jacobian at its solution (``_mean_response``), ``magnitude_z_response`` the lack-of-fit residuals' derivative,
where the procedure used to refit once per term.  Checked here against refits (finite differences)."""

from __future__ import annotations

import numpy as np
import pytest

from accelrig.estimation.gravity_fit import PoseStats, fit_six_face, magnitude_z, magnitude_z_response
from accelrig.geometry import FACES, face_down_direction, rotation_xyz
from accelrig.procedures.static import procedure as static_procedure
from accelrig.procedures.static.procedure import calibrate_static, detect_poses
from accelrig.sim.device import simulate
from accelrig.sim.rigs.static import StaticRig
from accelrig.sim.sensor import SensorModel, SimClock
from accelrig.units import STANDARD_GRAVITY

RATE = 200.0
G = STANDARD_GRAVITY


def _hand_held_poses(seed: int) -> tuple[list[PoseStats], np.ndarray]:
    """Fifteen poses (the six faces, each axis again, the opposite faces once more) of a sensor with a gain,
    misalignment and offset, each tilted about a degree from its face, the means noisy as 800 samples of
    0.03 m/s^2 make them: residuals of the size the fit sees, which its second-order term scales with.
    Also the poses' centre times (s)."""
    rng = np.random.default_rng(seed)
    k_true = np.diag([1.02, 0.98, 1.01]) @ rotation_xyz(np.radians([0.5, -0.3, 0.4]))
    offset = np.array([0.15, -0.1, 0.2])
    faces = [*FACES, "+z", "+x", "+y", "-z", "-x", "-y", "+z", "+x", "+y"]
    poses = []
    for k, face in enumerate(faces):
        down = face_down_direction(face) + np.radians(1.0) * rng.standard_normal(3)
        mean = k_true @ (-G * down / np.linalg.norm(down)) + offset + 0.03 / np.sqrt(800) * rng.standard_normal(3)
        poses.append(PoseStats(mean, 0.03, 800, face, f"pose {k + 1}"))
    return poses, 6.0 * np.arange(len(faces)) + 2.0


def _refit(poses, shift, **options):
    moved = [PoseStats(p.mean + s, p.cov, p.n, p.face, p.name) for p, s in zip(poses, shift, strict=True)]
    fit = fit_six_face(moved, "paper", 1.0, G, inflation="none", **options)
    return np.concatenate([fit.values, fit.correction.matrix.ravel(), fit.correction.bias])


def _drift_shifts(times: np.ndarray) -> np.ndarray:
    """A drift's columns as the procedure builds them: a rate and a curvature per axis."""
    middle = times.mean()
    bend = (times - times[0]) * (times - times[-1]) / 2.0
    unit = np.eye(3)
    return np.array([np.outer(times - middle, unit[k]) for k in range(3)] +
                    [np.outer(bend - bend.mean(), unit[k]) for k in range(3)])


@pytest.mark.parametrize("wander_var", [0.0, 1e-6])
def test_the_fits_response_to_the_pose_means_equals_refits(wander_var):
    """d [values, C, b] / d shift along each drift column, against central-difference refits whose step moves
    the means by 1e-4 m/s^2 (they agree with the response to 1e-6 to 1e-5 there; a step ten times smaller
    meets the refits' own convergence noise).  Tolerance 1e-4 of each column's largest entry: Gauss-Newton
    alone (J^T J, without the residuals' curvature) is off by about 1e-2 here and fails it."""
    poses, times = _hand_held_poses(3)
    shifts = _drift_shifts(times)
    fit = fit_six_face(poses, "paper", 1.0, G, inflation="none", wander_var=wander_var, mean_shifts=shifts)
    assert fit.mean_response.shape == (len(shifts), 9 + 12)
    for shift, response in zip(shifts, fit.mean_response, strict=True):
        step = 1e-4 / np.max(np.abs(shift))
        numeric = (_refit(poses, step * shift, wander_var=wander_var) -
                   _refit(poses, -step * shift, wander_var=wander_var)) / (2 * step)
        assert np.max(np.abs(response - numeric)) < 1e-4 * np.max(np.abs(numeric))
    # without shifts asked for, none is computed
    assert fit_six_face(poses, "paper", 1.0, G, inflation="none").mean_response is None


def test_the_magnitudes_z_response_equals_finite_differences():
    poses, times = _hand_held_poses(5)
    rng = np.random.default_rng(5)
    correction = np.concatenate([(np.eye(3) + 0.01 * rng.standard_normal((3, 3))).ravel(), [0.1, -0.1, 0.2]])
    d_correction = rng.standard_normal((4, 12)) * 1e-3
    d_means = np.concatenate([_drift_shifts(times)[:2], rng.standard_normal((2, len(poses), 3))])
    analytic = magnitude_z_response(correction, d_correction, poses, d_means, G, 1e-6)

    def z(k, s):
        moved = [PoseStats(p.mean + s * d, p.cov, p.n, p.face) for p, d in zip(poses, d_means[k], strict=True)]
        return magnitude_z(correction + s * d_correction[k], moved, G, 1e-6)[0]
    numeric = np.column_stack([(z(k, 1e-6) - z(k, -1e-6)) / 2e-6 for k in range(4)])
    assert np.max(np.abs(analytic - numeric)) < 1e-6 * np.max(np.abs(numeric))


def _drift_record(seed: int, order=None):
    rng = np.random.default_rng(seed)
    sensor = SensorModel.random(rng, noise_density=SensorModel.noise_density_for_sd(0.03, RATE),
                                drift_rate=np.array([2e-4, -1e-4, 3e-4]))
    rig = StaticRig(rng, tilt_deg=0.5, **({"order": order.split(",")} if order else {}))
    return simulate(rig, sensor, SimClock(RATE), seed=seed)


def _numbers(result) -> dict:
    drift = result.quality["noise"]["drift"]
    fitted = drift["shape"].get("fitted") or {}
    return {"terms": np.r_[drift["rate"], fitted.get("curvature", [])],
            "terms_u": np.r_[drift["rate_u"], fitted.get("curvature_u", [])],
            "estimate": np.r_[result.correction.matrix.ravel(), result.correction.bias],
            "u": np.r_[result.correction.matrix_uncertainty.ravel(), result.correction.bias_uncertainty]}


@pytest.mark.parametrize("order", [None, "+z,-z,+x,-x,+y,-y,+z,+x,+y,-z,-x,-y,+z"],
                         ids=["three rates, three curvatures", "three rates, one curvature, two allowances"])
def test_the_calibration_from_the_fits_response_equals_the_one_from_refits(monkeypatch, order):
    """End to end on a drifting record: the calibration with the drift terms' Jacobian from the fit's response
    equals the one with that Jacobian from refits (central differences along the same columns), the drift terms,
    C and b within 1e-4 of their u and every u within 1e-4 of itself (the refits' step leaves about 1e-6).  And
    the columns are the drift terms': a rate's is -(t_i - t_mid) on its axis, a curvature's sits on its axis."""
    rec = _drift_record(21, order)
    analytic = calibrate_static(rec, pose_flatness_deg=0.5, g_u=0.0)
    asked = []
    real_fit = static_procedure.fit_six_face

    def refitted(poses, *args, mean_shifts=None, **options):
        fit = real_fit(poses, *args, **options)
        if mean_shifts is not None:
            asked.append(mean_shifts)
            columns = []
            for shift in mean_shifts:
                step = 1e-4 / np.max(np.abs(shift))
                plus, minus = ([PoseStats(p.mean + s * step * d, p.cov, p.n, p.face, p.name)
                                for p, d in zip(poses, shift, strict=True)] for s in (1, -1))
                f_plus, f_minus = real_fit(plus, *args, **options), real_fit(minus, *args, **options)
                columns.append((np.r_[f_plus.values, f_plus.correction.matrix.ravel(), f_plus.correction.bias] -
                                np.r_[f_minus.values, f_minus.correction.matrix.ravel(), f_minus.correction.bias])
                               / (2 * step))
            fit.mean_response = np.array(columns)
        return fit

    def z_numeric(correction, d_correction, poses, d_means, g, extra_var):
        def z(k, s):
            moved = [PoseStats(p.mean + s * d, p.cov, p.n, p.face) for p, d in zip(poses, d_means[k], strict=True)]
            return magnitude_z(correction + s * d_correction[k], moved, g, extra_var)[0]
        return np.column_stack([(z(k, 1e-7) - z(k, -1e-7)) / 2e-7 for k in range(len(d_means))])

    monkeypatch.setattr(static_procedure, "fit_six_face", refitted)
    monkeypatch.setattr(static_procedure, "magnitude_z_response", z_numeric)
    numeric = calibrate_static(rec, pose_flatness_deg=0.5, g_u=0.0)
    a, n = _numbers(analytic), _numbers(numeric)
    assert len(a["terms"]) == (6 if order is None else 4)
    assert np.all(np.abs(a["terms"] - n["terms"]) < 1e-4 * n["terms_u"])
    assert np.all(np.abs(a["terms_u"] - n["terms_u"]) < 1e-4 * n["terms_u"])
    assert np.all(np.abs(a["estimate"] - n["estimate"]) <= 1e-4 * n["u"])
    assert np.all(np.abs(a["u"] - n["u"]) <= 1e-4 * n["u"])
    if order is not None:
        bend = analytic.quality["noise"]["drift"]["bend"]
        assert bend["allowance"]["on"] == ["x", "y"]      # the allowance's columns were used too

    # the columns: rate k is -(t_i - t_mid) e_k over the poses used (time order), curvature k only on axis k
    (shifts,) = asked
    poses = sorted(detect_poses(rec, pose_flatness_deg=0.5).poses, key=lambda p: p.start)
    centres = np.array([p.t.mean() for p in poses])
    middle = np.average(centres, weights=[len(p.t) for p in poses])
    for k in range(3):
        expected = np.zeros((len(poses), 3))
        expected[:, k] = -(centres - middle)
        np.testing.assert_allclose(shifts[k], expected, atol=1e-9)
    for column in shifts[3:]:
        axis = int(np.argmax(np.abs(column).sum(axis=0)))
        assert np.all(np.delete(column, axis, axis=1) == 0) and np.any(column[:, axis] != 0)


def test_the_drift_terms_cost_one_fit_not_one_per_term(monkeypatch):
    """The refits the response saves: of the calibration's six-face fits, the drift terms' Jacobian takes one
    (the one that gives the response), where it took one plus one per term (seven with three rates and three
    curvatures); the others are the result's own (the first fit, for the faces held again, and the one on the
    referred means: three in all on white noise)."""
    calls = []
    real_fit = static_procedure.fit_six_face

    def counted(*args, **options):
        calls.append((options.get("inflation", "repeatability"), options.get("mean_shifts") is not None))
        return real_fit(*args, **options)

    monkeypatch.setattr(static_procedure, "fit_six_face", counted)
    result = calibrate_static(_drift_record(21), pose_flatness_deg=0.5, g_u=0.0)
    assert result.quality["noise"]["drift"]["rate_from"] == "fit"
    assert len(result.quality["noise"]["drift"]["shape"]["fitted"]["axes"]) == 3      # 3 rates, 3 curvatures
    assert [c for c in calls if c[0] == "none"] == [("none", True)]
    assert len(calls) == 3
