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
from accelrig.estimation.crb import crb_covariance
from accelrig.procedures.wheel.model import FreeSet, WheelState, euler_jacobian, model_and_jacobian, pack, unpack
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


def _weighted(t, v, state, free, time_scale, g, weight):
    model, jac = model_and_jacobian(t, state, free, time_scale, g)
    res = ((v - model) * weight).ravel()
    jw = (jac * weight[None, :, None]).reshape(-1, free.size)
    return res, jw


def _levenberg_marquardt(t, v, state, free, time_scale, g, weight, max_iter=60):
    """Minimise the weighted misfit; the rotation is re-centred each step (increment about R)."""
    res, jw = _weighted(t, v, state, free, time_scale, g, weight)
    cost = float(res @ res)
    lam = 1e-4
    iterations = 0
    for iterations in range(1, max_iter + 1):  # noqa: B007 (the count is returned)
        a = jw.T @ jw
        grad = jw.T @ res
        d = np.sqrt(np.diag(a))
        d[d == 0] = 1.0
        scaled = a / np.outer(d, d)
        improved = False
        while lam < 1e12:
            step = np.linalg.solve(scaled + lam * np.eye(free.size), grad / d) / d
            trial = unpack(pack(state, free, time_scale) + step, free, time_scale, state)
            res_t, jw_t = _weighted(t, v, trial, free, time_scale, g, weight)
            cost_t = float(res_t @ res_t)
            if cost_t <= cost:
                improved = True
                break
            lam *= 10
        if not improved:
            break
        decrease = cost - cost_t
        state, res, jw, cost = trial, res_t, jw_t, cost_t
        lam = max(lam / 10, 1e-12)
        if decrease <= 1e-12 * cost and np.max(np.abs(step * d)) < 1e-6:
            break
    return state, jw, res, iterations


def _reporting_map(state: WheelState, free: FreeSet, time_scale: float) -> np.ndarray:
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
    """Maximum likelihood of all free parameters from ``start``; per-axis noise estimated."""
    time_scale = max(float(t[-1]), 1e-6)
    weight = np.ones(3)
    state, jw, res, it1 = _levenberg_marquardt(t, v, start, free, time_scale, g, weight)
    # per-axis noise sd from the residuals, then the weighted (ML) refinement
    resid = res.reshape(-1, 3) / weight
    dof = resid.size - free.size
    sigma = np.sqrt(np.sum(resid**2, axis=0) / (dof / 3))
    weight = 1.0 / sigma
    state, jw, res, it2 = _levenberg_marquardt(t, v, state, free, time_scale, g, weight)
    try:
        state = state.canonical()
    except ValueError:
        raise CalibrationError("the joint fit ended at gains of mixed sign",
                               "the data do not look like a tilted wheel; check the recording") from None
    res, jw = _weighted(t, v, state, free, time_scale, g, weight)
    try:
        cov_internal = crb_covariance(jw, 1.0, free.names)
    except CalibrationError as exc:
        raise CalibrationError(exc.message, MOUNTING_HINT) from None
    m = _reporting_map(state, free, time_scale)
    return JointFit(state, m @ cov_internal @ m.T, reported_names(free), sigma,
                    res.reshape(-1, 3) / weight, it1 + it2)


def wheel_crb(t: np.ndarray, truth: WheelState, free: FreeSet, sigma, g: float = STANDARD_GRAVITY) -> np.ndarray:
    """CRB (covariance of the reported parameters, SI) for white noise of sd ``sigma``
    (scalar or per axis) at the parameters ``truth``."""
    time_scale = max(float(t[-1]), 1e-6)
    weight = 1.0 / np.broadcast_to(np.asarray(sigma, dtype=float), (3,))
    _, jac = model_and_jacobian(t, truth, free, time_scale, g)
    jw = (jac * weight[None, :, None]).reshape(-1, free.size)
    m = _reporting_map(truth, free, time_scale)
    return m @ crb_covariance(jw, 1.0, free.names) @ m.T


def reported_values(state: WheelState, free: FreeSet) -> np.ndarray:
    geo = ([state.tilt] if free.tilt_free else []) + ([state.radius] if free.radius_free else [])
    return np.concatenate([[state.theta0], state.omega, geo, state.euler, state.gain, state.offset])
