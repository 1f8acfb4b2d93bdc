"""The simulated accelerometer: what a real MEMS part does to the true specific force.

raw = K f + o + noise, quantised to int16 counts at the range setting and
clipped at full scale, where

    K = diag(gain) @ T(nonorthogonality) @ R(misalignment)

R is a small rotation (the sensing frame misaligned with the body), T has unit
rows whose off-diagonal terms tilt the y axis in the x-y plane and the z axis
(the axes are not quite orthogonal), and gain scales each axis.  The
canonical correction (DESIGN.md) of such a sensor is C = K^-1, b = o.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from accelrig.geometry import rotation_xyz
from accelrig.result import Correction
from accelrig.units import STANDARD_GRAVITY, scale_for_range


def nonorthogonality_matrix(angles: np.ndarray) -> np.ndarray:
    """Unit-row matrix whose rows are the sensing axes: x exact, y tilted by
    angle[0] towards x, z tilted by angle[1] towards x and angle[2] towards y."""
    a, b, c = np.asarray(angles, dtype=float)
    t = np.array([[1.0, 0.0, 0.0], [np.sin(a), 1.0, 0.0], [np.sin(b), np.sin(c), 1.0]])
    return t / np.linalg.norm(t, axis=1, keepdims=True)


@dataclass
class SensorModel:
    """Ground truth of one simulated accelerometer.

    offset            o, m/s^2 (3,)
    gain              per-axis sensitivity relative to nominal (3,), 1 = perfect
    misalignment      rotation angles of the sensing frame, rad (3,)
    nonorthogonality  axis tilts, rad (3,)
    noise_density     white noise, one-sided, (m/s^2)/sqrt(Hz)
    range_g           full scale +-g; sets the count scale and the clipping
    """

    offset: np.ndarray = field(default_factory=lambda: np.zeros(3))
    gain: np.ndarray = field(default_factory=lambda: np.ones(3))
    misalignment: np.ndarray = field(default_factory=lambda: np.zeros(3))
    nonorthogonality: np.ndarray = field(default_factory=lambda: np.zeros(3))
    noise_density: float = 300e-6 * STANDARD_GRAVITY  # MPU-9250 datasheet, 300 ug/sqrt(Hz)
    range_g: float = 2.0

    def __post_init__(self) -> None:
        for name in ("offset", "gain", "misalignment", "nonorthogonality"):
            setattr(self, name, np.asarray(getattr(self, name), dtype=float).reshape(3))

    @classmethod
    def random(cls, rng: np.random.Generator, **overrides) -> SensorModel:
        """A plausible imperfect MEMS part: offsets of a few tens of mg, gains within 2 %,
        sub-degree misalignment and non-orthogonality."""
        values = dict(
            offset=rng.uniform(-0.4, 0.4, 3),
            gain=1.0 + rng.uniform(-0.02, 0.02, 3),
            misalignment=np.deg2rad(rng.uniform(-1.0, 1.0, 3)),
            nonorthogonality=np.zeros(3),
        )
        values.update(overrides)
        return cls(**values)

    @staticmethod
    def noise_density_for_sd(sd: float, rate: float) -> float:
        """One-sided density giving a per-sample sd at ``rate``: sd = density * sqrt(rate / 2)."""
        return sd / np.sqrt(rate / 2.0)

    def noise_sd(self, rate: float) -> float:
        return self.noise_density * np.sqrt(rate / 2.0)

    @property
    def scale(self) -> float:
        return scale_for_range(self.range_g)

    @property
    def response_matrix(self) -> np.ndarray:
        """K: raw = K f + o."""
        return np.diag(self.gain) @ nonorthogonality_matrix(self.nonorthogonality) @ rotation_xyz(self.misalignment)

    def correction(self) -> Correction:
        """The exact canonical correction of this sensor (zero covariance: it is truth)."""
        return Correction(np.linalg.inv(self.response_matrix), self.offset.copy(), np.zeros((12, 12)))

    def sense(self, force: np.ndarray, rng: np.random.Generator, rate: float) -> np.ndarray:
        """True specific force (n, 3) in m/s^2 -> int16 counts, with noise, quantisation, clipping."""
        raw = force @ self.response_matrix.T + self.offset
        if self.noise_density > 0:
            raw = raw + rng.standard_normal(raw.shape) * self.noise_sd(rate)
        counts = np.rint(raw / self.scale)
        np.clip(counts, -32768, 32767, out=counts)
        return counts.astype(np.int16)

    def truth(self) -> dict:
        corr = self.correction()
        return {
            "offset": self.offset.tolist(),
            "gain": self.gain.tolist(),
            "misalignment_rad": self.misalignment.tolist(),
            "nonorthogonality_rad": self.nonorthogonality.tolist(),
            "noise_density": self.noise_density,
            "range_g": self.range_g,
            "scale": self.scale,
            "correction": {"matrix": corr.matrix.tolist(), "bias": corr.bias.tolist()},
        }


@dataclass
class SimClock:
    """The device's sample clock: a rate off nominal and host timestamp jitter.

    True sample k is taken at k / (nominal_rate * (1 + rate_error)); the
    timestamps the driver reports carry Gaussian jitter (sd ``jitter`` s), kept
    small enough that they still increase.
    """

    nominal_rate: float = 200.0
    rate_error: float = 0.0
    jitter: float = 0.0

    @property
    def true_rate(self) -> float:
        return self.nominal_rate * (1.0 + self.rate_error)

    def times(self, first: int, n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        """(true times, reported times) of samples first .. first+n-1."""
        k = np.arange(first, first + n, dtype=float)
        true_t = k / self.true_rate
        if self.jitter > 0:
            limit = 0.45 / self.true_rate  # keep reported times increasing
            reported = true_t + np.clip(rng.standard_normal(n) * self.jitter, -limit, limit)
        else:
            reported = true_t
        return true_t, reported

    def truth(self) -> dict:
        return {"nominal_rate": self.nominal_rate, "rate_error": self.rate_error,
                "true_rate": self.true_rate, "jitter": self.jitter}
