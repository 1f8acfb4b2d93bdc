"""What an accelerometer riding a trajectory reads: the specific force, from first principles.

A rig describes the sensor's trajectory in the world, as plain functions of time:

    position(t)     p(t), m, world frame (z up), shape (n, 3)
    orientation(t)  R(t), world <- sensor rotation matrices, shape (n, 3, 3)

and the sensor reads f = R(t)^T (p''(t) - g_world), g_world = (0, 0, -g): at
rest the axis pointing up reads +g.  p'' comes from differentiating the
position function numerically, never from a formula for a rig's
acceleration, so the simulator shares no equation with the estimators it
judges: an error in an estimator's motion model cannot hide in the truth.

The stencil is the five-point central difference (fourth order)

    p''(t) ~ (-p(t-2h) + 16 p(t-h) - 30 p(t) + 16 p(t+h) - p(t+2h)) / (12 h^2)

Its error has three parts:

* truncation: h^4/90 |p^(6)|.  At the default h = 2^-12 s (244 us) that is
  3.9e-17 s^4 |p^(6)|: 6e-12 m/s^2 for a point at 0.28 m turning at 9 rad/s
  (p^(6) ~ r w^6), 1e-6 m/s^2 for a slider-crank at 13 Hz.
* rounding: an error delta in the position values costs (16/3) delta / h^2,
  8.9e7 s^-2 delta at the default step.  delta is a few ulp of |p| (1e-16 m
  near the origin), or more where the position goes through a large
  accumulated angle: after 100 turns (800 rad, ulp 1.1e-13) a point at
  0.28 m is off by 3e-14 m, 3e-6 m/s^2.  Keep the origin at the rig's centre.
* non-smooth motion: where p'' jumps (a motor ramp starting), the stencil
  blends the two sides for samples within 2h of the jump; where p''' jumps
  the error there is about 0.1 h |jump|.  A rig with sharp features takes
  a smaller step.

The step is a power of two, so t + k h is exact except where it crosses a
power of two, which costs at most (4/3) |p'| ulp(t) / h^2 (1e-6 m/s^2 at
2.5 m/s, t < 128 s, default step).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from accelrig.units import STANDARD_GRAVITY

DEFAULT_STEP = 2.0**-12  # s
OFFSETS = np.arange(-2, 3)
WEIGHTS = np.array([-1.0, 16.0, -30.0, 16.0, -1.0]) / 12.0

Trajectory = Callable[[np.ndarray], np.ndarray]


def acceleration(position: Trajectory, t: np.ndarray, step: float = DEFAULT_STEP) -> np.ndarray:
    """p''(t), world frame, m/s^2, shape (n, 3), by the five-point stencil on ``position``."""
    t = np.asarray(t, dtype=float).ravel()
    points = (t[None, :] + OFFSETS[:, None] * step).ravel()
    p = np.asarray(position(points), dtype=float).reshape(OFFSETS.size, t.size, 3)
    return np.tensordot(WEIGHTS, p, axes=1) / step**2


def specific_force(position: Trajectory, orientation: Trajectory, t: np.ndarray, g: float = STANDARD_GRAVITY,
                   step: float = DEFAULT_STEP) -> np.ndarray:
    """f = R(t)^T (p''(t) - g_world) in the sensor frame, m/s^2, shape (n, 3)."""
    t = np.asarray(t, dtype=float).ravel()
    world = acceleration(position, t, step) + np.array([0.0, 0.0, g])
    return np.einsum("nji,nj->ni", orientation(t), world)


def at_origin(t: np.ndarray) -> np.ndarray:
    """The position of a sensor that does not move."""
    return np.zeros((np.size(t), 3))


def level_mounting(forward: np.ndarray, up: np.ndarray) -> np.ndarray:
    """World <- sensor rotation of a sensor whose frame vectors ``forward`` and ``up`` (unit,
    orthogonal, sensor frame) point along world x and world z."""
    return np.array([forward, np.cross(up, forward), up], dtype=float)
