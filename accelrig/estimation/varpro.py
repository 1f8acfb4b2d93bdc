"""Separable least squares by variable projection (Golub-Pereyra), with covariance.

Model:  y ~ Phi(alpha) @ c,  alpha nonlinear (few), c linear.

For each alpha the linear coefficients are the weighted least-squares solution
c(alpha), computed by QR, so the search runs over alpha only and needs no
start value for c.  The residual is r(alpha) = P_perp(alpha) y; its Jacobian
is approximated by Kaufman's  J_k = -P_perp (dPhi/dalpha_k) c,  which is all
Gauss-Newton / Levenberg-Marquardt needs (scipy.optimize.least_squares).

At the solution the covariance of all parameters [alpha, c] is the usual
least-squares one, sigma^2 (J^T J)^-1, with the *full* Jacobian of the model
J = [dPhi/dalpha_k c ..., Phi]: that is the Gauss-Markov / Cramér-Rao form,
so the same code serves fits and bounds (see crb.py).

Weights: observation i has standard deviation sigma / w_i.  A fit on means of
n_i samples thus takes w_i = sqrt(n_i) and sigma = the per-sample noise sd.
With sigma unknown it is estimated from the weighted residual, RSS / (m - p).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy.linalg import qr, solve_triangular
from scipy.optimize import least_squares

from accelrig.errors import CalibrationError
from accelrig.estimation.crb import crb_covariance, numerical_jacobian, unidentifiable_direction

Basis = Callable[[np.ndarray], np.ndarray]
BasisDerivatives = Callable[[np.ndarray], np.ndarray]


@dataclass
class VarProResult:
    """Outcome of a separable least-squares fit.

    parameters   [alpha, c] in that order, names in ``parameter_names``.
    covariance   full covariance of ``parameters`` (sigma^2 (J^T J)^-1).
    sigma        noise sd used for the covariance (given, or fitted).
    residuals    weighted residuals w * (y - Phi c) at the solution.
    """

    alpha: np.ndarray
    linear: np.ndarray
    parameters: np.ndarray
    parameter_names: list[str]
    covariance: np.ndarray
    sigma: float
    sigma_fitted: bool
    residuals: np.ndarray
    rss: float
    dof: int
    n_iterations: int
    n_evaluations: int
    seconds: float
    message: str = ""
    extra: dict = field(default_factory=dict)

    @property
    def uncertainty(self) -> np.ndarray:
        return np.sqrt(np.clip(np.diag(self.covariance), 0.0, None))

    @property
    def residual_sd(self) -> float:
        """sqrt(RSS / dof) of the weighted residuals (= the noise sd if the model is right)."""
        return float(np.sqrt(self.rss / self.dof)) if self.dof > 0 else float("nan")


def solve_linear(phi_w: np.ndarray, y_w: np.ndarray, strict: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Weighted linear least squares: (c, residual, Q with orthonormal columns spanning Phi).

    QR when Phi has full rank.  A rank-deficient Phi is an error at the
    solution (``strict``); during the search (an LM trial step may make two
    basis functions coincide) the minimum-norm SVD solution keeps the
    projection defined so the search can step back.
    """
    q, r = qr(phi_w, mode="economic")
    diag = np.abs(np.diag(r))
    if not diag.size or diag.min() > 1e-13 * max(diag.max(), 1e-300):
        c = solve_triangular(r, q.T @ y_w)
        return c, y_w - phi_w @ c, q
    if strict:
        raise CalibrationError("the linear part of the model is rank deficient for these data",
                               "the data do not excite every linear coefficient")
    u, s, vt = np.linalg.svd(phi_w, full_matrices=False)
    keep = s > 1e-13 * s[0] if s.size and s[0] > 0 else np.zeros(s.size, bool)
    u, s, vt = u[:, keep], s[keep], vt[keep]
    c = vt.T @ ((u.T @ y_w) / s)
    return c, y_w - phi_w @ c, u


def separable_jacobian(basis: Basis, alpha: np.ndarray, linear: np.ndarray,
                       basis_derivatives: BasisDerivatives | None = None,
                       weights: np.ndarray | None = None) -> np.ndarray:
    """Full Jacobian of w * Phi(alpha) c with respect to [alpha, c]: [dPhi/dalpha_k c ..., Phi].

    What the covariance (and the CRB) of a separable model needs, at a fit's
    solution or at the truth.
    """
    alpha = np.asarray(alpha, dtype=float).ravel()
    linear = np.asarray(linear, dtype=float).ravel()
    phi = np.asarray(basis(alpha), dtype=float)
    w = np.ones(phi.shape[0]) if weights is None else np.asarray(weights, dtype=float).ravel()
    if alpha.size == 0:
        return w[:, None] * phi
    if basis_derivatives is not None:
        d = np.asarray(basis_derivatives(alpha), dtype=float)
    else:
        flat = numerical_jacobian(lambda a: np.asarray(basis(a), dtype=float).ravel(), alpha)
        d = np.moveaxis(flat.reshape(*phi.shape, alpha.size), -1, 0)
    return w[:, None] * np.hstack([(d @ linear).T, phi])


