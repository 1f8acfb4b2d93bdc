"""Six-face estimators against truth and the CRB: paper model (VP and Nelder-Mead), affine model, auto."""

import numpy as np
import pytest

from accelrig.geometry import FACES, rotation_xyz
from accelrig.procedures.static.fit import (
    AFFINE_NAMES,
    PAPER_NAMES,
    PoseData,
    face_reference,
    fit_model,
    paper_params_to_correction,
    static_crb,
)
from accelrig.procedures.static.procedure import calibrate_static
from accelrig.sim.device import simulate
from accelrig.sim.rigs.static import StaticRig, sensor_with_response
from accelrig.sim.sensor import SensorModel, SimClock


def _paper_truth(rng):
    return np.concatenate([np.deg2rad(rng.uniform(-1, 1, 3)), 1 + rng.uniform(-0.02, 0.02, 3),
                           rng.uniform(-0.4, 0.4, 3)])


def _correction(params):
    v = paper_params_to_correction(params)
    return v[:9].reshape(3, 3), v[9:]


def _synthetic_poses(c_mat, bias, rng, n=800, sigma=0.05, faces=FACES):
    """Samples drawn straight from the measurement model raw = C^-1 f + b + noise."""
    k = np.linalg.inv(c_mat)
    means, ss = [], []
    for face in faces:
        x = k @ face_reference(face) + bias + sigma * rng.standard_normal((n, 3))
        means.append(x.mean(axis=0))
        ss.append(np.sum((x - x.mean(axis=0)) ** 2))
    return PoseData(list(faces), means, [n] * len(faces), ss)


def test_paper_model_vp_and_nelder_mead_recover_truth_within_their_uncertainty():
    rng = np.random.default_rng(11)
    truth = _paper_truth(rng)
    data = _synthetic_poses(*_correction(truth), rng)
    vp = fit_model(data, "paper", "vp")
    nm = fit_model(data, "paper", "paper")
    assert vp.names == PAPER_NAMES
    assert np.all(np.abs(vp.values - truth) < 4 * vp.uncertainty)
    # the paper's scheme lands near the same optimum, within a fraction of the uncertainty
    assert np.all(np.abs(nm.values - vp.values) < 0.5 * vp.uncertainty)
    assert vp.n_evaluations < 20 < nm.n_evaluations
    # the reported uncertainty is the CRB of this design (with the fitted sigma)
    bound = np.sqrt(np.diag(static_crb("paper", truth, list(FACES), 800, data.noise_sd)))
    assert np.allclose(vp.uncertainty, bound, rtol=0.02)


def test_affine_model_recovers_a_non_orthogonal_sensor_the_paper_model_cannot():
    rng = np.random.default_rng(12)
    sensor = SensorModel.random(rng, nonorthogonality=np.deg2rad([0.8, -0.6, 0.5]))
    corr = sensor.correction()
    data = _synthetic_poses(corr.matrix, corr.bias, rng)
    affine = fit_model(data, "affine")
    paper = fit_model(data, "paper")
    assert affine.names == AFFINE_NAMES
    truth = np.concatenate([corr.matrix.ravel(), corr.bias])
    assert np.all(np.abs(affine.values - truth) < 4 * affine.uncertainty)
    assert paper.p_value < 1e-6 and affine.p_value > 1e-3
    assert affine.aic < paper.aic


def test_monte_carlo_default_fit_is_efficient_and_its_intervals_cover():
    """Small Monte Carlo (the benchmark runs the full-size one through the simulator)."""
    rng = np.random.default_rng(13)
    truth = _paper_truth(rng)
    c_mat, bias = _correction(truth)
    errors, covered = [], []
    for _ in range(150):
        fit = fit_model(_synthetic_poses(c_mat, bias, rng, n=400), "paper", "vp")
        errors.append(fit.values - truth)
        covered.append(np.abs(fit.values - truth) <= 2 * fit.uncertainty)
    bound = np.sqrt(np.diag(static_crb("paper", truth, list(FACES), 400, 0.05)))
    ratio = np.std(errors, axis=0) / bound
    assert np.all((ratio > 0.75) & (ratio < 1.25)), ratio
    assert 0.9 < np.mean(covered) < 0.99
    assert np.all(np.abs(np.mean(errors, axis=0)) < 4 * bound / np.sqrt(150))


