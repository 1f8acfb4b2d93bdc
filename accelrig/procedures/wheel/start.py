"""The joint fit's start: the paper's steps A and B, then step C in closed form (no search).

Given the phase law theta(t) of step B, the model is linear in what is left:

    v(t) = o + M_0 r w(t)^2 + M_1 r w'(t) + M_2 g cos(alpha) + g sin(alpha) (M_0 cos theta + M_1 sin theta)

with M = Gamma R (columns M_0, M_1, M_2).  One linear least-squares pass gives
Q = g sin(alpha) [M_0 M_1] from the cos/sin columns (the gravity signal, well
determined).  R has orthonormal columns, so with y_k = 1 / (g sin(alpha) gamma_k)^2

    sum_k Q_k0^2 y_k = 1,   sum_k Q_k1^2 y_k = 1,   sum_k Q_k0 Q_k1 y_k = 0

three linear equations for the three y_k: the gains up to the common factor
g sin(alpha), and R_0, R_1 (R_2 = R_0 x R_1).  The centripetal and tangential
terms then give that factor through u = r / (g sin(alpha)), one scalar fitted
over all three axes, which the known radius or the known tilt turns into the
other; the offsets are what is left of the constant.  The discrete ambiguities
of step B (theta + pi, and the spin direction theta -> -theta) are settled by
u > 0 and by the wheel axis pointing up (cos(alpha) > 0 in the constant term),
as the paper's own steps assume.

This replaces the paper's 4-D Nelder-Mead search of step C, which is what made the
joint method slower than the four steps it started from (it ran them in full).
When the closed form has no solution (y_k <= 0: a sensor axis nearly along the
wheel axis, or a signal the phase law does not follow), the four steps are the start.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from accelrig.procedures.wheel.checks import WheelSurvey
from accelrig.procedures.wheel.model import WheelState, phase
from accelrig.procedures.wheel.paper import PaperSteps, paper_calibrate, paper_motion
from accelrig.units import STANDARD_GRAVITY


def _closed_form(t, v, theta0, omega, radius, tilt, g) -> WheelState | None:
    theta, rate, accel = phase(t, theta0, omega)
    basis = np.column_stack([np.ones_like(t), rate**2, accel, np.cos(theta), np.sin(theta)])
    coef, *_ = np.linalg.lstsq(basis, v, rcond=None)          # (5, 3)
    q = coef[3:5].T                                             # (3, 2): g sin(alpha) [M_0 M_1]
    system = np.column_stack([q[:, 0] ** 2, q[:, 1] ** 2, q[:, 0] * q[:, 1]]).T
    try:
        y = np.linalg.solve(system, np.array([1.0, 1.0, 0.0]))
    except np.linalg.LinAlgError:
        return None
    if not np.all(y > 0):
        return None
    scaled_gain = 1.0 / np.sqrt(y)                              # g sin(alpha) gamma_k
    r0, r1 = q[:, 0] / scaled_gain, q[:, 1] / scaled_gain
    r2 = np.cross(r0, r1)
    rotation = np.column_stack([r0, r1, r2])
    # u = r / (g sin(alpha)): v - gravity part = o' + u (G R_0 w^2 + G R_1 w'), G = g sin(alpha) gamma
    rest = v - np.column_stack([np.cos(theta), np.sin(theta)]) @ q.T
    f = np.outer(rate**2, scaled_gain * r0) + np.outer(accel, scaled_gain * r1)
    f_mean, rest_mean = f.mean(axis=0), rest.mean(axis=0)
    denom = float(np.sum((f - f_mean) ** 2))
    if not denom > 0:
        return None
    u = float(np.sum((f - f_mean) * (rest - rest_mean)) / denom)
    if not u > 0:
        return None
    if radius is not None:
        sin_alpha = radius / (g * u)
        if tilt is not None:
            sin_alpha = np.sin(tilt)
        if not 0 < sin_alpha < 1:
            return None
        alpha = float(np.arcsin(sin_alpha))
        r = float(radius)
    else:
        alpha = float(tilt)
        r = float(u * g * np.sin(alpha))
    gain = scaled_gain / (g * np.sin(alpha))
    constant = rest_mean - u * f_mean                           # o + gamma R_2 g cos(alpha)
    offset = constant - gain * r2 * g * np.cos(alpha)
    # the constant's part along the axis must be + g cos(alpha): else the spin direction is the other one
    if float(np.sum(constant / gain * r2)) < 0:
        return None
    return WheelState(theta0, omega, alpha, r, rotation, gain, offset)


# The start needs the phase law only well enough for the joint fit to converge from it: beyond this
# many samples it looks at every k-th one, so its time and memory stop growing with the record.
START_SAMPLES = 40_000


def joint_start(t: np.ndarray, v: np.ndarray, survey: WheelSurvey, radius: float | None, tilt: float | None,
                g: float = STANDARD_GRAVITY, gap_times: np.ndarray | None = None) -> PaperSteps:
    """A start for the joint fit: steps A, B, then step C in closed form; the four steps if that fails."""
    stride = max(1, int(np.ceil(t.size / START_SAMPLES)))
    if stride > 1:
        t, v = t[::stride], v[::stride]
        survey = replace(survey, period=survey.period * stride)
    motion = paper_motion(t, v, survey, gap_times)
    amplitude = abs(motion.amplitude)
    for direction in (1.0, -1.0):
        for shift in (0.0, np.pi):
            theta0 = direction * motion.theta0 + shift
            omega = direction * motion.omega
            state = _closed_form(t, v, theta0, omega, radius, tilt, g)
            if state is None:
                continue
            try:
                state = state.canonical()
            except ValueError:
                continue
            w22 = np.sqrt(2.0) * np.std(motion.realigned[:, 1]) / (g * np.sin(state.tilt))
            return PaperSteps(state, motion.realignment, amplitude, float(w22), motion.speed_time,
                              motion.speed_samples, motion.n_function_evaluations)
    return paper_calibrate(t, v, survey, radius, tilt, g, gap_times)
