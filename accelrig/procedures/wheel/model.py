"""The tilted-wheel model of Pedersini (paper 002), eq. 1-7, with its analytic Jacobian.

Bench frame <XYZ> (rigid with the wheel): X radial, pointing towards the axis;
Y tangential; Z along the wheel axis.  The specific force at the sensor is

    a_X = r w(t)^2    + g sin(alpha) cos(theta(t))
    a_Y = r w'(t)     + g sin(alpha) sin(theta(t))                      (eq. 1)
    a_Z =               g cos(alpha)

with the cubic angular-velocity law (eq. 2)

    w(t)     = w0 + w1 t + w2 t^2 + w3 t^3
    theta(t) = theta0 + w0 t + w1 t^2/2 + w2 t^3/3 + w3 t^4/4

t counted from the first sample.  The sensor reads (eq. 6)

    v(t) = o + Gamma R a(t),   Gamma = diag(gain),  R = rotation_xyz(theta, phi, psi)

R maps a bench-frame vector to the sensor frame (the mounting); Gamma and o
belong to the sensor, whose canonical correction is therefore C = Gamma^-1,
b = o (DESIGN.md).  The Euler convention is accelrig's
``rotation_xyz((theta, phi, psi)) = Rz(psi) Ry(phi) Rx(theta)`` (the paper
does not spell its own out).

Equivalent solutions are folded onto one: alpha in [0, 90] degrees, positive
gains; the spin direction is then the sign of w.  (A clockwise and a
counter-clockwise spin differ in the sign of w only: see docs/wheel.md.)
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from accelrig.estimation.crb import numerical_jacobian
from accelrig.geometry import rotation_xyz
from accelrig.units import STANDARD_GRAVITY

N_MOTION = 5  # theta0, w0 .. w3

# Paper 002, Table I truth: w3 = 2 urad/s^4, w2 = 500 urad/s^3, w1 = -90 mrad/s^2, w0 = 9 rad/s, ...
TABLE_I_OMEGA = np.array([9.0, -90e-3, 500e-6, 2e-6])
TABLE_I_THETA0_DEG = 30.0
TABLE_I_TILT_DEG = 45.0
TABLE_I_MISALIGNMENT_DEG = (30.0, 20.0, 25.0)
TABLE_I_GAIN = (0.9, 1.0, 1.1)
TABLE_I_OFFSET = (1.0, -1.0, 1.0)


@dataclass
class WheelState:
    """One point of the model space m of eq. 7 (SI units, angles in rad)."""

    theta0: float
    omega: np.ndarray            # w0 .. w3 in rad/s, rad/s^2, rad/s^3, rad/s^4
    tilt: float                  # alpha
    radius: float                # r
    rotation: np.ndarray         # R (3, 3), bench -> sensor
    gain: np.ndarray = field(default_factory=lambda: np.ones(3))
    offset: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def __post_init__(self) -> None:
        self.omega = np.asarray(self.omega, dtype=float).reshape(4)
        self.rotation = np.asarray(self.rotation, dtype=float).reshape(3, 3)
        self.gain = np.asarray(self.gain, dtype=float).reshape(3)
        self.offset = np.asarray(self.offset, dtype=float).reshape(3)

    def copy(self) -> WheelState:
        return WheelState(self.theta0, self.omega.copy(), self.tilt, self.radius, self.rotation.copy(),
                          self.gain.copy(), self.offset.copy())

    @property
    def euler(self) -> np.ndarray:
        return euler_from_rotation(self.rotation)

    def canonical(self) -> WheelState:
        """Fold the model's discrete symmetries onto alpha in [0, pi/2], gains > 0, theta0 in [0, 2pi).

        alpha -> -alpha with theta -> theta + pi gives the same data; so does a
        negative gain pair with R flipped about the third axis.
        """
        s = self.copy()
        if np.sin(s.tilt) < 0:  # a_XY gravity terms change sign: absorb in the phase
            s.tilt = -s.tilt
            s.theta0 += np.pi
        if np.cos(s.tilt) < 0:  # a_Z changes sign; (w, theta, R) -> (-w, -theta, R diag(1,-1,-1))
            s.tilt = np.pi - s.tilt
            s.omega = -s.omega
            s.theta0 = -s.theta0
            s.rotation = s.rotation @ np.diag([1.0, -1.0, -1.0])
        flip = np.sign(s.gain)
        flip[flip == 0] = 1.0
        if np.prod(flip) < 0:
            # an odd number of negative gains cannot come with a proper rotation
            raise ValueError("gains with an odd number of negative signs")
        s.gain = s.gain * flip
        s.rotation = np.diag(flip) @ s.rotation
        s.theta0 = float(np.mod(s.theta0, 2 * np.pi))
        return s


# ----------------------------------------------------------------------------- physics


def phase(t: np.ndarray, theta0: float, omega: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """theta(t), theta'(t), theta''(t) of the cubic angular-velocity law (eq. 2)."""
    w0, w1, w2, w3 = omega
    theta = theta0 + t * (w0 + t * (w1 / 2 + t * (w2 / 3 + t * w3 / 4)))
    rate = w0 + t * (w1 + t * (w2 + t * w3))
    accel = w1 + t * (2 * w2 + t * 3 * w3)
    return theta, rate, accel


