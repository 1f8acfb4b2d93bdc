"""Estimation core: CRB, propagation, variable projection (fits judged against truth and the CRB)."""

import numpy as np
import pytest

from accelrig.errors import CalibrationError
from accelrig.estimation import (
    crb_covariance,
    crb_sd,
    numerical_jacobian,
    propagate_covariance,
    varpro,
)


def test_crb_of_a_mean_is_sigma_squared_over_n():
    jac = np.ones((50, 1))
    assert crb_covariance(jac, 0.2)[0, 0] == pytest.approx(0.2**2 / 50)


def test_crb_of_a_straight_line_matches_the_textbook_formula():
    t = np.linspace(0.0, 3.0, 31)
    jac = np.column_stack([np.ones_like(t), t])
    sigma = 0.1
    cov = crb_covariance(jac, sigma)
    sxx = np.sum((t - t.mean()) ** 2)
    assert cov[1, 1] == pytest.approx(sigma**2 / sxx)
    assert cov[0, 0] == pytest.approx(sigma**2 * (1 / t.size + t.mean() ** 2 / sxx))


def test_per_row_sigma_weights_rows():
    jac = np.ones((2, 1))
    # two measurements with sd 1 and 2: inverse-variance weighting gives 1 / (1 + 1/4)
    assert crb_covariance(jac, np.array([1.0, 2.0]))[0, 0] == pytest.approx(1.0 / 1.25)


def test_rank_deficient_jacobian_names_the_unidentifiable_combination():
    t = np.linspace(0, 1, 20)
    jac = np.column_stack([np.ones_like(t), t, 2.0 * np.ones_like(t)])  # offset_a and offset_b collide
    with pytest.raises(CalibrationError) as info:
        crb_covariance(jac, 0.1, names=["offset_a", "slope", "offset_b"])
    text = str(info.value)
    assert "offset_a" in text and "offset_b" in text and "slope" not in text


def test_crb_sd_is_the_root_of_the_diagonal():
    rng = np.random.default_rng(1)
    jac = rng.standard_normal((40, 3))
    assert np.allclose(crb_sd(jac, 0.3) ** 2, np.diag(crb_covariance(jac, 0.3)))


def test_numerical_jacobian_matches_analytic():
    def f(x):
        return np.array([np.sin(x[0]) * x[1], x[1] ** 3, np.exp(x[0])])

    x = np.array([0.3, 1.7])
    analytic = np.array([[np.cos(0.3) * 1.7, np.sin(0.3)], [0.0, 3 * 1.7**2], [np.exp(0.3), 0.0]])
    assert np.allclose(numerical_jacobian(f, x), analytic, rtol=1e-8, atol=1e-9)


def test_propagation_through_a_linear_map_is_exact():
    rng = np.random.default_rng(2)
    a = rng.standard_normal((4, 3))
    u = rng.standard_normal((3, 3))
    cov = u @ u.T
    y, cov_y = propagate_covariance(lambda x: a @ x, np.ones(3), cov)
    assert np.allclose(y, a @ np.ones(3))
    assert np.allclose(cov_y, a @ cov @ a.T, rtol=1e-7)


def test_linear_varpro_equals_ordinary_least_squares():
    rng = np.random.default_rng(3)
    x = np.column_stack([np.ones(30), np.linspace(0, 1, 30), np.linspace(0, 1, 30) ** 2])
    y = x @ [1.0, -2.0, 0.5] + 0.01 * rng.standard_normal(30)
    fit = varpro(y, lambda a: x)
    coef, rss, *_ = np.linalg.lstsq(x, y, rcond=None)
    assert np.allclose(fit.linear, coef)
    s2 = rss[0] / (30 - 3)
    assert np.allclose(fit.covariance, s2 * np.linalg.inv(x.T @ x), rtol=1e-8)
    assert fit.sigma_fitted and fit.dof == 27


def _two_exponentials(t):
    def basis(a):
        return np.column_stack([np.exp(-a[0] * t), np.exp(-a[1] * t)])

    def dbasis(a):
        z = np.zeros_like(t)
        return np.array([np.column_stack([-t * np.exp(-a[0] * t), z]),
                         np.column_stack([z, -t * np.exp(-a[1] * t)])])

    return basis, dbasis


def test_varpro_recovers_exponentials_and_analytic_equals_numeric_derivatives():
    t = np.linspace(0, 4, 200)
    basis, dbasis = _two_exponentials(t)
    truth_a, truth_c = np.array([0.7, 3.0]), np.array([2.0, -1.0])
    rng = np.random.default_rng(4)
    y = basis(truth_a) @ truth_c + 0.01 * rng.standard_normal(t.size)
    fit_a = varpro(y, basis, [0.4, 2.0], dbasis, sigma=0.01)
    fit_n = varpro(y, basis, [0.4, 2.0], None, sigma=0.01)
    assert np.allclose(fit_a.parameters, fit_n.parameters, rtol=1e-6)
    err = fit_a.parameters - np.concatenate([truth_a, truth_c])
    assert np.all(np.abs(err) < 4 * fit_a.uncertainty)
    assert fit_a.n_evaluations < 40


def test_varpro_monte_carlo_sd_is_at_the_crb_and_intervals_cover():
    """An efficient estimator: sd within ~15 % of the CRB, +-2u covers about 95 %."""
    t = np.linspace(0, 4, 120)
    basis, dbasis = _two_exponentials(t)
    truth = np.array([0.7, 3.0, 2.0, -1.0])
    sigma = 0.02
    full_jac = np.column_stack([
        -t * np.exp(-0.7 * t) * 2.0, -t * np.exp(-3.0 * t) * -1.0, np.exp(-0.7 * t), np.exp(-3.0 * t)])
    bound = crb_sd(full_jac, sigma)
    rng = np.random.default_rng(5)
    errors, covered = [], []
    clean = basis(truth[:2]) @ truth[2:]
    for _ in range(300):
        y = clean + sigma * rng.standard_normal(t.size)
        fit = varpro(y, basis, [0.5, 2.5], dbasis)  # sigma fitted from the residual
        errors.append(fit.parameters - truth)
        covered.append(np.abs(fit.parameters - truth) <= 2 * fit.uncertainty)
    ratio = np.std(errors, axis=0) / bound
    assert np.all(ratio < 1.15) and np.all(ratio > 0.85), ratio
    coverage = np.mean(covered, axis=0)
    assert np.all((coverage > 0.91) & (coverage < 0.99)), coverage


def test_varpro_refuses_too_few_observations():
    with pytest.raises(CalibrationError):
        varpro(np.ones(2), lambda a: np.ones((2, 3)))
