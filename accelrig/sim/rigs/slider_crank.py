"""Slider-crank test stand (paper 000, section 4): a DC motor turns a crank, a rod drives a slider.

Exact kinematics (REFERENCES.md): with crank angle phi, radius r, rod l,
x(phi) = r cos phi + sqrt(l^2 - r^2 sin^2 phi), and the slider's acceleration
is a = x''(phi) omega^2 + x'(phi) omega_dot (the second term matters while the
motor changes speed).  The motor runs a list of speed steps; each step starts
with a settling ramp from the previous speed (``step`` channel = -1 there,
the step index afterwards).

Imperfections the verification must see:
* clearance: the effective crank radius differs from the nominal (caliper)
  radius by a value drawn uniformly in +-clearance.
* backlash: the slider's joint has ``backlash`` metres of play.  At each dead
  centre the velocity reverses and the play is taken up on the other side: a
  step of the play through the contact's resonance (a knock, paper Fig. 6).
* motor limit: above ``max_speed`` the motor cannot follow: its speed falls
  back below the limit (the more so the harder it is pushed) and hunts with a
  slow ripple (paper: a drop-off above about 11.5 Hz).
"""

from __future__ import annotations

import numpy as np

from accelrig.acquisition.url import DeviceURL
from accelrig.errors import DeviceError
from accelrig.sim.rigs.base import Rig
from accelrig.units import STANDARD_GRAVITY

_AXES = {"+x": (1, 0, 0), "-x": (-1, 0, 0), "+y": (0, 1, 0), "-y": (0, -1, 0), "+z": (0, 0, 1), "-z": (0, 0, -1)}

# The contact that takes up the play rings at this frequency and damping; the
# knock's peak is about 20 m/s^2 per 0.1 mm of play.
KNOCK_FREQUENCY = 80.0
KNOCK_DAMPING = 0.25
# Beyond the motor limit: speed lost per Hz of excess command, and the hunting ripple.
OVERLOAD_DROOP = 0.3
HUNT_RIPPLE = 0.02
HUNT_FREQUENCY = 1.7
KNOCK_RISE = 0.002  # s over which the play is taken up


def _resonator_velocity(tau: np.ndarray) -> np.ndarray:
    """Derivative of the contact resonator's unit step response (0 before the step)."""
    wn = 2 * np.pi * KNOCK_FREQUENCY
    zeta = KNOCK_DAMPING
    wd = wn * np.sqrt(1 - zeta**2)
    positive = np.maximum(tau, 0.0)
    return np.where(tau > 0, wn / np.sqrt(1 - zeta**2) * np.exp(-zeta * wn * positive) * np.sin(wd * positive), 0.0)


def slider_position(phi, radius: float, rod: float):
    """x(phi) and its first and second derivatives in phi (exact, no series)."""
    s, c = np.sin(phi), np.cos(phi)
    root = np.sqrt(rod**2 - radius**2 * s**2)
    x = radius * c + root
    dx = -radius * s - radius**2 * s * c / root
    ddx = -radius * c - radius**2 * (np.cos(2 * phi) * root**2 + radius**2 * s**2 * c**2) / root**3
    return x, dx, ddx


def parse_axis(text: str) -> np.ndarray:
    """'+x' .. '-z' or three comma-separated components -> unit vector."""
    text = text.strip().replace(" ", "+")
    if text in _AXES:
        return np.array(_AXES[text], dtype=float)
    try:
        vec = np.array([float(v) for v in text.split(",")], dtype=float)
    except ValueError:
        vec = np.zeros(0)
    if vec.shape != (3,) or not np.all(np.isfinite(vec)) or np.linalg.norm(vec) == 0:
        raise DeviceError(f"axis={text!r} is not a direction", "use +x, -x, +y, -y, +z, -z or three numbers like 1,0.05,0")
    return vec / np.linalg.norm(vec)


