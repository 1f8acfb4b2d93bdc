"""The paper's four sequential steps (Pedersini, section III), as ``--method paper``.

A. Partial re-alignment T = T'' T':  T' (rotation about X and Y) makes the
   z component of T' v as constant as possible (eq. 24); T'' (rotation about Z)
   minimises the excursion max - min of the y component (eq. 26), so that
   W = T Gamma R is upper triangular (eq. 21).
B. Motion: fit r_y(t) = k + A sin(theta(t)) with the quartic phase of eq. 2 (eq. 29),
   started from the speeds of each half turn (the paper's Fig. 3).
C. Misalignment, tilt, gain: a 4-D minimum search over (Euler angles, alpha) of the
   zero-mean misfit (eq. 34), the gains of each candidate from the pseudo-inverse
   solve of eq. 30-32 with w22 from the sd of r_y (eq. 31).
D. Offset: the constant that best fits v - Gamma R a (eq. 35).

Where a step's criterion has an exact minimiser it is computed exactly rather
than searched: T' is the least-variance eigenvector (the minimum of eq. 24 over
all directions), and eq. 35 is a mean.  Step C is a Nelder-Mead search as in
the paper (reference [17]).  With the tilt given instead of the radius, step C
searches (Euler angles, r) with alpha fixed, the adaptation section II-C names.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares, minimize

from accelrig.errors import CalibrationError
from accelrig.estimation.stats import robust_sd
from accelrig.geometry import rot_x, rot_y, rot_z
from accelrig.procedures.wheel.checks import WheelSurvey, half_turn_speeds
from accelrig.procedures.wheel.model import (
    WheelState,
    bench_force,
    euler_from_rotation,
    phase,
    rotation_from_euler,
)
from accelrig.units import STANDARD_GRAVITY


@dataclass
class PaperSteps:
    """Everything the four steps produce, for the result's plots and for the joint start."""

    state: WheelState
    realignment: np.ndarray        # T
    amplitude: float               # A of eq. 28
    w22: float                     # eq. 31
    speed_time: np.ndarray         # Fig. 3: midpoints of half turns
    speed_samples: np.ndarray      # Fig. 3: mean speed of each half turn
    n_function_evaluations: int


def realign_z(v: np.ndarray) -> np.ndarray:
    """T' = Rx(eps_x) Ry(eps_y) whose third row is the least-variance direction (eq. 24),
    signed so that r'_z = g cos(alpha) + ... comes out positive."""
    centred = v - v.mean(axis=0)
    _, vecs = np.linalg.eigh(centred.T @ centred)
    n = vecs[:, 0]
    if v.mean(axis=0) @ n < 0:
        n = -n
    eps_x = np.arcsin(np.clip(n[1], -1, 1))
    eps_y = np.arctan2(-n[0], n[2])
    return rot_x(eps_x) @ rot_y(eps_y)


