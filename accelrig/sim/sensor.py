"""The simulated accelerometer: what a real MEMS part does to the true specific force.

raw = K f + o + noise, quantised to int16 counts at the range setting and
clipped at full scale, where

    K = diag(gain) @ T(nonorthogonality) @ R(misalignment)

R is a small rotation (the sensing frame misaligned with the body), T has unit
rows whose off-diagonal terms tilt the y axis in the x-y plane and the z axis
(the axes are not quite orthogonal), and gain scales each axis.  The
canonical correction (DESIGN.md) of such a sensor is C = K^-1, b = o.

The noise is white with one density for all axes unless told otherwise.  The
conditions real parts show and the papers' estimators assume away can be
switched on one by one (each independent of the others, all streamed block by
block with their state kept, so a long record is one continuous process):

    axis_noise    per-axis factors on the white sd (real parts: z often 2x x)
    ar1           the white part becomes AR(1) with this coefficient, same sd per sample
    flicker       1/f noise added, one-sided density h / f with h = flicker^2, (m/s^2)^2
                  at 1 Hz; made as a sum of first-order Gauss-Markov processes with
                  corners spaced three per decade (S(f) = sum 2 v / (pi fc (1 + (f/fc)^2)),
                  v = h ln 10 / 3 each), from 1e-4 Hz to the Nyquist frequency
    drift_rate    the offset moves linearly, m/s^2 per second of device time (3,)
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
    axis_noise        per-axis factors on the white noise sd (3,)
    ar1               AR(1) coefficient of the white part (0: white), marginal sd unchanged
    flicker           sqrt of the 1/f density at 1 Hz, (m/s^2)/sqrt(Hz) (0: none)
    flicker_slope     alpha of that density's h / f^alpha, 0 < alpha < 2 (1: flicker proper)
    drift_rate        offset drift, m/s^2 per s (3,); needs the sample times in ``sense``
    """

    offset: np.ndarray = field(default_factory=lambda: np.zeros(3))
    gain: np.ndarray = field(default_factory=lambda: np.ones(3))
    misalignment: np.ndarray = field(default_factory=lambda: np.zeros(3))
    nonorthogonality: np.ndarray = field(default_factory=lambda: np.zeros(3))
    noise_density: float = 300e-6 * STANDARD_GRAVITY  # MPU-9250 datasheet, 300 ug/sqrt(Hz)
    range_g: float = 2.0
    axis_noise: np.ndarray = field(default_factory=lambda: np.ones(3))
    ar1: float = 0.0
    flicker: float = 0.0
    flicker_slope: float = 1.0
    drift_rate: np.ndarray = field(default_factory=lambda: np.zeros(3))
    # filter states carried from one block to the next (None until the first block)
    _noise_state: dict | None = field(default=None, init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        for name in ("offset", "gain", "misalignment", "nonorthogonality", "axis_noise", "drift_rate"):
            setattr(self, name, np.asarray(getattr(self, name), dtype=float).reshape(3))
        if not -1.0 < self.ar1 < 1.0:
            raise ValueError(f"ar1 must lie in (-1, 1), got {self.ar1}")
        if self.flicker < 0 or np.any(self.axis_noise < 0):
            raise ValueError("flicker and axis_noise must not be negative")
        if not 0.0 < self.flicker_slope < 2.0:
            raise ValueError(f"flicker_slope must lie in (0, 2), got {self.flicker_slope}")

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

    def sense(self, force: np.ndarray, rng: np.random.Generator, rate: float,
              t: np.ndarray | None = None, response_t: np.ndarray | None = None) -> np.ndarray:
        """True specific force (n, 3) in m/s^2 -> int16 counts, with noise, quantisation, clipping.

        Successive calls continue one noise process (the coloured parts keep their state);
        ``t`` (true sample times, s) is needed only when ``drift_rate`` is set.  ``response_t``:
        ``response_matrix.T`` if the caller keeps it (a device streaming small blocks
        would otherwise rebuild it, trigonometry and all, for every block).
        """
        raw = force @ (self.response_matrix.T if response_t is None else response_t) + self.offset
        if np.any(self.drift_rate != 0):
            if t is None:
                raise ValueError("a drifting offset needs the sample times")
            raw = raw + np.asarray(t, dtype=float)[:, None] * self.drift_rate
        raw = raw + self.noise(raw.shape[0], rng, rate)
        counts = np.rint(raw / self.scale)
        np.clip(counts, -32768, 32767, out=counts)
        return counts.astype(np.int16)

    def noise(self, n: int, rng: np.random.Generator, rate: float) -> np.ndarray:
        """The next n samples of the noise process (n, 3), m/s^2; continues the previous call."""
        noise = np.zeros((n, 3))
        white_sd = self.noise_sd(rate) * self.axis_noise
        if self.noise_density > 0:
            e = rng.standard_normal((n, 3))
            if self.ar1 == 0.0:
                noise += e * white_sd
            else:
                from scipy.signal import lfilter  # only coloured noise loads scipy (start-up cost)

                state = self._state(rng, rate)
                rho = self.ar1
                # x_k = rho x_(k-1) + sqrt(1 - rho^2) e_k keeps a unit marginal sd
                x, _ = lfilter([np.sqrt(1.0 - rho * rho)], [1.0, -rho], e, axis=0,
                                zi=state["ar1"][None, :] * rho)
                state["ar1"] = x[-1].copy()
                noise += x * white_sd
        if self.flicker > 0:
            from scipy.signal import lfilter

            state = self._state(rng, rate)
            for k, fc in enumerate(self._flicker_corners(rate)):
                a = np.exp(-2.0 * np.pi * fc / rate)
                sd = np.sqrt(self.flicker_variance(fc))
                e = rng.standard_normal((n, 3))
                x, _ = lfilter([np.sqrt(1.0 - a * a)], [1.0, -a], e, axis=0,
                               zi=state["flicker"][k][None, :] * a)
                state["flicker"][k] = x[-1].copy()
                noise += x * sd
        return noise

    def flicker_variance(self, corner: float) -> float:
        """Variance of the relaxation process with ``corner`` Hz, one of three per decade that sum to h / f^alpha.

        The one-sided density of a process of variance v and corner f_c is (2 v / (pi f_c)) / (1 + (f / f_c)^2);
        with v = c f_c^(1 - alpha) and corners d = ln(10) / 3 apart in ln f_c the sum is close to
        c f^-alpha / (d sin(pi alpha / 2)), so c = h d sin(pi alpha / 2).  alpha = 1: v = h d for every corner."""
        alpha = self.flicker_slope
        return float(self.flicker**2 * np.log(10.0) / 3.0 * np.sin(np.pi * alpha / 2) * corner ** (1.0 - alpha))

    @staticmethod
    def _flicker_corners(rate: float) -> np.ndarray:
        decades = np.log10(rate / 2.0 / 1e-4)
        return 1e-4 * 10.0 ** (np.arange(int(np.floor(decades * 3)) + 1) / 3.0)

    def _state(self, rng: np.random.Generator, rate: float) -> dict:
        """The coloured processes start stationary: each state a draw from its unit marginal."""
        if self._noise_state is None:
            self._noise_state = {
                "ar1": rng.standard_normal(3),
                "flicker": [rng.standard_normal(3) for _ in self._flicker_corners(rate)],
            }
        return self._noise_state

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
            "axis_noise": self.axis_noise.tolist(),
            "ar1": self.ar1,
            "flicker": self.flicker,
            "flicker_slope": self.flicker_slope,
            "drift_rate": self.drift_rate.tolist(),
            "correction": {"matrix": corr.matrix.tolist(), "bias": corr.bias.tolist()},
        }


