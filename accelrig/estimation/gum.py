"""GUM uncertainty budgets (JCGM 100) and their Monte Carlo check (JCGM 101).

Generic: a budget is a list of contributions, each a standard uncertainty
(k = 1) with a sensitivity coefficient, combined with a correlation matrix:

    u_c^2 = c^T D R D c,   D = diag(u),  R = correlation

R = I is the textbook uncorrelated sum in quadrature; R = all ones is the
fully correlated (linear) sum, the conservative choice of paper 001's Table 2
(0.05 % + 0.05 % + 0.3 % = 0.4 %).  Expanded uncertainty U = k u_c, k = 2 for
about 95 %, reported labelled as such.  The law of propagation through a
function (J U J^T) is ``accelrig.estimation.crb.propagate_covariance``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from accelrig.errors import CalibrationError
from accelrig.estimation.distributions import normal_cdf, student_t_quantile
from accelrig.result import format_value

# The coverage probability of k = 2 for a normal distribution (95.45 %): the Student-t factor at this level
# tends to 2 as the degrees of freedom grow (GUM G.3-G.4, Table G.2), so an estimate resting on much data keeps
# the k = 2 it always had and one resting on little gets more.
COVERAGE_PROBABILITY = float(2.0 * normal_cdf(2.0) - 1.0)


def coverage_factor(dof: float, probability: float = COVERAGE_PROBABILITY) -> float:
    """k = t_p(nu_eff) for an expanded uncertainty U = k u whose u^2 rests on ``dof`` effective degrees of
    freedom (GUM G.4.1: Welch-Satterthwaite); 2.00 at infinite dof and the default probability."""
    dof = float(dof)
    if not dof > 0:
        raise ValueError(f"degrees of freedom must be positive, got {dof}")
    return float(student_t_quantile(0.5 + probability / 2.0, min(dof, 1e12)))


def correlation_matrix(n: int, correlation: float | np.ndarray) -> np.ndarray:
    """An n x n correlation matrix from one coefficient for every pair, or check a given matrix."""
    if np.ndim(correlation) == 0:
        rho = float(correlation)
        if not -1.0 <= rho <= 1.0:
            raise CalibrationError(f"a correlation coefficient must lie in [-1, 1], got {rho}")
        r = np.full((n, n), rho)
        np.fill_diagonal(r, 1.0)
    else:
        r = np.asarray(correlation, dtype=float)
        if r.shape != (n, n):
            raise CalibrationError(f"the correlation matrix must be {n} x {n}, got {r.shape}")
        if not np.allclose(r, r.T) or not np.allclose(np.diag(r), 1.0) or np.any(np.abs(r) > 1.0):
            raise CalibrationError("the correlation matrix must be symmetric with a unit diagonal and entries in [-1, 1]")
    if np.linalg.eigvalsh(r).min() < -1e-9:
        raise CalibrationError(
            "the correlation matrix is not positive semi-definite",
            "the coefficients given cannot all hold at once; use one coefficient for all pairs or fewer strong ones",
        )
    return r


def combined_standard_uncertainty(
    uncertainties, coefficients=None, correlation: float | np.ndarray = 0.0
) -> float:
    """u_c = sqrt(c^T D R D c) for standard uncertainties ``u`` and sensitivity coefficients ``c``."""
    u = np.asarray(uncertainties, dtype=float).ravel()
    c = np.ones_like(u) if coefficients is None else np.asarray(coefficients, dtype=float).ravel()
    if c.shape != u.shape:
        raise CalibrationError("one sensitivity coefficient per contribution is needed")
    if np.any(u < 0) or not np.all(np.isfinite(u)):
        raise CalibrationError("standard uncertainties must be finite and not negative")
    r = correlation_matrix(u.size, correlation)
    w = c * u
    return float(np.sqrt(max(w @ r @ w, 0.0)))


@dataclass
class Contribution:
    """One line of a budget: a standard uncertainty and its sensitivity coefficient."""

    name: str
    symbol: str
    uncertainty: float
    coefficient: float = 1.0
    note: str = ""

    @property
    def contribution(self) -> float:
        """|c| u: what this line adds to the budget."""
        return abs(self.coefficient) * self.uncertainty


@dataclass
class UncertaintyBudget:
    """A GUM budget (paper 001 Table 2 is one, with relative uncertainties and full correlation).

    ``correlation`` is one coefficient for every pair of contributions or a full matrix.
    ``relative`` says the uncertainties are fractions of ``value`` (then
    ``absolute_*`` multiply by |value|).
    """

    contributions: list[Contribution]
    correlation: float | list | np.ndarray = 0.0
    k: float = 2.0
    relative: bool = True
    value: float | None = None
    unit: str = ""
    notes: list[str] = field(default_factory=list)

    @property
    def combined(self) -> float:
        """Combined standard uncertainty u_c (k = 1), same scale as the contributions."""
        return combined_standard_uncertainty(
            [c.uncertainty for c in self.contributions],
            [c.coefficient for c in self.contributions],
            self.correlation,
        )

    @property
    def expanded(self) -> float:
        """Expanded uncertainty U = k u_c."""
        return self.k * self.combined

    def absolute(self, u: float) -> float:
        if not self.relative:
            return u
        if self.value is None:
            raise CalibrationError("a relative budget needs its value to give absolute uncertainties")
        return abs(self.value) * u

    def to_dict(self) -> dict:
        corr = self.correlation
        out = {
            "relative": self.relative,
            "contributions": [
                {"name": c.name, "symbol": c.symbol, "uncertainty": float(c.uncertainty),
                 "coefficient": float(c.coefficient), **({"note": c.note} if c.note else {})}
                for c in self.contributions
            ],
            "correlation": float(corr) if np.ndim(corr) == 0 else np.asarray(corr, dtype=float).tolist(),
            "combined_standard_uncertainty": self.combined,
            "coverage_factor": self.k,
            "expanded_uncertainty": self.expanded,
        }
        if self.value is not None:
            out["value"] = float(self.value)
            out["unit"] = self.unit
            if self.relative:
                out["combined_standard_uncertainty_absolute"] = self.absolute(self.combined)
                out["expanded_uncertainty_absolute"] = self.absolute(self.expanded)
        if self.notes:
            out["notes"] = list(self.notes)
        return out

    def markdown(self, percent: bool = True) -> str:
        """The budget as a Markdown table (relative values in % when ``percent``)."""
        scale, suffix = (100.0, " %") if (percent and self.relative) else (1.0, "")

        def u(value: float) -> str:   # an uncertainty by the one rule: two significant digits
            return format_value(value * scale, value * scale)[1] + suffix

        lines = ["| contribution | symbol | standard uncertainty | coefficient |", "|---|---|---|---|"]
        for c in self.contributions:
            lines.append(f"| {c.name} | {c.symbol} | {u(c.uncertainty)} | {c.coefficient:g} |")
        corr = self.correlation
        corr_text = f"{float(corr):g} between every pair" if np.ndim(corr) == 0 else "matrix (see report)"
        lines.append(f"| combined (correlation {corr_text}) | u_c | {u(self.combined)} | |")
        lines.append(f"| expanded, k = {self.k:g} | U | {u(self.expanded)} | |")
        return "\n".join(lines)


def monte_carlo_propagate(
    function: Callable[[np.ndarray], np.ndarray],
    mean,
    covariance,
    n: int,
    rng: np.random.Generator,
) -> tuple[np.ndarray, np.ndarray]:
    """JCGM 101 propagation of a Gaussian input (mean, covariance) through ``function``.

    ``function`` takes an (n, p) array of input draws and returns (n,) or (n, q)
    outputs.  Returns (mean, covariance) of the output; use it to check a
    first-order budget where the model is not linear.
    """
    mean = np.asarray(mean, dtype=float).ravel()
    cov = np.atleast_2d(np.asarray(covariance, dtype=float))
    if n < 2:
        raise CalibrationError("a Monte Carlo propagation needs at least 2 draws")
    draws = rng.multivariate_normal(mean, cov, size=n, method="eigh")
    out = np.asarray(function(draws), dtype=float)
    if out.ndim == 1:
        return np.array([out.mean()]), np.atleast_2d(out.var(ddof=1))
    return out.mean(axis=0), np.atleast_2d(np.cov(out, rowvar=False))