def realign_y(r1: np.ndarray, grid_step_deg: float = 0.5) -> float:
    """eps_z of T'' = Rz(eps_z) minimising max(r_y) - min(r_y) (eq. 26).

    The excursion has period pi in eps_z; a grid over [0, pi) then a bounded
    refinement around the best node."""
    per_pass = int(np.clip(4_000_000 // max(r1.shape[0], 1), 1, 60))   # about 32 MB of candidates at a time

    def excursion(eps: np.ndarray) -> np.ndarray:
        out = np.empty(eps.size)
        for i in range(0, eps.size, per_pass):
            e = eps[i:i + per_pass]
            ry = np.outer(np.sin(e), r1[:, 0])
            ry += np.outer(np.cos(e), r1[:, 1])
            out[i:i + per_pass] = ry.max(axis=1) - ry.min(axis=1)
        return out

    grid = np.deg2rad(np.arange(0.0, 180.0, grid_step_deg))
    best = grid[int(np.argmin(excursion(grid)))]
    step = np.deg2rad(grid_step_deg)
    fine = np.linspace(best - step, best + step, 81)
    return float(fine[int(np.argmin(excursion(fine)))])


def fit_motion(t: np.ndarray, ry: np.ndarray, survey: WheelSurvey, gap_times: np.ndarray):
    """Step B: speeds per half turn -> cubic start -> least squares of eq. 29 over 7 parameters.

    Returns (theta0, omega, k, A, speed_time, speed_samples); the speed is
    positive here (the direction is settled afterwards from r_x)."""
    y = ry - ry.mean()
    mid, speed, crossings, dirs = half_turn_speeds(t, y, survey.mean_speed, survey.period, gap_times)
    if speed.size < 6:
        raise CalibrationError(
            f"only {speed.size} half turns could be timed in the signal",
            "spin the wheel harder, with the axis tilted, and record longer",
        )
    # a robust cubic: refit without samples far off the first fit (a mistimed crossing)
    coef = np.polyfit(mid, speed, 3)
    resid = speed - np.polyval(coef, mid)
    mad = robust_sd(resid, center=0.0) + 1e-12
    good = np.abs(resid) < 5 * mad
    coef = np.polyfit(mid[good], speed[good], 3)
    omega = coef[::-1].copy()                                    # w0 .. w3
    # theta0: an upward crossing of A sin(theta) is theta = 0 (mod 2 pi), downward theta = pi
    swept = phase(crossings, 0.0, omega)[0]
    target = np.where(dirs > 0, 0.0, np.pi)
    theta0 = float(np.angle(np.mean(np.exp(1j * (target - swept)))))
    amplitude0 = np.sqrt(2.0) * np.std(y)
    scale = max(t[-1], 1e-9)
    powers = np.arange(4)

    def unpack(x):
        return x[0], x[1:5] / scale**powers, x[5], x[6]

    tau = t / scale

    def residual(x):
        th0, om, k, amp = unpack(x)
        theta = phase(t, th0, om)[0]
        return k + amp * np.sin(theta) - ry

    def jacobian(x):
        th0, om, k, amp = unpack(x)
        theta = phase(t, th0, om)[0]
        ac = amp * np.cos(theta)
        cols = [ac] + [ac * scale * tau ** (j + 1) / (j + 1) for j in range(4)] + [np.ones_like(t), np.sin(theta)]
        return np.column_stack(cols)

    x0 = np.concatenate([[theta0], omega * scale**powers, [ry.mean(), amplitude0]])
    sol = least_squares(residual, x0, jac=jacobian, method="lm", xtol=1e-12, ftol=1e-12)
    if not sol.success:
        raise CalibrationError(f"the wheel's speed law could not be fitted to the rotating gravity signal "
                               f"({sol.message})",
                               "check that the recording holds one continuous spin of the wheel")
    th0, om, k, amp = unpack(sol.x)
    return th0, om, k, amp, mid[good], speed[good], sol.nfev


def gains_from_constraints(T: np.ndarray, R: np.ndarray, w22: float) -> np.ndarray:
    """Eq. 30-32: w21 = w31 = w32 = 0, w22 = w22bar, solved for gamma in the least-squares sense."""
    U = np.array([
        [T[1, 0] * R[0, 0], T[1, 1] * R[1, 0], T[1, 2] * R[2, 0]],   # w21
        [T[2, 0] * R[0, 0], T[2, 1] * R[1, 0], T[2, 2] * R[2, 0]],   # w31
        [T[2, 0] * R[0, 1], T[2, 1] * R[1, 1], T[2, 2] * R[2, 1]],   # w32
        [T[1, 0] * R[0, 1], T[1, 1] * R[1, 1], T[1, 2] * R[2, 1]],   # w22
    ])
    b = np.array([0.0, 0.0, 0.0, w22])
    return np.linalg.solve(U.T @ U, U.T @ b)


@dataclass
class Motion:
    """Steps A and B: the re-alignment and the wheel's phase law from r_y, signs not yet settled."""

    realignment: np.ndarray        # T
    realigned: np.ndarray          # r = T v, (n, 3)
    theta0: float
    omega: np.ndarray              # w0 .. w3, positive speed (the direction is settled later)
    amplitude: float               # A of eq. 28 (sign not settled)
    speed_time: np.ndarray
    speed_samples: np.ndarray
    n_function_evaluations: int


def paper_motion(t: np.ndarray, v: np.ndarray, survey: WheelSurvey, gap_times: np.ndarray | None = None) -> Motion:
    """Steps A (partial re-alignment) and B (phase law from r_y): shared by both methods."""
    gap_times = np.empty(0) if gap_times is None else gap_times
    T1 = realign_z(v)
    r1 = v @ T1.T
    eps_z = realign_y(r1)
    T = rot_z(eps_z) @ T1
    r = v @ T.T
    theta0, omega, _, amp, speed_t, speed_s, nfev = fit_motion(t, r[:, 1], survey, gap_times)
    return Motion(T, r, theta0, omega, amp, speed_t, speed_s, nfev)


def paper_calibrate(t: np.ndarray, v: np.ndarray, survey: WheelSurvey, radius: float | None,
                    tilt: float | None, g: float = STANDARD_GRAVITY,
                    gap_times: np.ndarray | None = None) -> PaperSteps:
    """The four steps.  t from the first sample (s), v raw (n, 3) in m/s^2."""
    # --- A, B: partial re-alignment, motion from r_y
    motion = paper_motion(t, v, survey, gap_times)
    T, r = motion.realignment, motion.realigned
    theta0, omega, amp = motion.theta0, motion.omega, motion.amplitude
    speed_t, speed_s, nfev_b = motion.speed_time, motion.speed_samples, motion.n_function_evaluations
    # Signs.  W = T Gamma R has a positive diagonal (det W = det Gamma > 0, w33 > 0 by T').
    # The centripetal drift enters r_x as + w11 r w^2: if it comes out negative, T'' is off by pi.
    if _rx_terms(t, r[:, 0], theta0, omega)[0] < 0:
        T = rot_z(np.pi) @ T
        r = v @ T.T
        amp = -amp
    if amp < 0:  # A sin(theta) = -A sin(theta + pi): keep A = w22 g sin(alpha) > 0
        theta0, amp = theta0 + np.pi, -amp
    # the half-turn speeds are unsigned: theta and pi - theta give the same r_y; the
    # gravity term of r_x is + w11 g sin(alpha) cos(theta), which settles the spin direction
    if _rx_terms(t, r[:, 0], theta0, omega)[1] < 0:
        theta0, omega = np.pi - theta0, -omega
    # --- C: misalignment, tilt (or radius), gain
    sd_ry = np.std(r[:, 1])
    v0 = v - v.mean(axis=0)
    rate_accel = phase(t, theta0, omega)
    free_geo = "tilt" if tilt is None else ("radius" if radius is None else None)

    def candidate(x):
        R = rotation_from_euler(x[:3])
        alpha = x[3] if free_geo == "tilt" else tilt
        rad = x[3] if free_geo == "radius" else radius
        w22 = np.sqrt(2.0) * sd_ry / (g * np.sin(alpha))            # eq. 31
        gamma = gains_from_constraints(T, R, w22)                    # eq. 32
        a = bench_force(*rate_accel, rad, alpha, g)
        return R, alpha, rad, gamma, a

    def objective(x):
        _, _, _, gamma, a = candidate(x)
        model = (a @ rotation_from_euler(x[:3]).T) * gamma
        # ||T v0 - T v0^m|| = ||v0 - v0^m||: T is a rotation (eq. 33-34)
        resid = v0 - (model - model.mean(axis=0))
        return float(np.sum(resid * resid))

    euler0 = euler_from_rotation(T.T)        # T ~ R^T when the gains are nearly equal (eq. 18)
    alpha0 = float(np.arctan2(amp, abs(r[:, 2].mean())))
    x0 = list(euler0)
    if free_geo == "tilt":
        x0.append(alpha0)
    elif free_geo == "radius":
        x0.append(_radius_start(t, r[:, 0], theta0, omega))
    x0 = np.asarray(x0)
    simplex_step = np.full(x0.size, np.deg2rad(3.0))
    if free_geo == "radius":
        simplex_step[3] = 0.05 * x0[3]
    # Tolerances relative to the noise: the search stops when the simplex's values differ by less
    # than 1e-4 of one sample's residual variance (a chi^2 change of 1e-4, far below what moves an
    # estimate by a fraction of its u) and its points by less than 1e-7 rad or 1e-7 of the radius.
    # (An absolute fatol of 1e-12 on a sum of squares near 1e4 is unreachable: the search then
    # ran to maxfev on every record.)
    noise_var = objective(x0) / v0.size
    xatol = 1e-7 * (max(abs(x0[3]), 1.0) if free_geo == "radius" else 1.0)
    sol = minimize(objective, x0, method="Nelder-Mead",
                   options={"xatol": xatol, "fatol": 1e-4 * noise_var, "maxfev": 6000, "adaptive": True,
                            "initial_simplex": np.vstack([x0, x0 + np.diag(simplex_step)])})
    R, alpha, rad, gamma, a = candidate(sol.x)
    # --- D: offset (eq. 35 is quadratic in o: its minimum is the mean misfit)
    offset = (v - (a @ R.T) * gamma).mean(axis=0)
    state = WheelState(theta0, omega, alpha, rad, R, gamma, offset)
    try:
        state = state.canonical()
    except ValueError:
        raise CalibrationError(
            "the four-step search ended at gains of mixed sign; the sensor axes may be aligned with the "
            "wheel, which leaves a gain inseparable from an offset",
            "mount the sensor tilted on the wheel, so that every axis sees both the radial and the "
            "tangential direction, as the paper does with some 20-30 degrees about each axis",
        ) from None
    # checked after the gains: a search lost on an aligned mounting is reported as the mounting
    if not sol.success:
        raise CalibrationError(
            f"the paper's step C search did not converge in {sol.nfev} evaluations ({sol.message})",
            "use the joint fit (--method joint, the default), which needs no search",
        )
    w22 = np.sqrt(2.0) * sd_ry / (g * np.sin(state.tilt))
    return PaperSteps(state, T, float(amp), float(w22), speed_t, speed_s, int(sol.nfev + nfev_b))


def _rx_terms(t, rx, theta0, omega) -> np.ndarray:
    """Least-squares coefficients of r_x on [w(t)^2, cos theta, sin theta, 1]."""
    theta, rate, _ = phase(t, theta0, omega)
    basis = np.column_stack([rate**2, np.cos(theta), np.sin(theta), np.ones_like(t)])
    return np.linalg.lstsq(basis, rx, rcond=None)[0]


def _radius_start(t, rx, theta0, omega) -> float:
    """r from the centripetal drift of r_x, w11 r w^2, taking w11 ~ 1."""
    coef = _rx_terms(t, rx, theta0, omega)[0]
    if coef <= 0:
        raise CalibrationError("the centripetal term could not be found in the data",
                               "give the radius (--radius), or spin faster and let the wheel coast down")
    return float(coef)