def bench_force(theta: np.ndarray, rate: np.ndarray, accel: np.ndarray, radius: float, tilt: float,
                g: float = STANDARD_GRAVITY) -> np.ndarray:
    """Specific force in the bench frame (eq. 1), shape (n, 3), for any phase law."""
    ga = g * np.sin(tilt)
    out = np.empty((np.size(theta), 3))
    out[:, 0] = radius * rate**2 + ga * np.cos(theta)
    out[:, 1] = radius * accel + ga * np.sin(theta)
    out[:, 2] = g * np.cos(tilt)
    return out


def predict(t: np.ndarray, state: WheelState, g: float = STANDARD_GRAVITY) -> np.ndarray:
    """Sensor output v(t) = o + Gamma R a(t) (eq. 6), shape (n, 3)."""
    a = bench_force(*phase(t, state.theta0, state.omega), state.radius, state.tilt, g)
    return state.offset + (a @ state.rotation.T) * state.gain


# ------------------------------------------------------------------------- rotations


def skew(v: np.ndarray) -> np.ndarray:
    x, y, z = v
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def rotation_from_vector(v: np.ndarray) -> np.ndarray:
    """Rodrigues: the rotation by |v| rad about v."""
    v = np.asarray(v, dtype=float)
    angle = float(np.linalg.norm(v))
    k = skew(v)
    if angle < 1e-12:
        return np.eye(3) + k
    return np.eye(3) + np.sin(angle) / angle * k + (1 - np.cos(angle)) / angle**2 * (k @ k)


def euler_from_rotation(rot: np.ndarray) -> np.ndarray:
    """(theta, phi, psi) with rot = Rz(psi) Ry(phi) Rx(theta), phi in [-pi/2, pi/2]."""
    rot = np.asarray(rot, dtype=float)
    phi = np.arcsin(np.clip(-rot[2, 0], -1.0, 1.0))
    theta = np.arctan2(rot[2, 1], rot[2, 2])
    psi = np.arctan2(rot[1, 0], rot[0, 0])
    return np.array([theta, phi, psi])


def euler_jacobian(rot: np.ndarray, step: float = 1e-6) -> np.ndarray:
    """d(Euler angles)/d(delta) for rot(delta) = exp([delta]x) rot, at delta = 0 (3 x 3).

    Central differences of the angle change wrapped to (-pi, pi], so a psi
    near +-180 degrees does not jump.  Smooth away from phi = +-90 degrees,
    where the Euler angles themselves stop being defined (gimbal lock).
    """
    centre = euler_from_rotation(rot)

    def change(delta: np.ndarray) -> np.ndarray:
        return np.angle(np.exp(1j * (euler_from_rotation(rotation_from_vector(delta) @ rot) - centre)))

    return numerical_jacobian(change, np.zeros(3), step)


def rotation_from_euler(angles: np.ndarray) -> np.ndarray:
    return rotation_xyz(angles)


# --------------------------------------------------------------------- joint model


