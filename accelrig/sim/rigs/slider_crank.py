"""Slider-crank test stand (paper 000, section 4): a DC motor turns a crank, a rod drives a slider.

Exact geometry (REFERENCES.md): with crank angle phi, radius r, rod l, the
slider sits at x(phi) = r cos phi + sqrt(l^2 - r^2 sin^2 phi) from the crank
axis, along world x; the sensor rides it level, its ``axis`` along the motion.
accelrig.sim.kinematics differentiates that position (speed changes
included).  The motor runs a list of speed steps; each step starts with a
settling ramp from the speed the motor had reached (``step`` channel = -1
there, the step index afterwards).

Imperfections the verification must see:
* clearance: the effective crank radius differs from the nominal (caliper)
  radius by a value drawn uniformly in +-clearance.
* backlash: the slider's joint has ``backlash`` metres of play.  At each dead
  centre the velocity reverses and the play is taken up on the other side: the
  slider moves by the play, a ramp over KNOCK_RISE through the contact's
  resonance (a knock, paper Fig. 6).
* play: the pin joint has ``play`` metres of clearance and the slider rides
  on friction.  At each dead centre the pin reverses; the slider dwells where
  it stopped until the pin has crossed the clearance, then is picked up on
  the other side (the take-up smoothed over PLAY_SMOOTHING of the play: a
  contact of finite stiffness).  No resonance: a dwell and a pick-up.
* motor limit: above ``max_speed`` the motor cannot follow: its speed falls
  back below the limit (the more so the harder it is pushed) and hunts with a
  slow ripple (paper: a drop-off above about 11.5 Hz).
* an unsteady motor: ``wobble`` is a slow speed ripple (relative amplitude, at
  ``wobble_hz`` with a random phase), ``ramp`` a steady drift of the speed
  over each step (relative change over the step's steady part).
"""

from __future__ import annotations

import numpy as np

from accelrig.acquisition.url import DeviceURL
from accelrig.errors import DeviceError
from accelrig.sim import kinematics
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
# The pick-up after a dwell is a softplus over this fraction of the play (the contact's compliance).
PLAY_SMOOTHING = 0.6
# A knock has rung out (e^-40) this long after its dead centre: older ones count as settled.
KNOCK_MEMORY = 40.0 / (KNOCK_DAMPING * 2 * np.pi * KNOCK_FREQUENCY)
# The knock's jerk jumps where the take-up starts and ends: a short differentiation
# step keeps the stencil's error there at a few hundredths of a m/s^2 (kinematics.py).
STEP = 2.0**-15


def _ramp_response(tau: np.ndarray) -> np.ndarray:
    """The contact resonator's response to a unit ramp starting at tau = 0 (0 before)."""
    wn = 2 * np.pi * KNOCK_FREQUENCY
    zeta = KNOCK_DAMPING
    wd = wn * np.sqrt(1 - zeta**2)
    tau = np.maximum(tau, 0.0)
    ringing = np.exp(-zeta * wn * tau) * (2 * zeta / wn * np.cos(wd * tau) + (2 * zeta**2 - 1) / wd * np.sin(wd * tau))
    return tau - 2 * zeta / wn + ringing


def _take_up(tau: np.ndarray) -> np.ndarray:
    """Fraction of the play closed tau s after a dead centre: a ramp over KNOCK_RISE through the contact.

    The ramp (not an ideal step) keeps the acceleration continuous: a jump in a
    sampled signal would put sampling artefacts at the crank frequency that no
    real, band-limited sensor shows.
    """
    return (_ramp_response(tau) - _ramp_response(tau - KNOCK_RISE)) / KNOCK_RISE


