"""The tilted, freely rotating wheel of paper 002 (Pedersini): a hand-spun bench coasting down.

The trajectory, from the geometry alone: the hub sits at the origin, the wheel
axis Z is tilted by alpha from the vertical (towards world x), and the sensor
rides the rim at radius r.  The bench frame <XYZ> turns with the wheel: X
radial towards the axis, Y along the motion (increasing wheel angle theta),
Z = X x Y.  theta = 0 puts the sensor at the lowest point of the rim, and
theta increases clockwise seen from above (the spin turns about -Z; w < 0
spins the other way).  The sensor is mounted with the misalignment R
(bench -> sensor, paper eq. 4), so its orientation is [X Y Z] R^T.
accelrig.sim.kinematics turns position and orientation into the specific
force (eq. 1 is what comes out, never what goes in), and the SensorModel
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

An unbalanced wheel (``imbalance`` b > 0, rad/s^2): a mass off the hub feels
gravity's pull along the tilted rim, a torque b sin(theta - theta_b) that
speeds the wheel up on the way down and slows it on the way up, so its speed
swings once per turn on top of the friction law:

    theta'' = (friction law's w') - b sin(theta - theta_b)

integrated numerically (DOP853, dense output); the friction term is the law's
w' at the same time (cubic) or at the same speed (coulomb-viscous).

The operator's record (``rest`` and ``push`` seconds): the wheel stands still for ``rest`` s, then a
hand spins it up over ``push`` s with a torque shaped sin^2 (speed w_c (x - sin(2 pi x) / (2 pi)), x the
share of the push done, w_c the coast's first speed), then it coasts as above; the
coast's laws and ``theta0_deg`` count from the coast's start, and the record is ``rest + push +
seconds`` long.
"""

from __future__ import annotations

import numpy as np

from accelrig.acquisition.url import DeviceURL
from accelrig.errors import DeviceError
from accelrig.geometry import rotation_xyz
from accelrig.sim import kinematics
from accelrig.sim.rigs.base import Rig
from accelrig.units import STANDARD_GRAVITY

