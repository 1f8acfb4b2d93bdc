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


def rotation_xyz_derivatives(alpha: np.ndarray) -> np.ndarray:
    """d R / d angle_k (3, 3, 3) of R = Rz(c) Ry(b) Rx(a), the convention of rotation_xyz and Listing 1."""
    a, b, c = alpha
    ca, sa, cb, sb, cc, sc = np.cos(a), np.sin(a), np.cos(b), np.sin(b), np.cos(c), np.sin(c)
    rx = np.array([[1, 0, 0], [0, ca, -sa], [0, sa, ca]])
    ry = np.array([[cb, 0, sb], [0, 1, 0], [-sb, 0, cb]])
    rz = np.array([[cc, -sc, 0], [sc, cc, 0], [0, 0, 1]])
    drx = np.array([[0, 0, 0], [0, -sa, -ca], [0, ca, -sa]])
    dry = np.array([[-sb, 0, cb], [0, 0, 0], [-cb, 0, -sb]])
    drz = np.array([[-sc, -cc, 0], [cc, -sc, 0], [0, 0, 0]])
    return np.array([rz @ ry @ drx, rz @ dry @ rx, drz @ ry @ rx])


# ---------------------------------------------------------------- axes and faces
# The sensor's axes by name, and the six faces a cube-shaped housing rests on.
# A face is named by the axis that points DOWN ("+z" down: the sensor lies on its
# back, z pointing at the floor); at rest that axis reads -g (specific force).
AXES = ("x", "y", "z")
FACES = ("+x", "-x", "+y", "-y", "+z", "-z")


def opposite_face(face: str) -> str:
    """'+z' -> '-z': the face of the same axis on the other side."""
    return ("-" if face[0] == "+" else "+") + face[1:]


def parse_axis(spec: str) -> tuple[int, float] | None:
    """'x', '+y', '-z' -> (index, sign); None if ``spec`` names no axis."""
    text = str(spec).strip().lower().replace(" ", "+")
    sign = -1.0 if text.startswith("-") else 1.0
    name = text.lstrip("+-")
    return (AXES.index(name), sign) if len(name) == 1 and name in AXES else None


def axis_vector(spec: str) -> np.ndarray | None:
    """'x', '+y', '-z' -> the signed unit vector along that axis; None if ``spec`` names no axis."""
    parsed = parse_axis(spec)
    if parsed is None:
        return None
    v = np.zeros(3)
    v[parsed[0]] = parsed[1]
    return v


def face_down_direction(face: str) -> np.ndarray:
    """Unit vector (sensor frame) of the axis that points down when the housing rests on ``face``."""
    if face not in FACES:
        raise ValueError(f"not a face: {face!r}")
    return axis_vector(face)
