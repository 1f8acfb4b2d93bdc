"""Cramér-Rao bounds and the law of propagation of uncertainty.

For a least-squares model y = f(p) + e with independent Gaussian noise of sd
sigma, the Fisher information is J^T J / sigma^2 with J = df/dp at the true p,
and the CRB is its inverse: cov(p_hat) >= sigma^2 (J^T J)^-1.  The same
formula, evaluated at the estimate with the fitted noise level, is the
covariance a least-squares fit reports, so one function serves both.

Helpers here:
  crb_covariance      sigma^2 (J^T J)^-1, refusing a rank-deficient J with a
                      message naming the parameter combination the data cannot see;
  normal_covariance   the same from J^T J alone (chunked fits);
  crb_sd              its per-parameter square roots (the bound on the sd);
  numerical_jacobian  central differences of any vector function;
  propagate_covariance  GUM law  U_y = J U_x J^T  through any function.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from accelrig.errors import CalibrationError

# Singular values below this fraction of the largest (after scaling each
# column to unit norm, so units do not matter) count as zero.
RANK_TOLERANCE = 1e-10


def _row_weights(sigma, n_rows: int) -> np.ndarray:
    sigma = np.asarray(sigma, dtype=float)
    if sigma.ndim == 0:
        sigma = np.full(n_rows, float(sigma))
    if sigma.shape != (n_rows,):
        raise ValueError(f"sigma must be a scalar or one value per row ({n_rows}), got shape {sigma.shape}")
    if np.any(~np.isfinite(sigma)) or np.any(sigma <= 0):
        raise CalibrationError("the noise level must be positive and finite to compute a covariance")
    return 1.0 / sigma


def unidentifiable_direction(jacobian: np.ndarray, names: Sequence[str] | None = None) -> str | None:
    """Describe the parameter combination a Jacobian cannot see, or None if it has full rank.

    Columns are scaled to unit norm first, so a parameter in mm and one in m
    are judged alike; the direction is reported in the scaled parameters.
    """
    jac = np.asarray(jacobian, dtype=float)
    n_params = jac.shape[1]
    names = list(names) if names is not None else [f"p{k}" for k in range(n_params)]
    if jac.shape[0] < n_params:
        return f"only {jac.shape[0]} observations for {n_params} parameters"
    norms = np.linalg.norm(jac, axis=0)
    dead = [names[k] for k in range(n_params) if norms[k] == 0 or not np.isfinite(norms[k])]
    if dead:
        return f"the data do not depend on {', '.join(dead)}"
    # the singular values alone first (a third of the cost; fits ask this once per solve): the direction
    # only when there is one to name
    s = np.linalg.svd(jac / norms, compute_uv=False)
    if s[-1] > RANK_TOLERANCE * s[0]:
        return None
    v = np.linalg.svd(jac / norms, full_matrices=False)[2][-1]
    order = np.argsort(-np.abs(v))
    terms = [f"{v[k]:+.2f}*{names[k]}" for k in order if abs(v[k]) >= 0.1]
    return "the combination " + " ".join(terms) + " is not determined by the data"


def crb_covariance(jacobian: np.ndarray, sigma, names: Sequence[str] | None = None) -> np.ndarray:
    """sigma^2 (J^T J)^-1: the CRB at the truth, or a fit's covariance at its estimate.

    ``jacobian`` (n_obs, n_params) is df/dp; ``sigma`` the noise sd, a scalar
    or one value per observation (rows are then divided by it).  Raises
    CalibrationError naming the unidentifiable direction when J^T J is singular.
    """
    jac = np.asarray(jacobian, dtype=float)
    if jac.ndim != 2:
        raise ValueError("jacobian must be 2-D (observations x parameters)")
    jac = jac * _row_weights(sigma, jac.shape[0])[:, None]
    problem = unidentifiable_direction(jac, names)
    if problem:
        raise CalibrationError(f"parameters not identifiable: {problem}",
                               "add data that excite them or fix one of them")
    # Solve through the SVD of the column-scaled Jacobian: stable when the
    # parameters have very different scales.
    norms = np.linalg.norm(jac, axis=0)
    _, s, vt = np.linalg.svd(jac / norms, full_matrices=False)
    inner = (vt.T / s**2) @ vt
    cov = inner / np.outer(norms, norms)
    return 0.5 * (cov + cov.T)


def normal_covariance(normal_matrix: np.ndarray, names: Sequence[str] | None = None) -> np.ndarray:
    """(J^T J)^-1 from the normal matrix alone, for fits that accumulate J^T J in chunks
    (memory O(p^2) whatever the record length).  Same scaling and rank test as
    ``crb_covariance``: the singular values of the column-scaled J are the square roots
    of the eigenvalues of the scaled normal matrix."""
    a = np.asarray(normal_matrix, dtype=float)
    p = a.shape[0]
    names = list(names) if names is not None else [f"p{k}" for k in range(p)]
    norms = np.sqrt(np.diag(a))
    dead = [names[k] for k in range(p) if not norms[k] > 0 or not np.isfinite(norms[k])]
    if dead:
        raise CalibrationError(f"parameters not identifiable: the data do not depend on {', '.join(dead)}",
                               "add data that excite them or fix one of them")
    scaled = a / np.outer(norms, norms)
    eigval, eigvec = np.linalg.eigh(0.5 * (scaled + scaled.T))
    if not eigval[0] > RANK_TOLERANCE**2 * eigval[-1]:
        v = eigvec[:, 0]
        order = np.argsort(-np.abs(v))
        terms = [f"{v[k]:+.2f}*{names[k]}" for k in order if abs(v[k]) >= 0.1]
        raise CalibrationError("parameters not identifiable: the combination " + " ".join(terms)
                               + " is not determined by the data", "add data that excite them or fix one of them")
    inner = (eigvec / eigval) @ eigvec.T
    cov = inner / np.outer(norms, norms)
    return 0.5 * (cov + cov.T)


def crb_sd(jacobian: np.ndarray, sigma, names: Sequence[str] | None = None) -> np.ndarray:
    """The bound on each parameter's standard deviation: sqrt(diag(crb_covariance))."""
    return np.sqrt(np.diag(crb_covariance(jacobian, sigma, names)))