# Paper 002, Table I truth: w0 = 9 rad/s, w1 = -90 mrad/s^2, w2 = 500 urad/s^3, w3 = 2 urad/s^4,
# theta0 30 deg, tilt 45 deg, misalignment 30, 20, 25 deg.  Facts of the paper's rig, kept here
# because the simulator imports no procedure code (accelrig.procedures.wheel.model has its own copy).
TABLE_I_OMEGA = np.array([9.0, -90e-3, 500e-6, 2e-6])
TABLE_I_THETA0_DEG = 30.0
TABLE_I_TILT_DEG = 45.0
TABLE_I_MISALIGNMENT_DEG = (30.0, 20.0, 25.0)

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
        "imbalance": "peak angular acceleration from an unbalanced mass, rad/s^2 (default 0: balanced)",
        "imbalance_deg": "wheel angle at which the unbalanced mass hangs lowest, deg (default 0)",
        "wobble_deg": "bearing play: the wheel's axis nods by this once per turn, deg (default 0: runs true)",
        "wobble_turns": "how many times per turn the axis nods (default 1; 2: a bearing worn out of round)",
        "wobble_above": "the axis nods only while the wheel turns faster than this, rad/s (default 0: always)",
        "rest": "seconds the wheel stands still before the hand spins it (default 0: the record starts coasting)",
        "push": "seconds the hand takes to spin the wheel up from rest before it coasts (default 0)",
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
        imbalance: float = 0.0,
        imbalance_deg: float = 0.0,
        wobble_deg: float = 0.0,
        wobble_turns: int = 1,
        wobble_above: float = 0.0,
        rest: float = 0.0,
        push: float = 0.0,
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
        if imbalance < 0:
            raise DeviceError(f"imbalance={imbalance} must not be negative")
        if rest < 0 or push < 0 or (rest > 0 and push == 0):
            raise DeviceError(f"rest={rest}, push={push}: a wheel at rest needs a push (seconds > 0) to turn",
                              "give push=2 with rest, or neither")
        self.rest, self.push = float(rest), float(push)
        self.radius = float(radius)
        self.tilt = np.deg2rad(tilt_deg)
        self.duration = float(duration) + self.rest + self.push
        self.omega = np.asarray(TABLE_I_OMEGA * DEFAULT_SPEED / 9.0 if omega is None else omega, dtype=float)
        self.friction = friction
        self.coulomb = float(coulomb)
        self.viscous = float(viscous)
        self.misalignment = np.deg2rad(np.asarray(misalignment_deg, dtype=float))
        self.rotation = rotation_xyz(self.misalignment)
        self.theta0 = np.deg2rad(theta0_deg)
        self.g = g
        self.imbalance = float(imbalance)
        self.imbalance_angle = np.deg2rad(imbalance_deg)
        self.wobble = np.deg2rad(wobble_deg)
        self.wobble_turns = int(wobble_turns)
        self.wobble_above = float(wobble_above)
        self._unbalanced = None   # dense solution of the unbalanced motion, made on first use
        # the angle is the integral of the cubic speed law, starting at theta0
        self._angle_law = np.polynomial.Polynomial(self.omega).integ(k=self.theta0)
        # the bench frame at theta = 0: Z tilted towards world x, X pointing from the rim's lowest point to the axis
        self._bench0 = np.column_stack([
            [-np.cos(self.tilt), 0.0, np.sin(self.tilt)], [0.0, -1.0, 0.0], [np.sin(self.tilt), 0.0, np.cos(self.tilt)],
        ])

    @classmethod
    def from_url(cls, url: DeviceURL, rng: np.random.Generator) -> WheelRig:
        spin = url.get_choice("spin", ("normal", "barely"), "normal")
        speed = url.get_float("speed", BARELY_SPEED if spin == "barely" else DEFAULT_SPEED, low=0.0, low_open=True,
                              high=200.0, unit="rad/s")
        omega = _floats(url, "omega", 4)
        if omega is None:
            omega = TABLE_I_OMEGA * speed / 9.0
        misalignment = _floats(url, "misalignment", 3)
        return cls(
            radius=url.get_float("radius", 0.28, low=0.0, low_open=True, high=2.0, unit="m"),
            tilt_deg=url.get_float("tilt_deg", TABLE_I_TILT_DEG),   # the rig checks 0 .. 90 itself
            duration=url.get_float("seconds", 90.0, low=0.0, low_open=True, high=86400.0, unit="s"),
            omega=omega,
            friction=url.get_choice("friction", ("cubic", "coulomb-viscous"), "cubic"),
            coulomb=url.get_float("coulomb", DEFAULT_COULOMB, low=0.0),
            viscous=url.get_float("viscous", DEFAULT_VISCOUS, low=0.0),
            misalignment_deg=TABLE_I_MISALIGNMENT_DEG if misalignment is None else misalignment,
            theta0_deg=url.get_float("theta0_deg", TABLE_I_THETA0_DEG),
            imbalance=url.get_float("imbalance", 0.0, low=0.0),
            imbalance_deg=url.get_float("imbalance_deg", 0.0),
            wobble_deg=url.get_float("wobble_deg", 0.0, low=0.0, high=5.0, unit="deg"),
            wobble_turns=url.get_int("wobble_turns", 1, low=1, high=4),
            wobble_above=url.get_float("wobble_above", 0.0, low=0.0, unit="rad/s"),
            rest=url.get_float("rest", 0.0, low=0.0, high=3600.0, unit="s"),
            push=url.get_float("push", 0.0, low=0.0, high=60.0, unit="s"),
        )

    def motion(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Wheel angle theta and angular velocity theta' at times t: at rest, pushed, then coasting."""
        t = np.asarray(t, dtype=float)
        before = self.rest + self.push
        if before == 0:
            return self._coast(t)
        angle, rate = self._coast(np.maximum(t - before, 0.0))
        pushed = t < before
        if np.any(pushed):
            w_c = float(self._coast(np.zeros(1))[1][0])
            x = np.clip((t[pushed] - self.rest) / self.push, 0.0, 1.0)
            rate[pushed] = w_c * (x - np.sin(2 * np.pi * x) / (2 * np.pi))
            # the angle still to sweep before the coast: w_c push times the integral of the speed shape from x to 1
            to_go = 0.5 - x**2 / 2 - (np.cos(2 * np.pi * x) - 1) / (4 * np.pi**2)
            angle[pushed] = self.theta0 - w_c * self.push * to_go
        return angle, rate

    def _coast(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The coast-down from its first sample (analytic for both friction laws)."""
        if self.imbalance > 0:
            return self._unbalanced_motion(t)
        if self.friction == "cubic":
            return self._angle_law(t), np.polynomial.Polynomial(self.omega)(t)
        return self._coulomb_viscous(t)

    def _unbalanced_motion(self, t: np.ndarray):
        """theta, theta' of the unbalanced wheel: the equation of motion integrated once, densely."""
        if self._unbalanced is None:
            from scipy.integrate import solve_ivp

            cubic_accel = np.polynomial.Polynomial(self.omega).deriv()
            c, k = self.coulomb, self.viscous

            def rhs(time, y):
                theta, rate = y
                if self.friction == "cubic":
                    friction = cubic_accel(time)
                else:   # dry + viscous, against the motion; a wheel at rest stays there under friction
                    friction = -np.sign(rate) * (c + k * abs(rate))
                return [rate, friction - self.imbalance * np.sin(theta - self.imbalance_angle)]

            # forwards and backwards from t = 0, with a margin: the kinematics differentiates
            # around the first and the last sample
            start = [self.theta0, float(self.omega[0])]
            self._unbalanced = [solve_ivp(rhs, (0.0, end), start, method="DOP853", dense_output=True,
                                          rtol=1e-11, atol=1e-11).sol for end in (self.duration + 1.0, -1.0)]
        forward, backward = self._unbalanced
        out = np.where(t >= 0, forward(np.clip(t, 0.0, self.duration + 1.0)), backward(np.clip(t, -1.0, 0.0)))
        return out[0], out[1]

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
        else:
            t_stop = speed0 / c if c > 0 else np.inf
            tc = np.minimum(t, t_stop)
            speed = speed0 - c * tc
            angle = speed0 * tc - c * tc**2 / 2
        speed = np.where(t >= t_stop, 0.0, speed)
        return self.theta0 + direction * angle, direction * speed

    def _bench_frame(self, t: np.ndarray) -> np.ndarray:
        """[X Y Z] (columns, world frame) at times t: the frame at theta = 0 turned by theta about -Z."""
        theta, speed = self.motion(t)
        c, s = np.cos(theta)[:, None], np.sin(theta)[:, None]
        x0, y0, z = self._bench0.T
        frame = np.stack([c * x0 - s * y0, c * y0 + s * x0, np.broadcast_to(z, c.shape[:1] + (3,))], axis=2)
        if self.wobble:
            # bearing play: the whole wheel (axis, rim and sensor) nods about the horizontal world y axis, by
            # wobble cos(k theta): its tilt swings k times per turn
            nod = self.wobble * np.cos(self.wobble_turns * theta)
            if self.wobble_above:
                # play that opens only when the wheel runs fast: the nod fades in over 0.5 rad/s
                nod = nod * np.clip((np.abs(speed) - self.wobble_above) / 0.5 + 0.5, 0.0, 1.0)
            cn, sn = np.cos(nod), np.sin(nod)
            turn = np.zeros((theta.size, 3, 3))
            turn[:, 0, 0], turn[:, 0, 2], turn[:, 1, 1], turn[:, 2, 0], turn[:, 2, 2] = cn, sn, 1.0, -sn, cn
            frame = turn @ frame
        return frame

    def position(self, t: np.ndarray) -> np.ndarray:
        """On the rim, opposite X (which points at the axis)."""
        return -self.radius * self._bench_frame(t)[:, :, 0]

    def orientation(self, t: np.ndarray) -> np.ndarray:
        return self._bench_frame(t) @ self.rotation.T

    def specific_force(self, t: np.ndarray) -> np.ndarray:
        """Sensor-frame specific force, before the sensor's gain and offset."""
        return kinematics.specific_force(self.position, self.orientation, t, self.g)

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
            "imbalance": self.imbalance,
            "imbalance_rad": float(self.imbalance_angle),
            "misalignment_rad": self.misalignment.tolist(),
            "rotation": self.rotation.tolist(),
            "g": self.g,
            "coast_from": self.rest + self.push,
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
