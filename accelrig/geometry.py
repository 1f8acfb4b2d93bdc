"""Rotations shared by the sensor model and the estimators (one convention everywhere)."""

from __future__ import annotations

import numpy as np


def rotation_xyz(angles: np.ndarray) -> np.ndarray:
    """Rotation matrix Rz(c) @ Ry(b) @ Rx(a) for angles (a, b, c) in rad."""
    a, b, c = np.asarray(angles, dtype=float)
    ca, sa, cb, sb, cc, sc = np.cos(a), np.sin(a), np.cos(b), np.sin(b), np.cos(c), np.sin(c)
    rx = np.array([[1, 0, 0], [0, ca, -sa], [0, sa, ca]])
    ry = np.array([[cb, 0, sb], [0, 1, 0], [-sb, 0, cb]])
    rz = np.array([[cc, -sc, 0], [sc, cc, 0], [0, 0, 1]])
    return rz @ ry @ rx
