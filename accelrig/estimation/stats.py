"""Statistics for calibration campaigns: regression with the slope's sd, one-way ANOVA,
normalised error, Bland-Altman.  Generic: nothing here knows about a rig.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import stats as _sps

from accelrig.errors import CalibrationError


@dataclass
class LineFit:
    """q_o = slope q_i + intercept by least squares (paper 001 eq. 5-7).

    ``slope_sd`` is sigma_S = sqrt(N sigma_qo^2 / (N sum q_i^2 - (sum q_i)^2)) with
    sigma_qo^2 = sum (S q_i + b - q_o)^2 / (N - 2) (Doebelin), the usual
    standard error of the slope; ``intercept_sd`` likewise.
    """

    slope: float
    intercept: float
    slope_sd: float
    intercept_sd: float
    covariance: np.ndarray
    r_squared: float
    residuals: np.ndarray
    residual_sd: float
    n: int

    def to_dict(self) -> dict:
        return {
            "slope": self.slope, "slope_sd": self.slope_sd,
            "intercept": self.intercept, "intercept_sd": self.intercept_sd,
            "r_squared": self.r_squared, "residual_sd": self.residual_sd, "n": self.n,
            "residuals": self.residuals.tolist(),
        }


# Standard deviation of a normal distribution per median absolute deviation, 1 / Phi^-1(3/4).
MAD_TO_SD = 1.4826


def robust_sd(x, center=None, axis=None):
    """Standard deviation from the median absolute deviation about ``center`` (default: the median).

    Outliers (a mistimed crossing, a knock, a spike) barely move it, unlike the sample sd.
    """
    x = np.asarray(x, dtype=float)
    if center is None:
        center = np.median(x, axis=axis, keepdims=axis is not None)
    return np.median(np.abs(x - center), axis=axis) * MAD_TO_SD


def linear_regression(x, y) -> LineFit:
    x = np.asarray(x, dtype=float).ravel()
    y = np.asarray(y, dtype=float).ravel()
    n = x.size
    if y.size != n:
        raise CalibrationError(f"a regression needs pairs: {n} inputs and {y.size} outputs")
    if n < 3:
        raise CalibrationError(f"a line with a slope sd needs at least 3 points, got {n}",
                               "add tests at more amplitudes")
    sxx = n * np.sum(x**2) - np.sum(x) ** 2
    if sxx <= 1e-12 * max(n * np.sum(x**2), 1e-300):
        raise CalibrationError("all inputs of the regression are equal: the slope is undefined",
                               "test at two amplitudes at least")
    slope = (n * np.sum(x * y) - np.sum(x) * np.sum(y)) / sxx
    intercept = (np.sum(y) - slope * np.sum(x)) / n
    residuals = y - (slope * x + intercept)
    s2 = float(residuals @ residuals) / (n - 2)
    slope_var = n * s2 / sxx
    intercept_var = s2 * np.sum(x**2) / sxx
    cov_sb = -s2 * np.sum(x) / sxx
    ss_tot = float(np.sum((y - y.mean()) ** 2))
    r2 = 1.0 - float(residuals @ residuals) / ss_tot if ss_tot > 0 else 1.0
    return LineFit(
        slope=float(slope), intercept=float(intercept),
        slope_sd=float(np.sqrt(slope_var)), intercept_sd=float(np.sqrt(intercept_var)),
        covariance=np.array([[slope_var, cov_sb], [cov_sb, intercept_var]]),
        r_squared=float(r2), residuals=residuals, residual_sd=float(np.sqrt(s2)), n=n,
    )


@dataclass
class Anova:
    """One-way analysis of variance: are the group means equal?"""

    f_statistic: float
    p_value: float
    df_between: int
    df_within: int
    ss_between: float
    ss_within: float
    group_means: dict
    group_sizes: dict

    def equal_means(self, alpha: float = 0.05) -> bool:
        return self.p_value >= alpha

    def to_dict(self, alpha: float = 0.05) -> dict:
        return {
            "f_statistic": self.f_statistic, "p_value": self.p_value,
            "df_between": self.df_between, "df_within": self.df_within,
            "ss_between": self.ss_between, "ss_within": self.ss_within,
            "group_means": dict(self.group_means), "group_sizes": dict(self.group_sizes),
            "alpha": alpha, "means_differ": not self.equal_means(alpha),
        }


def one_way_anova(groups: dict) -> Anova:
    """One-way ANOVA over ``{name: values}`` (at least two groups, some with repeats)."""
    data = {str(k): np.asarray(v, dtype=float).ravel() for k, v in groups.items()}
    data = {k: v for k, v in data.items() if v.size}
    if len(data) < 2:
        raise CalibrationError(f"an ANOVA needs at least two groups, got {len(data)}")
    allv = np.concatenate(list(data.values()))
    n, k = allv.size, len(data)
    if n - k < 1:
        raise CalibrationError("an ANOVA needs repeats within the groups", "repeat each test at least twice")
    grand = allv.mean()
    ss_b = float(sum(v.size * (v.mean() - grand) ** 2 for v in data.values()))
    ss_w = float(sum(np.sum((v - v.mean()) ** 2) for v in data.values()))
    df_b, df_w = k - 1, n - k
    if ss_w == 0:
        f = np.inf if ss_b > 0 else 0.0
        p = 0.0 if ss_b > 0 else 1.0
    else:
        f = (ss_b / df_b) / (ss_w / df_w)
        p = float(_sps.f.sf(f, df_b, df_w))
    return Anova(float(f), float(p), df_b, df_w, ss_b, ss_w,
                 {k_: float(v.mean()) for k_, v in data.items()}, {k_: int(v.size) for k_, v in data.items()})


def normalized_error(x1: float, expanded1: float, x2: float, expanded2: float, shared_expanded: float = 0.0) -> float:
    """E_n = (x1 - x2) / sqrt(U1^2 + U2^2 - 2 U_shared^2); |E_n| <= 1 is consistent.

    ``shared_expanded`` is the expanded uncertainty of what both results share
    (e.g. the same reference), whose covariance k^2 cov(x1, x2) = U_shared^2 is
    subtracted: a shared error moves both results alike and cannot explain
    their difference.
    """
    denom2 = expanded1**2 + expanded2**2 - 2.0 * shared_expanded**2
    if denom2 <= 0:
        raise CalibrationError(
            "the uncertainties left after removing the shared reference are zero or negative",
            "the shared part cannot exceed either result's own uncertainty",
        )
    return float((x1 - x2) / np.sqrt(denom2))


@dataclass
class BlandAltman:
    """Agreement between two methods measuring the same thing (Bland & Altman 1986)."""

    bias: float
    sd: float
    lower_limit: float
    upper_limit: float
    bias_uncertainty: float
    n: int
    proportional_slope: float

    def to_dict(self) -> dict:
        return {
            "bias": self.bias, "sd": self.sd, "lower_limit_of_agreement": self.lower_limit,
            "upper_limit_of_agreement": self.upper_limit, "bias_uncertainty": self.bias_uncertainty,
            "n": self.n, "proportional_slope": self.proportional_slope,
        }


def bland_altman(a, b, z: float = 1.96) -> BlandAltman:
    """Differences a - b against means (a + b) / 2: bias, sd and limits bias +- z sd.

    ``proportional_slope`` is the slope of the differences on the means: a
    proportional (gain) disagreement shows there, not in the bias.
    """
    a = np.asarray(a, dtype=float).ravel()
    b = np.asarray(b, dtype=float).ravel()
    if a.size != b.size:
        raise CalibrationError(f"Bland-Altman needs pairs: {a.size} and {b.size} values")
    if a.size < 3:
        raise CalibrationError(f"Bland-Altman needs at least 3 pairs, got {a.size}")
    d = a - b
    m = (a + b) / 2.0
    bias = float(d.mean())
    sd = float(d.std(ddof=1))
    slope = float(np.polyfit(m, d, 1)[0]) if np.ptp(m) > 0 else 0.0
    return BlandAltman(bias, sd, bias - z * sd, bias + z * sd, sd / np.sqrt(d.size), int(d.size), slope)