def slider_position(phi, radius: float, rod: float):
    """x(phi): the slider's distance from the crank axis (exact, no series)."""
    return radius * np.cos(phi) + np.sqrt(rod**2 - radius**2 * np.sin(phi) ** 2)


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
        "play": "clearance in the pin joint, m: the slider dwells at the dead centres until it is taken up (default 0)",
        "max_speed": "highest crank speed the motor can follow, Hz (default 11.5)",
        "wobble": "slow motor speed ripple, relative amplitude (default 0)",
        "wobble_hz": "frequency of the speed ripple, Hz (default 1.3)",
        "ramp": "relative drift of the speed over each step's steady part (default 0)",
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
        play: float = 0.0,
        wobble: float = 0.0,
        wobble_hz: float = 1.3,
        wobble_phase: float = 0.0,
        ramp: float = 0.0,
    ):
        steps = np.asarray(steps, dtype=float)
        if steps.ndim != 1 or steps.size == 0 or np.any(~np.isfinite(steps)) or np.any(steps <= 0):
            raise DeviceError("steps= needs one or more positive speeds in Hz", "e.g. steps=2.5,4,6,8")
        for label, value in (("step_seconds", step_seconds), ("radius", radius), ("rod", rod), ("max_speed", max_speed)):
            if not value > 0:
                raise DeviceError(f"{label}={value} must be positive")
        if settle < 0 or clearance < 0 or backlash < 0 or play < 0:
            raise DeviceError("settle, clearance, backlash and play cannot be negative")
        if not (0 <= wobble < 0.5 and wobble_hz > 0 and -0.5 < ramp < 0.5):
            raise DeviceError("wobble must lie in [0, 0.5), wobble_hz be positive and ramp lie in (-0.5, 0.5)")
        if settle == 0 and steps.size > 1:
            raise DeviceError("settle=0 would change the motor speed instantly between steps (an infinite "
                              "acceleration)", "give the ramp a time, e.g. settle=0.5")
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
        self.play = float(play)
        self.wobble, self.wobble_hz, self.wobble_phase = float(wobble), float(wobble_hz), float(wobble_phase)
        self.ramp = float(ramp)
        self.axis = parse_axis(axis) if isinstance(axis, str) else np.asarray(axis, float) / np.linalg.norm(axis)
        self.effective_radius = self.radius + float(radius_offset)
        self.g = g
        # "up" (where gravity's specific force points) is the body z axis made
        # perpendicular to the motion, so the slider runs horizontally.
        up = np.array([0.0, 0.0, 1.0]) if abs(self.axis[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
        up = up - (up @ self.axis) * self.axis
        self.up = up / np.linalg.norm(up)
        self._mounting = kinematics.level_mounting(self.axis, self.up)
        self.actual_speeds = np.array([self._actual_speed(f) for f in steps])
        self.segment = self.settle + self.step_seconds
        self.duration = self.segment * steps.size
        # Each ramp starts from the speed the motor had at the end of the previous step; the
        # first from rest, or, with no ramp, the crank was already turning at the first speed.
        self._start_speeds = np.zeros(steps.size)
        if self.settle == 0:
            self._start_speeds[0] = 2 * np.pi * self.actual_speeds[0]
        for i in range(1, steps.size):
            self._start_speeds[i] = self._end_speed(i - 1)
        # crank angle at the start of each segment (cumulative integral of the speed)
        starts = [0.0]
        for i in range(steps.size):
            starts.append(starts[-1] + self._phase_in_segment(i, np.array([self.segment]))[0])
        self._segment_phase = np.array(starts)
        self._dead_centres = self._find_dead_centres() if self.backlash > 0 or self.play > 0 else np.zeros(0)

    # ---------------------------------------------------------------- motor
    def _actual_speed(self, commanded: float) -> float:
        if commanded <= self.max_speed:
            return commanded
        return max(self.max_speed - OVERLOAD_DROOP * (commanded - self.max_speed), 0.5 * self.max_speed)

    def _hunting(self, i: int) -> bool:
        return self.steps[i] > self.max_speed

    def _end_speed(self, i: int) -> float:
        """Crank speed in rad/s at the end of segment i, where the next ramp starts."""
        ripple = HUNT_RIPPLE * np.sin(2 * np.pi * HUNT_FREQUENCY * self.step_seconds) if self._hunting(i) else 0.0
        ripple += self.ramp + self._wobble(np.array([self.step_seconds]))[0]
        return 2 * np.pi * self.actual_speeds[i] * (1 + ripple)

    def _phase_in_segment(self, i: int, tau: np.ndarray) -> np.ndarray:
        """Crank angle gained since the start of segment i (closed-form integral of the speed)."""
        w_old, w_new = self._start_speeds[i], 2 * np.pi * self.actual_speeds[i]
        settle = self.settle
        # before the ramp (t < 0) the crank turns at the start speed
        in_ramp = np.clip(tau, 0.0, settle)
        phase = w_old * np.minimum(tau, settle) + (w_new - w_old) * in_ramp**2 / (2 * max(settle, 1e-12))
        ts = np.maximum(tau - settle, 0.0)
        if self._hunting(i):  # speed w_new (1 + ripple sin(h ts)) once the motor is overloaded
            h = 2 * np.pi * HUNT_FREQUENCY
            phase = phase + w_new * (ts + HUNT_RIPPLE * (1 - np.cos(h * ts)) / h)
        else:
            phase = phase + w_new * ts
        if self.ramp:  # the speed drifts linearly by ``ramp`` over the steady part
            phase = phase + w_new * self.ramp * ts**2 / (2 * self.step_seconds)
        if self.wobble:  # speed w_new (1 + wobble(ts)), its closed-form integral
            h, psi = 2 * np.pi * self.wobble_hz, self.wobble_phase
            phase = phase + w_new * self.wobble * ((np.cos(psi) - np.cos(h * ts + psi)) / h - ts * np.sin(psi))
        return phase

    def _wobble(self, ts: np.ndarray) -> np.ndarray:
        """Relative speed ripple ts s into a step's steady part: wobble (sin(h ts + psi) - sin psi), zero
        where the ramp hands over (the speed stays continuous: no infinite crank acceleration)."""
        h, psi = 2 * np.pi * self.wobble_hz, self.wobble_phase
        return self.wobble * (np.sin(h * ts + psi) - np.sin(psi))

    def crank_angle(self, t: np.ndarray):
        """phi(t), the segment index of each time and the time into that segment."""
        t = np.asarray(t, dtype=float)
        seg = np.clip((t // self.segment).astype(int), 0, self.steps.size - 1)
        tau = t - seg * self.segment
        phi = np.empty_like(t)
        for i in np.unique(seg):
            m = seg == i
            phi[m] = self._segment_phase[i] + self._phase_in_segment(i, tau[m])
        return phi, seg, tau

    def _find_dead_centres(self) -> np.ndarray:
        """Times where phi crosses a multiple of pi (phi is monotonic: the motor never reverses)."""
        grid = np.linspace(0.0, self.duration, int(self.duration * 20000) + 2)
        phi = self.crank_angle(grid)[0]
        targets = np.arange(np.pi, phi[-1], np.pi)
        return np.interp(targets, phi, grid)

    # ---------------------------------------------------------------- physics
    def _play(self, t: np.ndarray) -> np.ndarray:
        """The slider's displacement in its joint's play, m: each dead centre moves it to the other side."""
        passed = np.searchsorted(self._dead_centres, t, side="right")
        settled = np.searchsorted(self._dead_centres, t - KNOCK_MEMORY, side="right")
        # dead centre m (phi = m pi): odd m is the bottom (play flips to +), even m the top (back to 0);
        # the first one (index 0) is m = 1, so the settled ones sum to 1 after an odd count
        offset = (settled % 2).astype(float)
        for back in range(int(np.max(passed - settled, initial=0))):
            idx = settled + back
            ringing = idx < passed
            sign = np.where(idx[ringing] % 2 == 0, 1.0, -1.0)
            offset[ringing] += sign * _take_up(t[ringing] - self._dead_centres[idx[ringing]])
        return self.backlash * offset

    def _dwell(self, t: np.ndarray, pin: np.ndarray) -> np.ndarray:
        """Where the slider rides, given the pin's position: it dwells after each dead centre until the
        pin has crossed the clearance, then follows it on the other side (half the play behind)."""
        b = self.play
        # the crank starts at phi = 0, a top dead centre; dead centre m (phi = m pi): odd m bottom, even m top
        passed = np.searchsorted(self._dead_centres, t, side="right")
        top = passed % 2 == 0
        extreme = np.where(top, slider_position(0.0, self.effective_radius, self.rod),
                           slider_position(np.pi, self.effective_radius, self.rod))
        s = np.where(top, 1.0, -1.0)   # +1: the pin now moves down, away from the top
        u = s * (extreme - pin) / b    # how far the pin has come back, in units of the play
        # softplus, max(u - 1, 0) smoothed; less its value at u = 0 faded out by u = 1, so the slider
        # neither jumps at the dead centre nor ends up off its half-play lag after the pick-up
        at_zero = PLAY_SMOOTHING * np.logaddexp(0.0, -1.0 / PLAY_SMOOTHING)
        taken = PLAY_SMOOTHING * np.logaddexp(0.0, (u - 1.0) / PLAY_SMOOTHING) - at_zero * np.maximum(1.0 - u, 0.0) ** 2
        return extreme - s * b / 2 - s * b * taken

    def position(self, t: np.ndarray) -> np.ndarray:
        """The slider (and the sensor on it) along world x, from the crank axis."""
        t = np.asarray(t, dtype=float)
        x = slider_position(self.crank_angle(t)[0], self.effective_radius, self.rod)
        if self.play > 0:
            x = self._dwell(t, x)
        if self.backlash > 0:
            x = x + self._play(t)
        return np.column_stack([x, np.zeros_like(x), np.zeros_like(x)])

    def orientation(self, t: np.ndarray) -> np.ndarray:
        return np.broadcast_to(self._mounting, (np.size(t), 3, 3))

    def specific_force(self, t: np.ndarray) -> np.ndarray:
        return kinematics.specific_force(self.position, self.orientation, t, self.g, STEP)

    def slider_acceleration(self, t: np.ndarray) -> np.ndarray:
        """True acceleration of the slider along its axis, m/s^2."""
        return self.specific_force(t) @ self.axis

    @classmethod
    def from_url(cls, url: DeviceURL, rng: np.random.Generator) -> SliderCrankRig:
        steps_text = url.get_str("steps")
        steps = (2.5, 4.0, 6.0, 8.0, 10.0, 11.0, 12.0, 13.0)
        if steps_text:
            try:
                steps = tuple(float(v) for v in steps_text.split(","))
            except ValueError:
                raise DeviceError(f"steps={steps_text!r} is not a list of speeds in Hz", "e.g. steps=2.5,4,6,8") from None
        clearance = url.get_float("clearance", 0.0, low=0.0, high=0.1, unit="m")
        return cls(
            steps=steps,
            step_seconds=url.get_float("step_seconds", 1.0, low=0.0, low_open=True, high=3600.0, unit="s"),
            settle=url.get_float("settle", 0.5, low=0.0, high=3600.0, unit="s"),
            radius=url.get_float("radius", 0.00635, low=0.0, low_open=True, high=0.5, unit="m"),
            rod=url.get_float("rod", 0.0353, low=0.0, low_open=True, high=2.0, unit="m"),
            clearance=clearance,
            backlash=url.get_float("backlash", 0.0, low=0.0, high=0.1, unit="m"),
            max_speed=url.get_float("max_speed", 11.5, low=0.0, low_open=True, high=100.0, unit="Hz"),
            play=url.get_float("play", 0.0, low=0.0, high=0.01, unit="m"),
            wobble=url.get_float("wobble", 0.0, low=0.0, high=0.4),
            wobble_hz=url.get_float("wobble_hz", 1.3, low=0.0, low_open=True, high=100.0, unit="Hz"),
            ramp=url.get_float("ramp", 0.0, low=-0.4, high=0.4),
            axis=url.get_str("axis", "+x"),
            radius_offset=float(rng.uniform(-clearance, clearance)) if clearance > 0 else 0.0,
            # drawn last, and only when asked for: a stand without wobble keeps its seeds' draws
            wobble_phase=float(rng.uniform(-np.pi, np.pi)) if url.get_float("wobble", 0.0) > 0 else 0.0,
        )

    def channels(self, t: np.ndarray) -> dict[str, np.ndarray]:
        _, seg, tau = self.crank_angle(np.asarray(t, dtype=float))
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
            "play": self.play,
            "wobble": self.wobble,
            "wobble_hz": self.wobble_hz,
            "ramp": self.ramp,
            "max_speed": self.max_speed,
            "axis": self.axis.tolist(),
            "up": self.up.tolist(),
            "steps": self.steps.tolist(),
            "actual_speeds": self.actual_speeds.tolist(),
            "step_seconds": self.step_seconds,
            "settle": self.settle,
            "g": self.g,
        }
