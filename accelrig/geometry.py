"""Rotations shared by the sensor model and the estimators (one convention everywhere)."""

from __future__ import annotations

import numpy as np


def rot_x(a: float) -> np.ndarray:
    """Rotation by ``a`` rad about x."""
    c, s = np.cos(a), np.sin(a)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def rot_y(a: float) -> np.ndarray:
    """Rotation by ``a`` rad about y."""
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def rot_z(a: float) -> np.ndarray:
    """Rotation by ``a`` rad about z."""
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def rotation_xyz(angles: np.ndarray) -> np.ndarray:
    """Rotation matrix Rz(c) @ Ry(b) @ Rx(a) for angles (a, b, c) in rad."""
    a, b, c = np.asarray(angles, dtype=float)
    return rot_z(c) @ rot_y(b) @ rot_x(a)