def varpro(
    y: np.ndarray,
    basis: Basis,
    alpha0: Sequence[float] = (),
    basis_derivatives: BasisDerivatives | None = None,
    weights: np.ndarray | None = None,
    sigma: float | None = None,
    alpha_names: Sequence[str] | None = None,
    linear_names: Sequence[str] | None = None,
    max_evaluations: int = 200,
    tolerance: float = 1e-12,
) -> VarProResult:
    """Fit y ~ basis(alpha) @ c by variable projection with Levenberg-Marquardt.

    basis(alpha)              -> Phi, shape (m, n_linear)
    basis_derivatives(alpha)  -> dPhi/dalpha, shape (n_alpha, m, n_linear);
                                 central differences of ``basis`` when None.
    With no alpha (``alpha0`` empty) this is weighted linear least squares
    with the same covariance output, so every model goes through one path.
    """
    start = time.perf_counter()
    y = np.asarray(y, dtype=float).ravel()
    m = y.size
    w = np.ones(m) if weights is None else np.asarray(weights, dtype=float).ravel()
    if w.shape != (m,):
        raise ValueError("weights must have one value per observation")
    alpha0 = np.asarray(alpha0, dtype=float).ravel()
    n_alpha = alpha0.size
    y_w = w * y

    def phi_w(alpha):
        return w[:, None] * np.asarray(basis(alpha), dtype=float)

    def dphi_w(alpha):
        if basis_derivatives is not None:
            d = np.asarray(basis_derivatives(alpha), dtype=float)
        else:
            flat = numerical_jacobian(lambda a: np.asarray(basis(a), dtype=float).ravel(), alpha)
            shape = np.asarray(basis(alpha)).shape
            d = np.moveaxis(flat.reshape(*shape, n_alpha), -1, 0)
        return w[None, :, None] * d

    n_linear = np.asarray(basis(alpha0)).shape[1]
    n_params = n_alpha + n_linear
    alpha_names = list(alpha_names) if alpha_names is not None else [f"alpha{k}" for k in range(n_alpha)]
    linear_names = list(linear_names) if linear_names is not None else [f"c{k}" for k in range(n_linear)]
    names = alpha_names + linear_names
    if m < n_params:
        raise CalibrationError(f"{m} observations cannot determine {n_params} parameters")

    n_iter = n_eval = 0
    message = "linear least squares"
    alpha = alpha0
    if n_alpha:
        cache: dict = {}

        def project(a):
            key = a.tobytes()
            if cache.get("key") != key:
                p = phi_w(a)
                c, r, q = solve_linear(p, y_w, strict=False)
                cache.update(key=key, c=c, r=r, q=q)
            return cache

        def residual(a):
            return project(a)["r"]

        def kaufman_jacobian(a):
            state = project(a)
            q, c = state["q"], state["c"]
            d = dphi_w(a) @ c                      # (n_alpha, m): dPhi_k c
            d = d - (d @ q) @ q.T                  # P_perp applied to each
            return -d.T

        if m <= n_alpha:
            raise CalibrationError("too few observations for the nonlinear parameters")
        sol = least_squares(residual, alpha0, jac=kaufman_jacobian, method="lm",
                            xtol=tolerance, ftol=tolerance, gtol=tolerance, max_nfev=max_evaluations)
        alpha = sol.x
        n_eval = int(sol.nfev)
        n_iter = int(sol.njev) if sol.njev is not None else n_eval
        message = sol.message
        if not np.all(np.isfinite(alpha)):
            raise CalibrationError("the nonlinear search diverged")
    p = phi_w(alpha)
    c, r, _ = solve_linear(p, y_w)
    full_jac = separable_jacobian(basis, alpha, c, basis_derivatives, w)
    rss = float(r @ r)
    dof = m - n_params
    fitted = sigma is None
    if fitted:
        if dof <= 0:
            raise CalibrationError("no residual degrees of freedom to estimate the noise; give sigma")
        sigma = float(np.sqrt(rss / dof))
    problem = unidentifiable_direction(full_jac, names)
    if problem:
        raise CalibrationError(f"parameters not identifiable: {problem}")
    cov = crb_covariance(full_jac, sigma, names) if sigma > 0 else np.zeros((n_params, n_params))
    return VarProResult(
        alpha=alpha,
        linear=c,
        parameters=np.concatenate([alpha, c]),
        parameter_names=names,
        covariance=cov,
        sigma=float(sigma),
        sigma_fitted=fitted,
        residuals=r,
        rss=rss,
        dof=dof,
        n_iterations=n_iter,
        n_evaluations=n_eval,
        seconds=time.perf_counter() - start,
        message=str(message),
    )
