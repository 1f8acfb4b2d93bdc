"""The tilted, freely rotating wheel of paper 002 (Pedersini): a hand-spun bench coasting down.

The specific force is eq. 1 of the paper in the bench frame, turned into the
sensor's frame by the mounting misalignment R (eq. 4); the SensorModel then
applies its own gain and offset (eq. 5).  Use a SensorModel with zero
misalignment and non-orthogonality to reproduce the paper exactly: then the
sensor's response matrix is Gamma and its true canonical correction is
C = Gamma^-1, b = o.  (A sensor with its own misalignment R_s reads
Gamma R_s R a: the wheel sees the product R_s R as the mounting, so its gains
and offsets are still exact but its correction omits R_s, which no wheel can
tell from the mounting.)

Friction laws:
    cubic            angular velocity w(t) = w0 + w1 t + w2 t^2 + w3 t^3, the paper's law
                     (default: Table I's coefficients, scaled by speed / 9 rad/s)
    coulomb-viscous  w' = -(c + k w) for w > 0 (dry plus linear viscous friction): an
                     exponential decay towards a stop, which no cubic fits exactly
"""

from __future__ import annotations

import numpy as np

from accelrig.acquisition.url import DeviceURL
from accelrig.errors import DeviceError
from accelrig.procedures.wheel_model import (
    TABLE_I_MISALIGNMENT_DEG, TABLE_I_OMEGA, TABLE_I_THETA0_DEG, TABLE_I_TILT_DEG, bench_force, phase,
)
from accelrig.sim.rigs.base import Rig
from accelrig.geometry import rotation_xyz
from accelrig.units import STANDARD_GRAVITY

# Default hand spin: Table I's coast-down shape started at 6 rad/s, whose peak
# specific force (about 17 m/s^2) stays inside the +-2 g default range.
DEFAULT_SPEED = 6.0
BARELY_SPEED = 0.3       # spin=barely: a nudge, a handful of turns in 90 s
DEFAULT_COULOMB = 0.02   # rad/s^2, dry friction of the coulomb-viscous law
DEFAULT_VISCOUS = 0.01   # 1/s, viscous friction of the coulomb-viscous law