@dataclass
class SimClock:
    """The device's sample clock: a rate off nominal and host timestamp jitter.

    True sample k is taken at k / (nominal_rate * (1 + rate_error)); the
    timestamps the driver reports carry Gaussian jitter (sd ``jitter`` s), kept
    small enough that they still increase.  ``rate_drift`` (per second) makes the
    rate move during the run, as a crystal's does while it warms: rate(t) =
    true_rate (1 + rate_drift t), so sample k is taken when the integral of the
    rate reaches k.
    """

    nominal_rate: float = 200.0
    rate_error: float = 0.0
    jitter: float = 0.0
    rate_drift: float = 0.0

    @property
    def true_rate(self) -> float:
        return self.nominal_rate * (1.0 + self.rate_error)

    def times(self, first: int, n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        """(true times, reported times) of samples first .. first+n-1."""
        k = np.arange(first, first + n, dtype=float)
        if self.rate_drift:
            # true_rate (t + rate_drift t^2 / 2) = k, the root written to keep its precision for small drift
            true_t = 2 * k / self.true_rate / (1 + np.sqrt(1 + 2 * self.rate_drift * k / self.true_rate))
        else:
            true_t = k / self.true_rate
        if self.jitter > 0:
            limit = 0.45 / self.true_rate  # keep reported times increasing
            reported = true_t + np.clip(rng.standard_normal(n) * self.jitter, -limit, limit)
        else:
            reported = true_t
        return true_t, reported

    def truth(self) -> dict:
        return {"nominal_rate": self.nominal_rate, "rate_error": self.rate_error,
                "true_rate": self.true_rate, "jitter": self.jitter, "rate_drift": self.rate_drift}
