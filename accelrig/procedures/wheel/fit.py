"""The joint maximum-likelihood fit of all free parameters of eq. 6-7, and the CRB it reaches.

The joint method starts from the paper's four steps and fits all free
parameters together (Levenberg-Marquardt with the analytic Jacobian of
``model``), weighting each axis by its own noise sd.  Its covariance is
(J^T W J)^-1 at the estimate: the CRB, which an efficient estimator reaches.

The null space of section II-C couples r, alpha, Gamma and o_z: the radius or
the tilt must be given (both may be).  With neither the calibration refuses.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from accelrig.errors import CalibrationError, DataError
from accelrig.estimation.crb import crb_covariance, normal_covariance
from accelrig.procedures.wheel.model import (
    FreeSet,
    WheelState,
    euler_jacobian,
    model_and_jacobian,
    pack,
    predict,
    unpack,
)
from accelrig.units import STANDARD_GRAVITY

MOUNTING_HINT = ("mount the sensor tilted on the wheel, so that every axis sees both the radial and the "
                 "tangential direction, as the paper does with some 20-30 degrees about each axis")

# Reported parameters (SI), in covariance order; "geometry" is tilt or radius, whichever is free.
MOTION_NAMES = ["theta0", "omega0", "omega1", "omega2", "omega3"]
ROTATION_NAMES = ["misalignment_theta", "misalignment_phi", "misalignment_psi"]
SENSOR_NAMES = ["gain_x", "gain_y", "gain_z", "offset_x", "offset_y", "offset_z"]


def reported_names(free: FreeSet) -> list[str]:
    geo = (["tilt"] if free.tilt_free else []) + (["radius"] if free.radius_free else [])
    return MOTION_NAMES + geo + ROTATION_NAMES + SENSOR_NAMES


def free_set(radius: float | None, tilt: float | None) -> FreeSet:
    """Which of r, alpha is estimated; refuse when neither is known (the null space of II-C)."""
    if radius is None and tilt is None:
        raise CalibrationError(
            "the wheel needs the radius or the tilt: with both unknown, r, the tilt, the gains and "
            "the z offset trade off against each other and the data cannot tell them apart",
            "measure the distance from the sensor to the wheel axis and give it as the radius in metres "
            "(--radius, the form's radius field), or the tilt (--tilt-deg)",
        )
    if radius is not None and not radius > 0:
        raise DataError(f"radius {radius} m must be positive")
    if tilt is not None and not 0 < tilt < np.pi / 2:
        raise DataError(f"tilt {np.rad2deg(tilt):g} deg must lie strictly between 0 and 90 degrees")
    return FreeSet(radius_free=radius is None, tilt_free=tilt is None)


# ------------------------------------------------------------------------- the fit


@dataclass
class JointFit:
    state: WheelState
    covariance: np.ndarray          # reported parameters, SI
    names: list[str]
    sigma: np.ndarray               # noise sd per axis
    residuals: np.ndarray           # (n, 3), m/s^2
    iterations: int
    crb: np.ndarray                 # (J^T W J)^-1 in the reported parameters: the white-noise covariance
    normal_matrix: np.ndarray       # J^T W J, internal parameters
    time_scale: float


# Instants per pass of the normal equations: the Jacobian of one chunk (CHUNK x 3 x p doubles,
# about 3 MB) is all the fit holds at a time, so memory stays O(p^2) beyond the data themselves.
CHUNK = 8192
MAX_ITERATIONS = 60
# Converged when a step lowers the cost by less than this fraction and moves no parameter by more
# than STEP_TOLERANCE of its own scale (the model's sensitivity to it): relative, so reachable.
COST_TOLERANCE = 1e-10
STEP_TOLERANCE = 1e-6


def chunks(n: int, size: int = CHUNK):
    for lo in range(0, n, size):
        yield slice(lo, min(lo + size, n))


def normal_equations(t, v, state, free, time_scale, g, weight) -> tuple[float, np.ndarray, np.ndarray]:
    """Weighted cost, J^T W J and J^T W r at ``state``, accumulated chunk by chunk (one pass)."""
    p = free.size
    a, grad, cost = np.zeros((p, p)), np.zeros(p), 0.0
    for part in chunks(t.size):
        model, jac = model_and_jacobian(t[part], state, free, time_scale, g)
        res = ((v[part] - model) * weight).ravel()
        jw = (jac * weight[None, :, None]).reshape(-1, p)
        a += jw.T @ jw
        grad += jw.T @ res
        cost += float(res @ res)
    return cost, a, grad


def score_blocks(t, v, state, free, time_scale, g, weight, block: int) -> np.ndarray:
    """Sums of the weighted score J_t' W r_t over blocks of ``block`` instants, accumulated in the
    same chunked pass (the blocking of ``residuals.block_scores``: a short last block of less than
    half a block joins the previous one)."""
    n = t.size
    k = max(1, n // block)
    if n - k * block >= block / 2:
        k += 1
    out = np.zeros((k, free.size))
    for part in chunks(t.size):
        model, jac = model_and_jacobian(t[part], state, free, time_scale, g)
        res = (v[part] - model) * weight**2          # W r: the weight on J and on r
        scores = np.einsum("nkp,nk->np", jac, res)
        index = np.minimum(np.arange(part.start, part.stop) // block, k - 1)
        np.add.at(out, index, scores)
    return out


def weighted_cost(t, v, state, g, weight) -> float:
    return float(np.sum(axis_sums_of_squares(t, v, state, g) * weight**2))


def axis_sums_of_squares(t, v, state, g) -> np.ndarray:
    """Sum of squared residuals of each axis, (3,), chunk by chunk (no residual array)."""
    out = np.zeros(3)
    for part in chunks(t.size):
        res = v[part] - predict(t[part], state, g)
        out += np.einsum("nk,nk->k", res, res)
    return out


def residuals(t, v, state, g) -> np.ndarray:
    """v - model, (n, 3), filled chunk by chunk: the model's temporaries never span the record."""
    out = np.empty((t.size, 3))
    for part in chunks(t.size):
        out[part] = v[part] - predict(t[part], state, g)
    return out


