"""The encoder-driven oscillating disk of paper 001 (Chiominto et al., Sensors 2025).

A servo motor swings a horizontal disk about a vertical axis with
theta(t) = theta0 cos(2 pi f t + phase).  The MEMS sits on the disk at radius
r: its position is r (cos theta, sin theta, 0) and its orientation turns
with the disk; accelrig.sim.kinematics turns that into the specific force.
The paper's eq. 3-4 are what comes out: tangential r theta'' at f,
centripetal r theta'^2 at DC + 2f, pointing to the axis.

Axis mapping: ``tangential=x`` means the sensor's +x axis points along the
direction of increasing theta (counter-clockwise seen from above);
``radial=y`` means +y points towards the rotation axis.  A leading '-' flips
an axis.  The third axis completes a right-handed frame: it points up (reads
+g) for x,y / y,z / z,x and down (reads -g) for the mirrored pairs y,x / z,y
/ x,z; truth()["up_axis"] says which ("z" or "-z").

``amplitude_deg`` is PEAK TO PEAK, as the paper's "oscillation angle":
34 degrees at 5 Hz is theta0 = 17 degrees, 49 m/s^2 tangential and 15 m/s^2
centripetal peak at r = 170 mm.

How sim://rotary delivers its clocks.  The MEMS samples on its own clock
(SimClock with a rate_error): the procedure treats the MEMS timestamps as
untrustworthy and uses sample indices only.  The encoder lives on an accurate
clock and reaches the procedure one of two ways:

* as the ``theta`` channel of the MEMS recording, sampled at the MEMS's TRUE
  sample instants (SimDevice evaluates channels at true times) -- the
  recording's ``t`` column is then the logger's accurate timestamp of each
  encoder reading (the sim reports the true instants plus the clock jitter);
* as a separate encoder CSV ``t,theta[,ref]`` on the accurate clock at its own
  rate, written by :func:`write_encoder_csv` (this is how a PLC log arrives).

``ref=1`` adds a ``ref`` channel: a reference (IEPE-like) accelerometer at
``ref_radius`` reading the tangential acceleration there, with a small gain
error drawn from the seed (in truth()).  The encoder reading is quantised to
``encoder_deg`` (paper: 0.01 degrees).
"""

from __future__ import annotations

import os

import numpy as np

from accelrig.acquisition.url import DeviceURL
from accelrig.errors import DataError, DeviceError
from accelrig.files import atomic_write
from accelrig.geometry import parse_axis as parse_axis_spec
from accelrig.sim import kinematics
from accelrig.sim.rigs.base import Rig
from accelrig.units import STANDARD_GRAVITY

# Paper 001's test plan, (frequency Hz, oscillation angle peak to peak deg), and its three
# mountings (tangential, radial axis).  Facts of the paper's rig, kept here because the
# simulator imports no procedure code (accelrig.procedures.rotary has its own copy of the plan).
PAPER_PLAN = ((5.0, 34.0), (5.0, 20.0), (8.0, 13.0), (8.0, 6.0))
PAPER_ORIENTATIONS = (("x", "y"), ("z", "x"), ("y", "z"))


def parse_axis(spec: str, role: str) -> tuple[int, float]:
    """'x', '+y', '-z' -> (index, sign); raises DeviceError naming the role."""
    parsed = parse_axis_spec(spec)
    if parsed is None:
        raise DeviceError(f"{role}={spec!r} is not a sensor axis", "use x, y or z (optionally -x, ...)")
    return parsed


