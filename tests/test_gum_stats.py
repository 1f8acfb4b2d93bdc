import numpy as np
import pytest
from scipy import stats as sps

from accelrig.errors import CalibrationError
from accelrig.estimation.gum import (
    Contribution,
    UncertaintyBudget,
    combined_standard_uncertainty,
    correlation_matrix,
    monte_carlo_propagate,
)
from accelrig.estimation.stats import bland_altman, linear_regression, normalized_error, one_way_anova


def test_paper_table2_full_correlation_is_the_linear_sum():
    # paper 001 Table 2: 0.05 % + 0.05 % + 0.3 % with every correlation 1 -> 0.4 %
    u = combined_standard_uncertainty([0.0005, 0.0005, 0.003], correlation=1.0)
    assert u == pytest.approx(0.004, rel=1e-12)
    assert combined_standard_uncertainty([0.0005, 0.0005, 0.003], correlation=0.0) == pytest.approx(
        np.sqrt(0.0005**2 * 2 + 0.003**2), rel=1e-12)


def test_budget_expanded_and_absolute():
    b = UncertaintyBudget([Contribution("repeatability", "u_r", 0.0005), Contribution("linearity", "u_l", 0.0005),
                           Contribution("reference", "u_ref", 0.003)], correlation=1.0, k=2, value=423.0)
    assert b.expanded == pytest.approx(0.008)
    d = b.to_dict()
    assert d["expanded_uncertainty_absolute"] == pytest.approx(423.0 * 0.008)
    assert "| expanded, k = 2 | U | 0.80 % |" in b.markdown()   # two significant digits (format_value)


def test_correlation_matrix_must_be_possible():
    with pytest.raises(CalibrationError, match="positive semi-definite"):
        correlation_matrix(3, np.array([[1, 0.9, -0.9], [0.9, 1, 0.9], [-0.9, 0.9, 1]]))
    with pytest.raises(CalibrationError):
        correlation_matrix(2, 1.5)


def test_monte_carlo_matches_first_order_for_a_product():
    rng = np.random.default_rng(1)
    mean, cov = monte_carlo_propagate(lambda x: x[:, 0] * x[:, 1], [2.0, 3.0], np.diag([0.01**2, 0.02**2]),
                                      200_000, rng)
    linear = np.sqrt((3 * 0.01) ** 2 + (2 * 0.02) ** 2)
    assert mean[0] == pytest.approx(6.0, abs=5e-4)
    assert np.sqrt(cov[0, 0]) == pytest.approx(linear, rel=0.01)


def test_regression_matches_scipy_and_its_sd_is_honest():
    rng = np.random.default_rng(2)
    x = np.array([4.0, 8, 15, 25, 35, 49])
    y = 423 * x + 3 + rng.normal(0, 5, x.size)
    line = linear_regression(x, y)
    ref = sps.linregress(x, y)
    assert line.slope == pytest.approx(ref.slope)
    assert line.slope_sd == pytest.approx(ref.stderr)
    assert line.intercept_sd == pytest.approx(ref.intercept_stderr)
    assert line.r_squared == pytest.approx(ref.rvalue**2)
    slopes, sds = [], []
    for _ in range(2000):
        fit = linear_regression(x, 423 * x + 3 + rng.normal(0, 5, x.size))
        slopes.append(fit.slope)
        sds.append(fit.slope_sd**2)
    assert np.std(slopes) == pytest.approx(np.sqrt(np.mean(sds)), rel=0.06)


def test_regression_refuses_a_single_amplitude():
    with pytest.raises(CalibrationError, match="equal"):
        linear_regression([5, 5, 5], [1, 2, 3])


def test_anova_matches_scipy():
    rng = np.random.default_rng(3)
    groups = {"x": rng.normal(423, 1, 6), "y": rng.normal(423.5, 1, 6), "z": rng.normal(424, 1, 5)}
    a = one_way_anova(groups)
    ref = sps.f_oneway(*groups.values())
    assert a.f_statistic == pytest.approx(ref.statistic)
    assert a.p_value == pytest.approx(ref.pvalue)
    assert a.df_between == 2 and a.df_within == 14
    with pytest.raises(CalibrationError, match="two groups"):
        one_way_anova({"x": [1, 2]})


def test_normalized_error_removes_the_shared_reference():
    # two sensors 0.5 % apart, each with U = 0.8 % of which the shared reference is 0.75 %
    s1, s2 = 423.0, 421.0
    plain = normalized_error(s1, 0.008 * s1, s2, 0.008 * s2)
    shared = normalized_error(s1, 0.008 * s1, s2, 0.008 * s2, shared_expanded=0.0075 * np.sqrt(s1 * s2))
    assert abs(plain) < 1 < abs(shared)
    with pytest.raises(CalibrationError):
        normalized_error(1.0, 0.1, 1.0, 0.1, shared_expanded=0.2)


def test_bland_altman_bias_limits_and_proportional_error():
    rng = np.random.default_rng(4)
    truth = rng.uniform(-50, 50, 5000)
    a = truth * 1.002 - 0.08 + rng.normal(0, 0.05, truth.size)
    ba = bland_altman(a, truth)
    assert ba.bias == pytest.approx(-0.08, abs=0.01)
    assert ba.proportional_slope == pytest.approx(0.002, rel=0.1)
    assert ba.upper_limit - ba.lower_limit == pytest.approx(2 * 1.96 * ba.sd)