@dataclass
class FreeSet:
    """Which geometry parameter is free: the null space of section II-C needs r or alpha fixed."""

    radius_free: bool
    tilt_free: bool

    @property
    def names(self) -> list[str]:
        geo = (["tilt"] if self.tilt_free else []) + (["radius"] if self.radius_free else [])
        return (["theta0", "omega0", "omega1*T", "omega2*T^2", "omega3*T^3"] + geo
                + ["mount_rotation_x", "mount_rotation_y", "mount_rotation_z"]
                + ["gain_x", "gain_y", "gain_z", "offset_x", "offset_y", "offset_z"])

    @property
    def size(self) -> int:
        return len(self.names)

    @property
    def rotation_slice(self) -> slice:
        i = N_MOTION + int(self.tilt_free) + int(self.radius_free)
        return slice(i, i + 3)


def pack(state: WheelState, free: FreeSet, time_scale: float) -> np.ndarray:
    """Internal vector: the angular-velocity coefficients scaled to rad/s at t = time_scale
    (c_k = w_k T^k) so the normal equations stay well conditioned; rotation as an
    increment (zero) about ``state.rotation``."""
    c = state.omega * time_scale ** np.arange(4)
    geo = ([state.tilt] if free.tilt_free else []) + ([state.radius] if free.radius_free else [])
    return np.concatenate([[state.theta0], c, geo, np.zeros(3), state.gain, state.offset])


def unpack(x: np.ndarray, free: FreeSet, time_scale: float, base: WheelState) -> WheelState:
    """Inverse of ``pack``; the rotation increment is applied to ``base.rotation``."""
    i = N_MOTION
    tilt, radius = base.tilt, base.radius
    if free.tilt_free:
        tilt = x[i]
        i += 1
    if free.radius_free:
        radius = x[i]
        i += 1
    rot = rotation_from_vector(x[i:i + 3]) @ base.rotation
    i += 3
    return WheelState(x[0], x[1:5] / time_scale ** np.arange(4), tilt, radius, rot, x[i:i + 3], x[i + 3:i + 6])


def model_and_jacobian(t: np.ndarray, state: WheelState, free: FreeSet, time_scale: float,
                       g: float = STANDARD_GRAVITY) -> tuple[np.ndarray, np.ndarray]:
    """v(t) (n, 3) and dv/dx (n, 3, p) in the internal parameters of ``pack`` at ``state``
    (rotation increment zero)."""
    tau = t / time_scale
    theta, rate, accel = phase(t, state.theta0, state.omega)
    r, tilt, gamma, rot = state.radius, state.tilt, state.gain, state.rotation
    sa, ca = np.sin(tilt), np.cos(tilt)
    cos_t, sin_t = np.cos(theta), np.sin(theta)
    n = t.size
    a = bench_force(theta, rate, accel, r, tilt, g)
    s = a @ rot.T                      # sensed, sensor frame
    v = state.offset + s * gamma

    # d a / d (bench parameters), shape (n, 3, k)
    da = []
    da.append(np.stack([-g * sa * sin_t, g * sa * cos_t, np.zeros(n)], axis=1))  # theta0
    tau_pow = [np.ones(n), tau, tau**2, tau**3, tau**4]
    for k in range(4):
        d_theta = time_scale * tau_pow[k + 1] / (k + 1)
        d_rate = tau_pow[k]
        d_accel = k * tau_pow[k - 1] / time_scale if k > 0 else np.zeros(n)
        da.append(np.stack([2 * r * rate * d_rate - g * sa * sin_t * d_theta,
                            r * d_accel + g * sa * cos_t * d_theta, np.zeros(n)], axis=1))
    if free.tilt_free:
        da.append(np.stack([g * ca * cos_t, g * ca * sin_t, np.full(n, -g * sa)], axis=1))
    if free.radius_free:
        da.append(np.stack([rate**2, accel, np.zeros(n)], axis=1))
    da = np.stack(da, axis=2)                                     # (n, 3, kb)
    jac = np.empty((n, 3, free.size))
    kb = da.shape[2]
    # Gamma R da: rotate each column then scale rows
    jac[:, :, :kb] = np.matmul(rot, da) * gamma[None, :, None]
    # rotation increment: d(exp([d]x) R a)/d d_k = e_k x (R a)
    for k in range(3):
        e = np.zeros(3)
        e[k] = 1.0
        jac[:, :, kb + k] = np.cross(e, s) * gamma
    jac[:, :, kb + 3:kb + 6] = 0.0
    for k in range(3):
        jac[:, k, kb + 3 + k] = s[:, k]
    jac[:, :, kb + 6:] = 0.0
    for k in range(3):
        jac[:, k, kb + 6 + k] = 1.0
    return v, jac