class RotaryRig(Rig):
    name = "rotary"
    description = "encoder-driven oscillating disk (paper 001): tangential at f, centripetal at DC + 2f"
    # the paper's 34 degrees at 5 Hz swing the tangential axis by 49.8 m/s^2, beyond +-2 g: its LSM6DSR ran at
    # +-8 g, and a +-2 g default clipped three quarters of a first recording
    default_range_g = 8.0
    options = {
        "radius": "sensor distance from the rotation axis, m (default 0.170)",
        "frequency": "oscillation frequency, Hz (default 5)",
        "amplitude_deg": "oscillation angle PEAK TO PEAK, degrees, as in the paper (default 34)",
        "tangential": "sensor axis along the motion: x (default), y, z, or -x ...",
        "radial": "sensor axis pointing to the rotation axis: y (default), ... ; the third axis completes a "
                  "right-handed frame (up for x,y / y,z / z,x)",
        "seconds": "length of the run, s (default 40, as the paper's tests)",
        "ref": "1 adds a 'ref' channel: reference accelerometer at ref_radius (default 0)",
        "ref_radius": "radius of the reference accelerometer, m (default 0.145)",
        "encoder_deg": "encoder resolution, degrees (default 0.01)",
    }

    def __init__(
        self,
        radius: float = 0.170,
        frequency: float = 5.0,
        amplitude_deg: float = 34.0,
        tangential: str = "x",
        radial: str = "y",
        duration: float | None = 40.0,
        ref: bool = False,
        ref_radius: float = 0.145,
        encoder_deg: float = 0.01,
        phase: float = 0.0,
        ref_gain_error: float = 0.0,
        g: float = STANDARD_GRAVITY,
    ):
        if not 0 < radius < 2:
            raise DeviceError(f"radius={radius} m is not a plausible disk radius", "give it in metres, e.g. 0.170")
        if not 0 < frequency < 100:
            raise DeviceError(f"frequency={frequency} Hz is outside 0 .. 100 Hz")
        if not 0 < amplitude_deg <= 360:
            raise DeviceError(f"amplitude_deg={amplitude_deg} is outside 0 .. 360 degrees (peak to peak)")
        if encoder_deg < 0:
            raise DeviceError(f"encoder_deg={encoder_deg} must not be negative")
        self.t_axis, self.t_sign = parse_axis(tangential, "tangential")
        self.r_axis, self.r_sign = parse_axis(radial, "radial")
        if self.t_axis == self.r_axis:
            raise DeviceError(f"tangential={tangential!r} and radial={radial!r} are the same axis")
        self.up_axis = 3 - self.t_axis - self.r_axis
        # sensor -> disk frame (tangential, radial inwards, up): a signed permutation, right-handed
        self._mounting = np.zeros((3, 3))
        self._mounting[0, self.t_axis] = self.t_sign
        self._mounting[1, self.r_axis] = self.r_sign
        self._mounting[:, self.up_axis] = np.cross(self._mounting[:, (self.up_axis + 1) % 3],
                                                   self._mounting[:, (self.up_axis + 2) % 3])
        self.radius = float(radius)
        self.frequency = float(frequency)
        self.amplitude_deg = float(amplitude_deg)
        self.theta0 = np.deg2rad(amplitude_deg) / 2.0  # peak-to-peak -> peak
        self.duration = duration
        self.ref = bool(ref)
        self.ref_radius = float(ref_radius)
        self.encoder_rad = np.deg2rad(encoder_deg)
        self.phase = float(phase)
        self.ref_gain_error = float(ref_gain_error)
        self.g = g
        self.channel_names = ("theta", "ref") if self.ref else ("theta",)

    @classmethod
    def from_url(cls, url: DeviceURL, rng: np.random.Generator) -> RotaryRig:
        ref = url.get_int("ref", 0)
        if ref not in (0, 1):
            raise DeviceError(f"ref={ref} in {url.raw!r} must be 0 or 1")
        return cls(
            radius=url.get_float("radius", 0.170, low=0.0, low_open=True, high=2.0, unit="m"),
            frequency=url.get_float("frequency", 5.0, low=0.0, low_open=True, high=100.0, unit="Hz"),
            amplitude_deg=url.get_float("amplitude_deg", 34.0, low=0.0, low_open=True, high=360.0, unit="deg"),
            tangential=url.get_str("tangential", "x"),
            radial=url.get_str("radial", "y"),
            duration=url.get_float("seconds", 40.0, low=0.0, low_open=True, high=86400.0, unit="s"),
            ref=bool(ref),
            ref_radius=url.get_float("ref_radius", 0.145, low=0.0, high=2.0, unit="m"),
            encoder_deg=url.get_float("encoder_deg", 0.01, low=0.0, low_open=True, high=10.0, unit="deg"),
            # the motor starts anywhere in its cycle; the reference sensor is good to ~0.1 %
            phase=float(rng.uniform(-np.pi, np.pi)),
            ref_gain_error=float(rng.normal(0.0, 1e-3)),
        )

    # ------------------------------------------------------------ motion law
    @property
    def omega(self) -> float:
        return 2 * np.pi * self.frequency

    def angle(self, t: np.ndarray) -> np.ndarray:
        return self.theta0 * np.cos(self.omega * np.asarray(t, dtype=float) + self.phase)

    def _on_disk(self, t: np.ndarray, radius: float) -> np.ndarray:
        """Position of a point of the disk at ``radius`` (the axis at the origin)."""
        theta = self.angle(t)
        return radius * np.column_stack([np.cos(theta), np.sin(theta), np.zeros_like(theta)])

    def _disk_frame(self, t: np.ndarray) -> np.ndarray:
        """Columns: tangential (increasing theta), radial towards the axis, up; world frame."""
        theta = self.angle(t)
        c, s, zero = np.cos(theta), np.sin(theta), np.zeros_like(theta)
        return np.stack([np.column_stack([-s, c, zero]), np.column_stack([-c, -s, zero]),
                         np.column_stack([zero, zero, zero + 1.0])], axis=2)

    def _disk_force(self, t: np.ndarray, radius: float) -> np.ndarray:
        """Specific force at ``radius`` in the disk frame (tangential, radial, up)."""
        return kinematics.specific_force(lambda tt: self._on_disk(tt, radius), self._disk_frame, t, self.g)

    def position(self, t: np.ndarray) -> np.ndarray:
        return self._on_disk(t, self.radius)

    def orientation(self, t: np.ndarray) -> np.ndarray:
        return self._disk_frame(t) @ self._mounting

    def specific_force(self, t: np.ndarray) -> np.ndarray:
        return kinematics.specific_force(self.position, self.orientation, t, self.g)

    def encoder_reading(self, t: np.ndarray) -> np.ndarray:
        theta = self.angle(t)
        if self.encoder_rad > 0:
            theta = np.round(theta / self.encoder_rad) * self.encoder_rad
        return theta

    def ref_reading(self, t: np.ndarray) -> np.ndarray:
        """The reference accelerometer: tangential at ref_radius, with its gain error."""
        return (1.0 + self.ref_gain_error) * self._disk_force(np.asarray(t, dtype=float), self.ref_radius)[:, 0]

    def channels(self, t: np.ndarray) -> dict[str, np.ndarray]:
        out = {"theta": self.encoder_reading(t)}
        if self.ref:
            out["ref"] = self.ref_reading(t)
        return out

    # ------------------------------------------------------------ truth
    @property
    def tangential_amplitude(self) -> float:
        """Peak tangential force, read where the disk turns back (theta = theta0: no centripetal part)."""
        return float(abs(self._disk_force(np.array([-self.phase / self.omega]), self.radius)[0, 0]))

    @property
    def centripetal_amplitude(self) -> float:
        """Amplitude of the 2f component, equal to the DC part: half the peak, read where theta = 0."""
        return float(self._disk_force(np.array([(np.pi / 2 - self.phase) / self.omega]), self.radius)[0, 1] / 2)

    def truth(self) -> dict:
        names = "xyz"
        return {
            "rig": self.name,
            "radius": self.radius,
            "frequency": self.frequency,
            "amplitude_deg_peak_to_peak": self.amplitude_deg,
            "theta0_rad": self.theta0,
            "phase_rad": self.phase,
            "tangential_axis": ("-" if self.t_sign < 0 else "") + names[self.t_axis],
            "radial_axis": ("-" if self.r_sign < 0 else "") + names[self.r_axis],
            "up_axis": ("-" if self._mounting[2, self.up_axis] < 0 else "") + names[self.up_axis],
            "tangential_amplitude": self.tangential_amplitude,
            "centripetal_amplitude": self.centripetal_amplitude,
            "centripetal_dc": self.centripetal_amplitude,
            "ref": self.ref,
            "ref_radius": self.ref_radius,
            "ref_gain_error": self.ref_gain_error,
            "encoder_deg": float(np.rad2deg(self.encoder_rad)),
            "g": self.g,
        }