def test_crb_offsets_use_all_six_faces():
    """Every face informs every offset: sd(b) = sigma / sqrt(6 n), not the sqrt(2 n) of +- pairs."""
    cov = static_crb("affine", np.concatenate([np.eye(3).ravel(), np.zeros(3)]), list(FACES), 800, 0.05)
    assert np.allclose(np.sqrt(np.diag(cov))[9:], 0.05 / np.sqrt(6 * 800), rtol=1e-6)


def test_repeated_faces_add_data_and_shrink_the_uncertainty():
    rng = np.random.default_rng(14)
    truth = _paper_truth(rng)
    c_mat, bias = _correction(truth)
    six = fit_model(_synthetic_poses(c_mat, bias, rng), "paper")
    twelve = fit_model(_synthetic_poses(c_mat, bias, rng, faces=FACES + FACES), "paper")
    assert np.all(twelve.uncertainty < 0.8 * six.uncertainty)


def test_end_to_end_on_the_simulator_matches_truth():
    rng = np.random.default_rng(15)
    truth = _paper_truth(rng)
    c_mat, bias = _correction(truth)
    sensor = sensor_with_response(np.linalg.inv(c_mat), bias,
                                  noise_density=SensorModel.noise_density_for_sd(0.05, 200.0))
    rig = StaticRig(np.random.default_rng(16))
    rec = simulate(rig, sensor, SimClock(200.0), seed=17)
    result = calibrate_static(rec, model="paper")
    values = np.array([result.parameters[n].value for n in PAPER_NAMES])
    unc = np.array([result.parameters[n].uncertainty for n in PAPER_NAMES])
    assert np.all(np.abs(values - truth) < 4 * unc)
    assert np.all(np.abs(result.correction.matrix - c_mat) < 4 * result.correction.matrix_uncertainty + 1e-12)
    assert np.all(np.abs(result.correction.bias - bias) < 4 * result.correction.bias_uncertainty)
    assert result.quality["noise_sd"] == pytest.approx(0.05, rel=0.05)
    # six faces, three again twice, their opposites once more
    assert result.quality["n_poses"] == 15 and len(result.quality["faces"]) == 15
    # calibrated poses read g on the face axis
    for row in result.quality["faces"]:
        assert row["residual_norm"] < 5 * 0.05 / np.sqrt(row["n"]) * 3


def test_paper_method_is_refused_for_the_affine_model():
    rng = np.random.default_rng(18)
    sensor = SensorModel.random(rng)
    rec = simulate(StaticRig(np.random.default_rng(1)), sensor, SimClock(200.0), seed=2)
    from accelrig.errors import CalibrationError
    with pytest.raises(CalibrationError, match="only for the 9-parameter model"):
        calibrate_static(rec, model="affine", method="paper")


def test_rotation_convention_matches_the_paper_listing():
    """Listing 1: R = rotz(z) * roty(y) * rotx(x)."""
    a, b, c = 0.1, -0.2, 0.3
    rx = np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])
    ry = np.array([[np.cos(b), 0, np.sin(b)], [0, 1, 0], [-np.sin(b), 0, np.cos(b)]])
    rz = np.array([[np.cos(c), -np.sin(c), 0], [np.sin(c), np.cos(c), 0], [0, 0, 1]])
    assert np.allclose(rotation_xyz([a, b, c]), rz @ ry @ rx)


def test_analytic_rotation_derivatives_match_central_differences():
    from accelrig.estimation import numerical_jacobian
    from accelrig.geometry import rotation_xyz_derivatives

    a = np.array([0.1, -0.3, 0.5])
    numeric = numerical_jacobian(lambda x: rotation_xyz(x).ravel(), a).T.reshape(3, 3, 3)
    assert np.allclose(rotation_xyz_derivatives(a), numeric, atol=1e-9)