class WheelRig(Rig):
    name = "wheel"
    description = "tilted freely rotating wheel (paper 002): hand spun, coasting down"
    options = {
        "radius": "distance sensor - axis, m (default 0.28)",
        "tilt_deg": "tilt of the wheel axis from the vertical, deg (default 45)",
        "seconds": "length of the run, s (default 90)",
        "speed": f"initial angular velocity, rad/s (default {DEFAULT_SPEED:g}; Table I: 9, needs range=4)",
        "spin": "normal (default) or barely (a nudge that barely turns the wheel)",
        "friction": "cubic (default, the paper's law) or coulomb-viscous (not cubic)",
        "omega": "cubic law w0,w1,w2,w3 in rad/s^(k+1) (overrides speed)",
        "coulomb": f"dry friction, rad/s^2, coulomb-viscous only (default {DEFAULT_COULOMB:g})",
        "viscous": f"viscous friction, 1/s, coulomb-viscous only (default {DEFAULT_VISCOUS:g})",
        "misalignment": "mounting Euler angles theta,phi,psi in deg (default 30,20,25 as Table I)",
        "theta0_deg": "wheel phase at the first sample, deg (default 30)",
    }

    def __init__(
        self,
        radius: float = 0.28,
        tilt_deg: float = TABLE_I_TILT_DEG,
        duration: float = 90.0,
        omega: np.ndarray | None = None,
        friction: str = "cubic",
        coulomb: float = DEFAULT_COULOMB,
        viscous: float = DEFAULT_VISCOUS,
        misalignment_deg=TABLE_I_MISALIGNMENT_DEG,
        theta0_deg: float = TABLE_I_THETA0_DEG,
        g: float = STANDARD_GRAVITY,
    ):
        if radius <= 0:
            raise DeviceError(f"radius={radius} m: the sensor must sit off the axis", "give a positive radius")
        if not 0.0 <= tilt_deg <= 90.0:
            raise DeviceError(f"tilt_deg={tilt_deg} is outside 0 .. 90 degrees")
        if duration <= 0:
            raise DeviceError(f"seconds={duration} must be positive")
        if friction not in ("cubic", "coulomb-viscous"):
            raise DeviceError(f"friction={friction!r} is not a friction law", "use cubic or coulomb-viscous")
        if coulomb < 0 or viscous < 0:
            raise DeviceError("friction coefficients must not be negative")
        self.radius = float(radius)
        self.tilt = np.deg2rad(tilt_deg)
        self.duration = float(duration)
        self.omega = np.asarray(TABLE_I_OMEGA * DEFAULT_SPEED / 9.0 if omega is None else omega, dtype=float)
        self.friction = friction
        self.coulomb = float(coulomb)
        self.viscous = float(viscous)
        self.misalignment = np.deg2rad(np.asarray(misalignment_deg, dtype=float))
        self.rotation = rotation_xyz(self.misalignment)
        self.theta0 = np.deg2rad(theta0_deg)
        self.g = g

    @classmethod
    def from_url(cls, url: DeviceURL, rng: np.random.Generator) -> "WheelRig":
        spin = url.get_choice("spin", ("normal", "barely"), "normal")
        speed = url.get_float("speed", BARELY_SPEED if spin == "barely" else DEFAULT_SPEED)
        omega = _floats(url, "omega", 4)
        if omega is None:
            omega = TABLE_I_OMEGA * speed / 9.0
        misalignment = _floats(url, "misalignment", 3)
        return cls(
            radius=url.get_float("radius", 0.28),
            tilt_deg=url.get_float("tilt_deg", TABLE_I_TILT_DEG),
            duration=url.get_float("seconds", 90.0),
            omega=omega,
            friction=url.get_choice("friction", ("cubic", "coulomb-viscous"), "cubic"),
            coulomb=url.get_float("coulomb", DEFAULT_COULOMB),
            viscous=url.get_float("viscous", DEFAULT_VISCOUS),
            misalignment_deg=TABLE_I_MISALIGNMENT_DEG if misalignment is None else misalignment,
            theta0_deg=url.get_float("theta0_deg", TABLE_I_THETA0_DEG),
        )

    def motion(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """theta, theta', theta'' at times t (analytic for both friction laws)."""
        t = np.asarray(t, dtype=float)
        if self.friction == "cubic":
            return phase(t, self.theta0, self.omega)
        return self._coulomb_viscous(t)

    def _coulomb_viscous(self, t: np.ndarray):
        # w' = -sign(w0) (c + k |w|): |w|(t) = (|w0| + c/k) e^{-kt} - c/k until it stops.
        w0 = float(self.omega[0])
        direction = 1.0 if w0 >= 0 else -1.0
        c, k = self.coulomb, self.viscous
        speed0 = abs(w0)
        if k > 0:
            lim = c / k
            t_stop = np.log1p(speed0 / lim) / k if c > 0 else np.inf
            tc = np.minimum(t, t_stop)
            decay = np.exp(-k * tc)
            speed = (speed0 + lim) * decay - lim
            angle = (speed0 + lim) * (1 - decay) / k - lim * tc
            accel = -(c + k * speed)
        else:
            t_stop = speed0 / c if c > 0 else np.inf
            tc = np.minimum(t, t_stop)
            speed = speed0 - c * tc
            angle = speed0 * tc - c * tc**2 / 2
            accel = np.full_like(tc, -c)
        stopped = t >= t_stop
        speed = np.where(stopped, 0.0, speed)
        accel = np.where(stopped, 0.0, accel)
        return self.theta0 + direction * angle, direction * speed, direction * accel

    def bench_force(self, t: np.ndarray) -> np.ndarray:
        return bench_force(*self.motion(t), self.radius, self.tilt, self.g)

    def specific_force(self, t: np.ndarray) -> np.ndarray:
        """Sensor-frame specific force R a(t), before the sensor's gain and offset."""
        return self.bench_force(t) @ self.rotation.T

    def channels(self, t: np.ndarray) -> dict[str, np.ndarray]:
        # the true wheel angle, as an encoder on the hub would read it
        return {"theta": self.motion(t)[0]}

    channel_names = ("theta",)

    def truth(self) -> dict:
        return {
            "rig": self.name,
            "radius": self.radius,
            "tilt_rad": float(self.tilt),
            "tilt_deg": float(np.rad2deg(self.tilt)),
            "friction": self.friction,
            "omega": self.omega.tolist() if self.friction == "cubic" else None,
            "initial_speed": float(self.omega[0]),
            "coulomb": self.coulomb if self.friction == "coulomb-viscous" else None,
            "viscous": self.viscous if self.friction == "coulomb-viscous" else None,
            "theta0_rad": float(self.theta0),
            "misalignment_rad": self.misalignment.tolist(),
            "rotation": self.rotation.tolist(),
            "g": self.g,
        }


def _floats(url: DeviceURL, key: str, count: int) -> np.ndarray | None:
    text = url.get_str(key)
    if text is None:
        return None
    try:
        values = np.array([float(v) for v in text.split(",")])
    except ValueError:
        raise DeviceError(f"option {key}={text!r} in {url.raw!r} is not {count} comma-separated numbers") from None
    if values.size != count:
        raise DeviceError(f"option {key}={text!r} in {url.raw!r} needs {count} comma-separated numbers")
    return values
