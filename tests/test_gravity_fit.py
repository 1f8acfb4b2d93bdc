"""Issue 12 estimation core: multi-position and tilt-robust six-face fits, on real recordings and Monte Carlo.

Real recordings (tests/data, with licences) are judged against the published tools' answers; the
Monte Carlo draws pose statistics from first principles (tests/benchmarks/bench_static_tilt.py) and
judges coverage and the bound.  Thresholds are the issue's, not fitted to these files.
"""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest

from accelrig.errors import CalibrationError
from accelrig.estimation.gravity_fit import (
    DEFAULT_POSE_FLATNESS_DEG,
    FACE_REFUSE_SD,
    PoseStats,
    check_faces,
    face_tilts,
    fit_ferraris,
    fit_multiposition,
    fit_six_face,
    multiposition_crb,
    six_face_crb,
    upper_gauge,
)
from accelrig.geometry import face_down_direction
from accelrig.procedures.static.procedure import detect_poses
from accelrig.recording import load_recording

DATA = Path(__file__).parent / "data"
IMUCAL_G = 9.81                # imucal's FerrarisCalibration default grav
IMUTK_G = 9.81744              # imu_tk's g for its Xsens data
IMUCAL_OFFSETS = np.array([0.53711742, -0.61620299, 0.39886734])   # imucal 2.6.0 on the annotated sections
IMUCAL_IMUTK_AGREEMENT = 0.0024   # README: imucal and imu_tk agree on the offsets to this (m/s^2)

_spec = importlib.util.spec_from_file_location("bench_static_tilt", Path(__file__).parent / "benchmarks" / "bench_static_tilt.py")
bench = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(bench)


def _poses(name: str) -> list[PoseStats]:
    proc = detect_poses(load_recording(DATA / name))   # every still pose, any angle
    return [PoseStats.from_samples(p.samples, p.face, f"pose {k + 1}") for k, p in enumerate(proc.poses)]


@pytest.fixture(scope="module")
def imucal_poses():
    return _poses("imucal-ferraris-session.csv")


@pytest.fixture(scope="module")
def xsens_poses():
    return _poses("imutk-xsens-multipose.csv")


@pytest.fixture(scope="module")
def imucal_annotated():
    rec = load_recording(DATA / "imucal-ferraris-session.csv")
    ann = json.loads((DATA / "imucal-ferraris-session-annotation.json").read_text())
    faces = {"x_p": "-x", "x_a": "+x", "y_p": "-y", "y_a": "+y", "z_p": "-z", "z_a": "+z"}
    return [PoseStats.from_samples(rec.to_si().acc[ann[k]["start"]:ann[k]["end"]], f, k) for k, f in faces.items()]


# ------------------------------------------------------------------ real: imucal's hand-held Ferraris session

@pytest.mark.parametrize("model", ["affine", "paper"])
def test_imucal_session_six_face(imucal_poses, imucal_annotated, model):
    assert len(imucal_poses) == 13
    fit = fit_six_face(imucal_poses, model, g=IMUCAL_G)
    # every still pose's calibrated gravity magnitude within 0.005 m/s^2 of g
    assert np.max(np.abs(fit.magnitude_residuals)) < 0.005
    # offsets agree with imucal's within 3 combined standard uncertainties; imucal states none, so its u is
    # its own formula's noise propagation on its sections plus the per-pose repeatability this session shows
    ref = fit_ferraris(imucal_annotated, g=IMUCAL_G, repeatability_sd=fit.repeatability_sd)
    assert np.allclose(ref.correction.bias, IMUCAL_OFFSETS, atol=1e-7)       # our pairing is imucal's formula
    u = fit.correction.bias_uncertainty
    u_c = np.hypot(u, ref.correction.bias_uncertainty)
    assert np.all(np.abs(fit.correction.bias - IMUCAL_OFFSETS) <= 3 * u_c)
    # every u at least what the imucal / imu_tk disagreement justifies: |d| <= 2 sqrt(2) u for two methods
    assert np.all(u >= IMUCAL_IMUTK_AGREEMENT / (2 * np.sqrt(2)))
    # ... and at least the sd of the offsets across the methods run on this session
    others = [fit_six_face(imucal_poses, m, g=IMUCAL_G).correction.bias for m in ("affine", "paper")]
    spread = np.std(np.vstack(others + [fit_ferraris(imucal_poses, g=IMUCAL_G).correction.bias, IMUCAL_OFFSETS]),
                    axis=0, ddof=1)
    assert np.all(u >= spread)
    # the lack of fit was seen and said
    assert fit.inflated and "repeatability" in fit.uncertainty_source