def true_sensitivity(truth: dict) -> dict[str, float]:
    """Counts per m/s^2 of each axis from a simulation's meta["truth"].

    The rotary bench measures, on axis i, the response to a force along body
    axis i: K[i, i] / scale with raw = K f + o (K = C^-1 of the sensor's true
    canonical correction).  Cross-axis terms land at other frequencies (the
    radial 2f on the tangential axis, gravity at DC) and do not enter.
    """
    sensor = truth["sensor"]
    k = np.linalg.inv(np.asarray(sensor["correction"]["matrix"], dtype=float))
    return {name: float(k[i, i] / sensor["scale"]) for i, name in enumerate("xyz")}


def encoder_samples(
    rig: RotaryRig, seconds: float, rate: float = 1000.0, start: float = 0.0,
    ref_noise: float = 0.0, rng: np.random.Generator | None = None,
) -> dict[str, np.ndarray]:
    """The encoder log on the accurate clock: {"t", "theta"[, "ref"]} sampled at ``rate`` Hz.

    ``ref_noise`` (m/s^2 sd) adds white noise to the reference accelerometer;
    it needs ``rng``.
    """
    if seconds <= 0 or rate <= 0:
        raise DataError("an encoder log needs a positive length and rate")
    t = start + np.arange(int(np.floor(seconds * rate))) / rate
    out = {"t": t, "theta": rig.encoder_reading(t)}
    if rig.ref:
        ref = rig.ref_reading(t)
        if ref_noise > 0:
            if rng is None:
                raise ValueError("ref_noise needs an rng")
            ref = ref + rng.standard_normal(t.size) * ref_noise
        out["ref"] = ref
    return out


def write_encoder_csv(path: str | os.PathLike, columns: dict[str, np.ndarray]) -> None:
    """Write an encoder log (``t,theta[,ref]``) as CSV, atomically."""
    names = list(columns)
    data = np.column_stack([columns[n] for n in names])

    def _write(fh) -> None:
        fh.write("# encoder log: t in s on the accurate clock, theta in rad, ref in m/s^2\n")
        fh.write(",".join(names) + "\n")
        np.savetxt(fh, data, fmt=["%.9f"] + ["%.12g"] * (len(names) - 1), delimiter=",")

    atomic_write(path, _write, text=True)