class SliderCrankRig(Rig):
    name = "slider-crank"
    description = "slider-crank stand: exact kinematics over motor speed steps, clearance, backlash knocks"
    options = {
        "steps": "motor speed steps in Hz, comma-separated (default 2.5,4,6,8,10,11,12,13)",
        "step_seconds": "seconds of steady running recorded per step (default 1)",
        "settle": "seconds of speed ramp before each step, step channel -1 (default 0.5)",
        "radius": "nominal (caliper) crank radius, m (default 0.00635)",
        "rod": "connecting rod length, m (default 0.0353, lambda = 0.18)",
        "clearance": "+-clearance on the radius, m: the effective radius is drawn inside it (default 0)",
        "backlash": "play in the slider joint, m: knocks at the dead centres (default 0)",
        "max_speed": "highest crank speed the motor can follow, Hz (default 11.5)",
        "axis": "direction of motion in the sensor frame: +x .. -z or three numbers (default +x)",
    }
    channel_names = ("step",)

    def __init__(
        self,
        steps=(2.5, 4.0, 6.0, 8.0, 10.0, 11.0, 12.0, 13.0),
        step_seconds: float = 1.0,
        settle: float = 0.5,
        radius: float = 0.00635,
        rod: float = 0.0353,
        clearance: float = 0.0,
        backlash: float = 0.0,
        max_speed: float = 11.5,
        axis="+x",
        radius_offset: float = 0.0,
        g: float = STANDARD_GRAVITY,
    ):
        steps = np.asarray(steps, dtype=float)
        if steps.ndim != 1 or steps.size == 0 or np.any(~np.isfinite(steps)) or np.any(steps <= 0):
            raise DeviceError("steps= needs one or more positive speeds in Hz", "e.g. steps=2.5,4,6,8")
        for label, value in (("step_seconds", step_seconds), ("radius", radius), ("rod", rod), ("max_speed", max_speed)):
            if not value > 0:
                raise DeviceError(f"{label}={value} must be positive")
        if settle < 0 or clearance < 0 or backlash < 0:
            raise DeviceError("settle, clearance and backlash cannot be negative")
        if rod <= radius + clearance:
            raise DeviceError(f"rod={rod} m must be longer than the crank radius {radius} m (+ clearance)")
        if abs(radius_offset) > clearance:
            raise DeviceError("the effective radius must lie inside the clearance")
        self.steps = steps
        self.step_seconds = float(step_seconds)
        self.settle = float(settle)
        self.radius = float(radius)
        self.rod = float(rod)
        self.clearance = float(clearance)
        self.backlash = float(backlash)
        self.max_speed = float(max_speed)
        self.axis = parse_axis(axis) if isinstance(axis, str) else np.asarray(axis, float) / np.linalg.norm(axis)
        self.effective_radius = self.radius + float(radius_offset)
        self.g = g
        # "up" (where gravity's specific force points) is the body z axis made
        # perpendicular to the motion, so the slider runs horizontally.
        up = np.array([0.0, 0.0, 1.0]) if abs(self.axis[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
        up = up - (up @ self.axis) * self.axis
        self.up = up / np.linalg.norm(up)
        self.actual_speeds = np.array([self._actual_speed(f) for f in steps])
        self.segment = self.settle + self.step_seconds
        self.duration = self.segment * steps.size
        # crank angle at the start of each segment (cumulative integral of the speed)
        starts = [0.0]
        for i in range(steps.size):
            starts.append(starts[-1] + self._phase_in_segment(i, np.array([self.segment]))[0])
        self._segment_phase = np.array(starts)
        self._dead_centres = self._find_dead_centres() if self.backlash > 0 else np.zeros(0)

    # ---------------------------------------------------------------- motor
    def _actual_speed(self, commanded: float) -> float:
        if commanded <= self.max_speed:
            return commanded
        return max(self.max_speed - OVERLOAD_DROOP * (commanded - self.max_speed), 0.5 * self.max_speed)

    def _omega_in_segment(self, i: int, tau: np.ndarray):
        """Angular speed and its derivative at time tau into segment i."""
        w_new = 2 * np.pi * self.actual_speeds[i]
        w_old = 0.0 if i == 0 else 2 * np.pi * self.actual_speeds[i - 1]
        ramp = tau < self.settle
        omega = np.where(ramp, w_old + (w_new - w_old) * tau / max(self.settle, 1e-12), w_new)
        domega = np.where(ramp, (w_new - w_old) / max(self.settle, 1e-12), 0.0)
        if self.steps[i] > self.max_speed:  # hunting once the motor is overloaded
            steady = ~ramp
            h = 2 * np.pi * HUNT_FREQUENCY
            ts = tau - self.settle
            omega = np.where(steady, w_new * (1 + HUNT_RIPPLE * np.sin(h * ts)), omega)
            domega = np.where(steady, w_new * HUNT_RIPPLE * h * np.cos(h * ts), domega)
        return omega, domega

    def _phase_in_segment(self, i: int, tau: np.ndarray) -> np.ndarray:
        """Crank angle gained since the start of segment i (closed-form integral of omega)."""
        w_new = 2 * np.pi * self.actual_speeds[i]
        w_old = 0.0 if i == 0 else 2 * np.pi * self.actual_speeds[i - 1]
        settle = self.settle
        in_ramp = np.minimum(tau, settle)
        phase = w_old * in_ramp + (w_new - w_old) * in_ramp**2 / (2 * max(settle, 1e-12))
        ts = np.maximum(tau - settle, 0.0)
        if self.steps[i] > self.max_speed:
            h = 2 * np.pi * HUNT_FREQUENCY
            phase = phase + w_new * (ts + HUNT_RIPPLE * (1 - np.cos(h * ts)) / h)
        else:
            phase = phase + w_new * ts
        return phase

    def crank_angle(self, t: np.ndarray):
        """phi(t), omega(t), omega_dot(t) and the segment index of each time."""
        t = np.asarray(t, dtype=float)
        seg = np.clip((t // self.segment).astype(int), 0, self.steps.size - 1)
        tau = t - seg * self.segment
        phi = np.empty_like(t)
        omega = np.empty_like(t)
        domega = np.empty_like(t)
        for i in np.unique(seg):
            m = seg == i
            phi[m] = self._segment_phase[i] + self._phase_in_segment(i, tau[m])
            omega[m], domega[m] = self._omega_in_segment(i, tau[m])
        return phi, omega, domega, seg, tau

    def _find_dead_centres(self) -> np.ndarray:
        """Times where phi crosses a multiple of pi (phi is monotonic: the motor never reverses)."""
        grid = np.linspace(0.0, self.duration, int(self.duration * 20000) + 2)
        phi = self.crank_angle(grid)[0]
        targets = np.arange(np.pi, phi[-1], np.pi)
        return np.interp(targets, phi, grid)

    # ---------------------------------------------------------------- physics
    def slider_acceleration(self, t: np.ndarray) -> np.ndarray:
        """True acceleration of the slider along its axis, m/s^2."""
        phi, omega, domega, _, _ = self.crank_angle(t)
        _, dx, ddx = slider_position(phi, self.effective_radius, self.rod)
        acc = ddx * omega**2 + dx * domega
        if self.backlash > 0 and self._dead_centres.size:
            acc = acc + self._knocks(np.asarray(t, dtype=float))
        return acc

    def _knocks(self, t: np.ndarray) -> np.ndarray:
        """Acceleration of the play's take-up: a ramp of ``backlash`` over KNOCK_RISE through the contact resonance.

        The ramp (not an ideal step) keeps the acceleration continuous: a jump
        in a sampled signal would put sampling artefacts at the crank frequency
        that no real, band-limited sensor shows.
        """
        latest = np.searchsorted(self._dead_centres, t, side="right") - 1
        acc = np.zeros_like(t)
        for back in range(4):  # a knock has decayed to < 0.1 % after 4 dead centres at any stand speed
            idx = latest - back
            ok = idx >= 0
            tau = t[ok] - self._dead_centres[idx[ok]]
            # dead centre m (phi = m pi): odd m is the bottom (play flips to +), even m the top (to -)
            sign = np.where(idx[ok] % 2 == 0, 1.0, -1.0)
            response = (_resonator_velocity(tau) - _resonator_velocity(tau - KNOCK_RISE)) / KNOCK_RISE
            acc[ok] += sign * self.backlash * response
        return acc

    @classmethod
    def from_url(cls, url: DeviceURL, rng: np.random.Generator) -> "SliderCrankRig":
        steps_text = url.get_str("steps")
        steps = (2.5, 4.0, 6.0, 8.0, 10.0, 11.0, 12.0, 13.0)
        if steps_text:
            try:
                steps = tuple(float(v) for v in steps_text.split(","))
            except ValueError:
                raise DeviceError(f"steps={steps_text!r} is not a list of speeds in Hz", "e.g. steps=2.5,4,6,8") from None
        clearance = url.get_float("clearance", 0.0)
        return cls(
            steps=steps,
            step_seconds=url.get_float("step_seconds", 1.0),
            settle=url.get_float("settle", 0.5),
            radius=url.get_float("radius", 0.00635),
            rod=url.get_float("rod", 0.0353),
            clearance=clearance,
            backlash=url.get_float("backlash", 0.0),
            max_speed=url.get_float("max_speed", 11.5),
            axis=url.get_str("axis", "+x"),
            radius_offset=float(rng.uniform(-clearance, clearance)) if clearance > 0 else 0.0,
        )

    def specific_force(self, t: np.ndarray) -> np.ndarray:
        acc = self.slider_acceleration(np.asarray(t, dtype=float))
        return acc[:, None] * self.axis[None, :] + self.g * self.up[None, :]

    def channels(self, t: np.ndarray) -> dict[str, np.ndarray]:
        _, _, _, seg, tau = self.crank_angle(np.asarray(t, dtype=float))
        return {"step": np.where(tau < self.settle, -1.0, seg.astype(float))}

    def truth(self) -> dict:
        return {
            "rig": self.name,
            "radius": self.radius,
            "effective_radius": self.effective_radius,
            "rod": self.rod,
            "lambda": self.effective_radius / self.rod,
            "clearance": self.clearance,
            "backlash": self.backlash,
            "max_speed": self.max_speed,
            "axis": self.axis.tolist(),
            "up": self.up.tolist(),
            "steps": self.steps.tolist(),
            "actual_speeds": self.actual_speeds.tolist(),
            "step_seconds": self.step_seconds,
            "settle": self.settle,
            "g": self.g,
        }