def test_imucal_session_exact_faces_is_what_issue_12_reports(imucal_poses):
    """The exact-face model (today's) is off imucal by many of its noise-only uncertainties."""
    fit = fit_six_face(imucal_poses, "affine", pose_flatness_deg=0.0, g=IMUCAL_G, inflation="none")
    assert np.max(np.abs(fit.correction.bias - IMUCAL_OFFSETS) / fit.correction.bias_uncertainty) > 20
    assert fit.p_value < 1e-6


def test_imucal_session_refused_by_multiposition(imucal_poses):
    with pytest.raises(CalibrationError, match=r"6 distinct orientations.*at least 9"):
        fit_multiposition(imucal_poses, g=IMUCAL_G)


def test_imucal_session_faces_pass_classifier(imucal_poses):
    tilts = check_faces(imucal_poses)
    assert [t.face for t in tilts] == [p.face for p in imucal_poses]
    assert max(t.angle_deg for t in tilts) < FACE_REFUSE_SD * DEFAULT_POSE_FLATNESS_DEG


# ------------------------------------------------------------------ real: imu_tk's Xsens multi-position data

def test_xsens_multiposition(xsens_poses):
    fit = fit_multiposition(xsens_poses, g=IMUTK_G)
    assert len(xsens_poses) >= 30
    assert np.max(np.abs(fit.magnitude_residuals)) < 0.005
    c = fit.correction
    assert np.all(c.matrix[[1, 2, 2], [0, 0, 1]] == 0) and np.all(c.covariance[[3, 6, 7]] == 0)
    # the nominal scale in the file is a guess: the fit finds a gain 8 % off it, stated to < 1e-3
    assert np.all(np.abs(np.diag(c.matrix) - 1) > 0.05) and np.all(c.matrix_uncertainty[[0, 1, 2], [0, 1, 2]] < 1e-3)
    assert np.all(c.bias_uncertainty < 0.005)


def test_xsens_refused_by_six_face_classifier(xsens_poses):
    with pytest.raises(CalibrationError, match=r"pose \d+ is \d+\.\d degrees from [+-][xyz].*multi-position"):
        check_faces(xsens_poses)
    off = [t for t in face_tilts(xsens_poses, IMUTK_G) if t.angle_deg > FACE_REFUSE_SD * DEFAULT_POSE_FLATNESS_DEG]
    assert len(off) >= 10


# ------------------------------------------------------------------ synthetic checks

def test_multiposition_refuses_a_great_circle():
    rng = np.random.default_rng(3)
    angles = rng.uniform(0, 2 * np.pi, 14)
    poses = [PoseStats(9.80665 * np.array([np.cos(a), np.sin(a), 0.0]) + 0.1, 0.02, 400) for a in angles]
    with pytest.raises(CalibrationError, match="span the sphere"):
        fit_multiposition(poses)