def numerical_jacobian(func: Callable[[np.ndarray], np.ndarray], x: np.ndarray,
                       step: float | np.ndarray | None = None) -> np.ndarray:
    """Central-difference Jacobian d func / d x, shape (len(func(x)), len(x)).

    The default step, 1e-6 x max(|x_k|, 1), balances truncation against
    rounding for functions that are smooth on the scale of their arguments.
    """
    x = np.asarray(x, dtype=float)
    if step is None:
        step = 1e-6 * np.maximum(np.abs(x), 1.0)
    step = np.broadcast_to(np.asarray(step, dtype=float), x.shape)
    f0 = np.atleast_1d(np.asarray(func(x), dtype=float)).ravel()
    jac = np.empty((f0.size, x.size))
    for k in range(x.size):
        dx = np.zeros_like(x)
        dx[k] = step[k]
        f_plus = np.atleast_1d(np.asarray(func(x + dx), dtype=float)).ravel()
        f_minus = np.atleast_1d(np.asarray(func(x - dx), dtype=float)).ravel()
        jac[:, k] = (f_plus - f_minus) / (2.0 * step[k])
    return jac


def propagate_covariance(func: Callable[[np.ndarray], np.ndarray], x: np.ndarray, cov: np.ndarray,
                         step: float | np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """GUM law of propagation: y = func(x), U_y = J U_x J^T with J = d func / d x.

    First order, which is what the GUM prescribes; fine while the function is
    close to linear over a few standard uncertainties of x.
    """
    x = np.asarray(x, dtype=float)
    y = np.atleast_1d(np.asarray(func(x), dtype=float)).ravel()
    jac = numerical_jacobian(func, x, step)
    out = jac @ np.asarray(cov, dtype=float) @ jac.T
    return y, 0.5 * (out + out.T)