def _levenberg_marquardt(t, v, state, free, time_scale, g, weight, cost_tolerance=COST_TOLERANCE):
    """Minimise the weighted misfit; the rotation is re-centred each step (increment about R).

    A trial step costs one pass of the model alone; the Jacobian is computed only where a
    step is taken.  Returns (state, iterations, converged)."""
    cost, a, grad = normal_equations(t, v, state, free, time_scale, g, weight)
    lam = 1e-4
    iterations = 0
    converged = False
    for iterations in range(1, MAX_ITERATIONS + 1):  # noqa: B007 (the count is returned)
        d = np.sqrt(np.diag(a))
        d[d == 0] = 1.0
        scaled = a / np.outer(d, d)
        improved = False
        while lam < 1e12:
            step = np.linalg.solve(scaled + lam * np.eye(free.size), grad / d) / d
            trial = unpack(pack(state, free, time_scale) + step, free, time_scale, state)
            cost_t = weighted_cost(t, v, trial, g, weight)
            if cost_t <= cost:
                improved = True
                break
            if cost_t - cost <= 1e-12 * cost:
                break          # a step that changes the cost only by rounding: at the minimum
            lam *= 10
        if not improved:
            # no step lowers the cost: converged when what is left is rounding
            converged = bool(cost_t - cost <= 1e-12 * cost)
            break
        decrease = cost - cost_t
        small_step = np.max(np.abs(step * d)) < STEP_TOLERANCE * np.sqrt(max(cost, 1e-300))
        state = trial
        cost, a, grad = normal_equations(t, v, state, free, time_scale, g, weight)
        lam = max(lam / 10, 1e-12)
        if decrease <= cost_tolerance * cost_t and small_step:
            converged = True
            break
    return state, iterations, converged


def reporting_map(state: WheelState, free: FreeSet, time_scale: float) -> np.ndarray:
    """d(reported)/d(internal): c_k -> w_k = c_k / T^k, rotation increment -> Euler angles."""
    p = free.size
    m = np.eye(p)
    for k in range(4):
        m[1 + k, 1 + k] = time_scale ** -k
    rs = free.rotation_slice
    m[rs, rs] = euler_jacobian(state.rotation)
    return m


def joint_fit(t: np.ndarray, v: np.ndarray, start: WheelState, free: FreeSet,
              g: float = STANDARD_GRAVITY) -> JointFit:
    """Maximum likelihood of all free parameters from ``start``; per-axis noise estimated.

    Cost linear in the record length, memory O(p^2) beyond the data: the normal equations
    are accumulated chunk by chunk.  The covariance returned is the white-noise one,
    (J^T W J)^-1; ``residual_checks`` decides whether the residuals allow it."""
    time_scale = max(float(t[-1]), 1e-6)
    weight = np.ones(3)
    # this first pass only needs the residuals' sd per axis (to 0.1 %): a loose tolerance
    state, it1, _ = _levenberg_marquardt(t, v, start, free, time_scale, g, weight, cost_tolerance=1e-6)
    # per-axis noise sd from the residuals, then the weighted (ML) refinement
    dof = 3 * t.size - free.size
    sigma = np.sqrt(axis_sums_of_squares(t, v, state, g) / (dof / 3))
    weight = 1.0 / sigma
    state, it2, converged = _levenberg_marquardt(t, v, state, free, time_scale, g, weight)
    if not converged:
        raise CalibrationError(
            f"the joint fit did not converge in {MAX_ITERATIONS} iterations",
            "the data do not follow the wheel model closely enough; check the recording covers one "
            "continuous coast-down, or try --method paper")
    try:
        state = state.canonical()
    except ValueError:
        raise CalibrationError("the joint fit ended at gains of mixed sign",
                               "the data do not look like a tilted wheel; check the recording") from None
    _, a, _ = normal_equations(t, v, state, free, time_scale, g, weight)
    resid = residuals(t, v, state, g)
    try:
        cov_internal = normal_covariance(a, free.names)
    except CalibrationError as exc:
        raise CalibrationError(exc.message, MOUNTING_HINT) from None
    m = reporting_map(state, free, time_scale)
    cov = m @ cov_internal @ m.T
    return JointFit(state, cov, reported_names(free), sigma, resid, it1 + it2, cov, a, time_scale)


def wheel_crb(t: np.ndarray, truth: WheelState, free: FreeSet, sigma, g: float = STANDARD_GRAVITY) -> np.ndarray:
    """CRB (covariance of the reported parameters, SI) for white noise of sd ``sigma``
    (scalar or per axis) at the parameters ``truth``."""
    time_scale = max(float(t[-1]), 1e-6)
    weight = 1.0 / np.broadcast_to(np.asarray(sigma, dtype=float), (3,))
    _, jac = model_and_jacobian(t, truth, free, time_scale, g)
    jw = (jac * weight[None, :, None]).reshape(-1, free.size)
    m = reporting_map(truth, free, time_scale)
    return m @ crb_covariance(jw, 1.0, free.names) @ m.T


def reported_values(state: WheelState, free: FreeSet) -> np.ndarray:
    geo = ([state.tilt] if free.tilt_free else []) + ([state.radius] if free.radius_free else [])
    return np.concatenate([[state.theta0], state.omega, geo, state.euler, state.gain, state.offset])