def test_multiposition_exact_and_crb_matches_covariance():
    rng = np.random.default_rng(4)
    c_true, b_true, _ = bench.draw_truth(rng)
    dirs = rng.standard_normal((20, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    means = np.linalg.solve(c_true, (9.80665 * dirs).T).T + b_true
    fit = fit_multiposition([PoseStats(m, 0.02, 400) for m in means])
    assert np.allclose(fit.correction.matrix, upper_gauge(c_true), atol=1e-9)
    assert np.allclose(fit.correction.bias, b_true, atol=1e-9)
    crb = multiposition_crb(c_true, b_true, dirs, 400, 0.02)
    assert np.allclose(crb, fit.correction.covariance, rtol=1e-6, atol=1e-15)


def test_six_face_flatness_zero_is_exact_face_and_tilts_do_not_bias_offsets():
    rng = np.random.default_rng(5)
    c_true, b_true, paper = bench.draw_truth(rng)
    poses, _ = bench.draw_poses(rng, c_true, b_true, "faces", 0.0, 0.0)
    exact = fit_six_face(poses, "paper", 0.0)
    assert exact.model == "exact-face paper" and exact.tilts_deg.max() == 0
    crb = six_face_crb("paper", c_true, b_true, bench.FACE_LIST, bench.N, bench.SIGMA, 0.0, params=paper)
    assert np.allclose(np.sqrt(np.diag(crb))[9:], exact.correction.bias_uncertainty, rtol=0.05)


def test_six_face_bound_with_drift_rates_matches_the_linear_model_written_out():
    """The drift rates as nuisance columns: with exact faces the affine model is linear, raw = K f + o + r (t - t0),
    so the offsets' bound is the o block of sigma^2 (X^T W X)^-1 with X written out here; fitting a rate costs its
    axis precision and leaves an axis without one as it was."""
    faces = ["+z", "-z", "+x", "-x", "+y", "-y", "+z", "+x", "+y"]
    counts = np.array([800, 700, 800, 900, 800, 750, 800, 820, 790], dtype=float)
    times = np.array([2, 8, 13, 19, 24, 29, 35, 41, 46], dtype=float)
    sigma, g, axes = 0.05, 9.81, [0, 2]
    rows, weights = [], []
    for face, n, t in zip(faces, counts, times, strict=True):
        f = -g * face_down_direction(face)
        for j in range(3):
            row = np.zeros(12 + len(axes))
            row[3 * j:3 * j + 3], row[9 + j] = f, 1.0
            if j in axes:
                row[12 + axes.index(j)] = t - np.average(times, weights=counts)
            rows.append(row)
            weights.append(n / sigma**2)
    x = np.array(rows)
    expected = np.linalg.inv(x.T @ (np.array(weights)[:, None] * x))[9:12, 9:12]
    bound = six_face_crb("affine", np.eye(3), np.zeros(3), faces, counts, sigma, 0.0, g,
                         drift_times=times, drift_axes=axes)
    assert np.allclose(bound[9:, 9:], expected, rtol=1e-6)
    without = six_face_crb("affine", np.eye(3), np.zeros(3), faces, counts, sigma, 0.0, g)
    assert np.all(np.diag(bound)[[9, 11]] > 1.001 * np.diag(without)[[9, 11]])
    assert np.isclose(bound[10, 10], without[10, 10], rtol=1e-9)   # y's rate is not fitted


def test_six_face_bound_with_a_drift_curvature_matches_the_linear_model_written_out():
    """The twelve-hold sequence: each axis's face held three times, so each axis's drift has a rate and a
    curvature, kappa (q(t) - mean q) with q(t) = (t - t_a)(t - t_b) / 2 through that face's first and last holds."""
    faces = ["+z", "-z", "+x", "-x", "+y", "-y", "+z", "+x", "+y", "+z", "+x", "+y"]
    counts = np.array([800, 700, 800, 900, 800, 750, 800, 820, 790, 810, 780, 800], dtype=float)
    times = np.array([2, 8, 13, 19, 24, 29, 35, 41, 46, 52, 57, 63], dtype=float)
    sigma, g, axes = 0.05, 9.81, [0, 1, 2]
    anchors = {2: (2.0, 52.0), 0: (13.0, 57.0), 1: (24.0, 63.0)}
    mean_w = lambda v: np.average(v, weights=counts)  # noqa: E731
    q = {k: (times - a) * (times - b) / 2 for k, (a, b) in anchors.items()}
    rows, weights = [], []
    for i, (face, n, t) in enumerate(zip(faces, counts, times, strict=True)):
        f = -g * face_down_direction(face)
        for j in range(3):
            row = np.zeros(18)
            row[3 * j:3 * j + 3], row[9 + j] = f, 1.0
            row[12 + j] = t - mean_w(times)
            row[15 + j] = q[j][i] - mean_w(q[j])
            rows.append(row)
            weights.append(n / sigma**2)
    x = np.array(rows)
    expected = np.linalg.inv(x.T @ (np.array(weights)[:, None] * x))[9:12, 9:12]
    bound = six_face_crb("affine", np.eye(3), np.zeros(3), faces, counts, sigma, 0.0, g,
                         drift_times=times, drift_axes=axes, curvature_anchors=anchors)
    assert np.allclose(bound[9:, 9:], expected, rtol=1e-6)
    rates_only = six_face_crb("affine", np.eye(3), np.zeros(3), faces, counts, sigma, 0.0, g,
                              drift_times=times, drift_axes=axes)
    assert np.all(np.diag(bound)[9:] > 1.001 * np.diag(rates_only)[9:])


@pytest.mark.parametrize("scenario, models", [
    ("hand 0.3", ["six-face affine", "six-face paper"]),
    ("hand 1", ["six-face paper"]),
    ("arbitrary", ["multi-position"]),
])
def test_monte_carlo_small(scenario, models):
    """A fast version of the benchmark: coverage of +-2u and the bound hold for the tilt-robust models;
    the paper's exact-face model and Ferraris pairing fail on the same tilted poses."""
    checked = models + (["exact-face paper", "ferraris"] if scenario.startswith("hand") else [])
    result = bench.run_scenario(scenario, 120, seed=11, models=checked)
    for model in models:
        s = bench.summarise(result[model])
        cover = np.concatenate([s["cover_C"], s["cover_b"]])
        assert 0.90 <= cover.mean() <= 0.985, (model, cover)
        assert cover.min() >= 0.84, (model, cover)
        assert np.all(s["ratio_b"] < 1.3) and np.all(s["ratio_b"] > 0.75), (model, s["ratio_b"])
    if scenario.startswith("hand"):
        exact = bench.summarise(result["exact-face paper"])
        assert exact["ratio_b"].min() > 10                     # the offsets are off by tens of their bound
        ferraris = bench.summarise(result["ferraris"])
        assert ferraris["cover_C"].min() < 0.9                 # noise-only u on the cross terms does not cover


def test_classifier_does_not_count_the_sensors_misalignment_as_tilt():
    """A sensor mounted 1.5 degrees off in its housing on level faces: the common rotation is the model's R,
    so even a stated flatness of 0.1 degree (a 0.5-degree gate) lets every face through."""
    rng = np.random.default_rng(3)
    c_true = bench._rz(np.radians(1.5)) @ bench._ry(np.radians(-1.2)) @ bench._rx(np.radians(0.8))
    poses, _ = bench.draw_poses(rng, c_true, np.array([0.3, -0.2, 0.4]), "faces", 0.0, 0.05)
    tilts = check_faces(poses, 0.1)
    assert max(t.angle_deg for t in tilts) < 0.3
    assert [t.face for t in tilts] == bench.FACE_LIST


@pytest.mark.parametrize("model, seen", [("affine", 6), ("paper", 9)])
def test_tilt_test_counts_only_the_tilt_combinations_the_faces_see(model, seen):
    rng = np.random.default_rng(8)
    c_true, b_true, _ = bench.draw_truth(rng)
    poses, _ = bench.draw_poses(rng, c_true, b_true, "faces", 0.0, 1.0)
    fit = fit_six_face(poses, model, 1.0)
    assert fit.extra["tilt_dof"] == pytest.approx(seen, abs=0.3)


def test_a_table_tilted_more_than_stated_widens_the_flatness_and_says_so():
    rng = np.random.default_rng(12)
    warned = 0
    for _ in range(10):
        c_true, b_true, _ = bench.draw_truth(rng)
        poses, _ = bench.draw_poses(rng, c_true, b_true, "faces", 3.0, 0.2)
        for model in ("affine", "paper"):
            fit = fit_six_face(poses, model, 1.0)
            assert fit.pose_flatness_deg > 1.5 and "observed flatness" in fit.uncertainty_source
            warned += bool(fit.extra["notes"])
    assert warned >= 15
