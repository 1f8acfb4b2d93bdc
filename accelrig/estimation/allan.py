"""Allan deviation of a still recording and the noise figures read from it.

Conventions (stated because datasheets differ):

* Overlapping Allan deviation at octave-spaced averaging times tau = m / fs,
  m = 1, 2, 4, ...  sigma^2(tau) = < (ybar_{k+m} - ybar_k)^2 > / 2 over all
  overlapping pairs of m-sample means.
* White-noise density N is ONE-SIDED, as on MEMS datasheets
  (ug/sqrt(Hz)): on the white-noise line sigma(tau) = N / sqrt(2 tau), and a
  white sequence sampled at fs has per-sample sd = N sqrt(fs / 2).  (The
  IEEE 952 "random walk coefficient" read at tau = 1 s is N / sqrt(2).)
* Bias instability B = minimum of sigma / 0.664 (IEEE 952: for flicker noise
  sigma flattens at sqrt(2 ln 2 / pi) B = 0.664 B).
* Rate random walk K: on the +1/2 line sigma(tau) = K sqrt(tau / 3), read at
  tau = 3 s; units (m/s^2)/sqrt(s).

Uncertainty of each sigma(tau) uses the equivalent degrees of freedom (edf)
of the overlapping estimator for the noise type that dominates where the
figure is read (Riley, NIST SP 1065, sec. 5.3, N phase points): white noise
for the density, flicker for the bias instability, random walk for K; then
u(sigma)/sigma = 1/sqrt(2 edf).  Points at different tau are correlated, so
the uncertainty given for a figure read from several points is that of the
best single point (conservative), not a combination that would pretend they
were independent.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from accelrig.errors import DataError
from accelrig.geometry import AXES
from accelrig.recording import Recording
from accelrig.result import Estimate

BIAS_INSTABILITY_FACTOR = 0.664   # IEEE 952: sigma_min = 0.664 B for flicker noise
SLOPE_TOLERANCE = 0.1             # how far a log-log slope may stray from -1/2 or +1/2 ...
SLOPE_SIGMAS = 2.0                # ... beyond its own statistical scatter
MIN_SAMPLES = 64
MIN_EDF_BIAS = 20.0              # trust a minimum only where sigma is known to ~16 %
HUMP_TAU_PER_PERIOD = 0.37        # a sinusoid's Allan deviation peaks at tau = 0.37 x its period


@dataclass
class AllanCurve:
    """Overlapping Allan deviation of one sequence at octave taus.

    ``edf`` (and so ``relative_uncertainty``) assumes white noise: right on the
    white-noise line, optimistic where flicker or random walk dominate; the
    figures read there use their own edf.
    """

    tau: np.ndarray          # s
    adev: np.ndarray         # same units as the data
    edf: np.ndarray          # equivalent degrees of freedom of each point
    m: np.ndarray            # averaging factor of each point
    n_samples: int           # length of the sequence

    @property
    def relative_uncertainty(self) -> np.ndarray:
        return 1.0 / np.sqrt(2.0 * self.edf)


def octave_factors(n: int) -> np.ndarray:
    """m = 1, 2, 4, ... while a pair of adjacent m-sample means exists (2m < n)."""
    ms = []
    m = 1
    while 2 * m < n:
        ms.append(m)
        m *= 2
    return np.asarray(ms, dtype=np.int64)


def white_edf(n: int, m: np.ndarray) -> np.ndarray:
    """Equivalent degrees of freedom of the overlapping ADEV for white noise (n samples)."""
    big_n = n + 1  # number of 'phase' points (cumulative sums) the formula counts
    m = np.asarray(m, dtype=float)
    edf = (3.0 * (big_n - 1) / (2.0 * m) - 2.0 * (big_n - 2) / big_n) * 4.0 * m**2 / (4.0 * m**2 + 5.0)
    return np.maximum(edf, 1.0)


def flicker_edf(n: int, m: float) -> float:
    """edf of the overlapping ADEV at factor m for flicker noise (n samples)."""
    big_n = n + 1
    if m == 1:
        return max(2.0 * (big_n - 2) ** 2 / (2.3 * big_n - 4.9), 1.0)
    return max(5.0 * big_n**2 / (4.0 * m * (big_n + 3.0 * m)), 1.0)


def random_walk_edf(n: int, m: float) -> float:
    """edf of the overlapping ADEV at factor m for random-walk noise (n samples)."""
    big_n = n + 1
    edf = (big_n - 2) / m * ((big_n - 1) ** 2 - 3.0 * m * (big_n - 1) + 4.0 * m**2) / (big_n - 3) ** 2
    return max(edf, 1.0)


def _relative(edf: float) -> float:
    return 1.0 / np.sqrt(2.0 * edf)


def allan_deviation(y: np.ndarray, rate: float, m: np.ndarray | None = None) -> AllanCurve:
    """Overlapping Allan deviation of evenly sampled data ``y`` (n,) at ``rate`` Hz."""
    y = np.asarray(y, dtype=float)
    n = y.size
    if n < MIN_SAMPLES:
        raise DataError(f"{n} samples are too few for an Allan deviation (need at least {MIN_SAMPLES})")
    if not rate > 0:
        raise DataError(f"sample rate {rate} Hz must be positive")
    ms = octave_factors(n) if m is None else np.asarray(m, dtype=np.int64)
    # Cumulative sums make every m-sample mean one subtraction: O(n) per tau.
    # Subtracting the mean first keeps the sums small (no cancellation on a 1 g axis).
    x = np.concatenate(([0.0], np.cumsum(y - y.mean())))
    adev = np.empty(ms.size)
    for i, mi in enumerate(ms):
        d = x[2 * mi:] - 2.0 * x[mi:-mi] + x[:-2 * mi]   # m (ybar_{k+m} - ybar_k)
        adev[i] = np.sqrt(0.5 * np.mean(d * d)) / mi
    return AllanCurve(ms / rate, adev, white_edf(n, ms), ms, n)


@dataclass
class AxisNoise:
    """Noise figures of one axis, with the points they were read from."""

    density: Estimate                       # (m/s^2)/sqrt(Hz), one-sided
    bias_instability: Estimate | None       # m/s^2
    bias_instability_tau: float | None      # s
    bias_instability_slopes: tuple[float, float] | None   # log-log slopes just before and after that tau
    random_walk: Estimate | None            # (m/s^2)/sqrt(s)
    white_points: np.ndarray                # indices of the taus on the white-noise line
    notes: list[str] = field(default_factory=list)

    def to_dict(self) -> dict:
        return {
            "density": self.density.to_dict(),
            "bias_instability": None if self.bias_instability is None else self.bias_instability.to_dict(),
            "bias_instability_tau": self.bias_instability_tau,
            "random_walk": None if self.random_walk is None else self.random_walk.to_dict(),
        }

    def reading(self) -> dict:
        """Where the bias instability was read (or why not) and the notes: the JSON beside the figures."""
        slopes = self.bias_instability_slopes
        return {
            "bias_instability_read_at": None if slopes is None else {
                "tau": self.bias_instability_tau, "slope_before": slopes[0], "slope_after": slopes[1]},
            "notes": list(self.notes),
        }


def _slopes(curve: AllanCurve) -> tuple[np.ndarray, np.ndarray]:
    """Log-log slope between neighbouring points and its standard uncertainty."""
    ratio = np.log(curve.adev[1:] / curve.adev[:-1]) / np.log(curve.tau[1:] / curve.tau[:-1])
    r = curve.relative_uncertainty
    u = np.sqrt(r[1:] ** 2 + r[:-1] ** 2) / np.log(curve.tau[1:] / curve.tau[:-1])
    return ratio, u


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """(start, stop) of runs of True."""
    runs, start = [], None
    for i, v in enumerate(mask):
        if v and start is None:
            start = i
        if not v and start is not None:
            runs.append((start, i))
            start = None
    if start is not None:
        runs.append((start, len(mask)))
    return runs


def _bias_instability(curve: AllanCurve, density: float, slope: np.ndarray, white_end: int
                      ) -> tuple[Estimate | None, float | None, tuple[float, float] | None, int, str]:
    """Bias instability at a flat bottom of the curve: (estimate, tau, slopes around it, index of the
    minimum, reason when not reached).

    The minimum is taken over the points with enough degrees of freedom to trust (flicker edf >=
    MIN_EDF_BIAS) and read only where (1) the curve has no hump from the end of the white-noise line
    (``white_end``) to two octaves past the minimum (a sinusoid of period P makes one near tau = 0.37 P:
    the dip before it, or the trough after it, is no bias instability), (2) it lies clearly (3 sd) above
    the white-noise line (for white noise the minimum is just the last point still falling), (3) no slope
    within two octaves after it is steeper than a random walk's +1/2 by 2 sd (a sinusoid's rise, or a
    drift ramp's: conservative), and (4) both neighbours agree with it within 2 combined sd: a flat
    bottom, not a dip between a fall and a rise. Uncertainties from the flicker edf.
    """
    edf = np.array([flicker_edf(curve.n_samples, float(m)) for m in curve.m])
    r = 1.0 / np.sqrt(2.0 * edf)
    u_slope = np.sqrt(r[1:] ** 2 + r[:-1] ** 2) / np.log(curve.tau[1:] / curve.tau[:-1])
    candidates = np.flatnonzero(edf >= MIN_EDF_BIAS)
    k = int(np.argmin(curve.adev))
    if candidates.size < 2:
        return None, None, None, k, f"fewer than 2 points of the curve have {MIN_EDF_BIAS:.0f} degrees of freedom"
    k = int(candidates[np.argmin(curve.adev[candidates])])
    # A hump between the white-noise line and two octaves past the minimum: a point clearly (2 combined
    # sd) above a point before it and one after it. Flicker and random walk never make one.
    humps = [j for j in range(white_end + 1, min(k + 3, curve.tau.size - 1))
             if np.any(curve.adev[j] > curve.adev[white_end:j] * (1.0 + SLOPE_SIGMAS * np.hypot(r[white_end:j], r[j])))
             and np.any(curve.adev[j] > curve.adev[j + 1:] * (1.0 + SLOPE_SIGMAS * np.hypot(r[j + 1:], r[j])))]
    if humps:
        j = max(humps, key=lambda i: curve.adev[i])
        return None, None, None, k, (
                f"the curve has a hump at tau = {curve.tau[j]:.3g} s: a periodic disturbance (period roughly "
                f"{curve.tau[j] / HUMP_TAU_PER_PERIOD:.2g} s), not a flat bottom")
    white_line = density / np.sqrt(2.0 * curve.tau[k])
    if not curve.adev[k] > white_line * (1.0 + 3.0 * curve.relative_uncertainty[k]):
        return None, None, None, k, "the Allan deviation is still falling at the longest tau"
    if k == 0 or k == curve.tau.size - 1:
        return None, None, None, k, f"the minimum is at the end of the curve (tau = {curve.tau[k]:.3g} s)"
    after = np.arange(k, min(k + 2, slope.size))
    steep = after[slope[after] - SLOPE_SIGMAS * u_slope[after] > 0.5]
    if steep.size:
        j = int(steep[0])
        return None, None, None, k, (
            f"the curve rises with slope {slope[j]:+.2f} after tau = {curve.tau[k]:.3g} s, steeper than a random "
            "walk's +1/2 (a sinusoid or a drift ramp rises at +1): not a flat bottom")
    for j in (k - 1, k + 1):
        if abs(curve.adev[j] / curve.adev[k] - 1.0) > SLOPE_SIGMAS * np.hypot(r[j], r[k]):
            return None, None, None, k, (
                f"no flat bottom: at tau = {curve.tau[j]:.3g} s the curve differs from its minimum at "
                f"tau = {curve.tau[k]:.3g} s by {100 * (curve.adev[j] / curve.adev[k] - 1):+.0f} %, "
                "beyond 2 sd")
    b = curve.adev[k] / BIAS_INSTABILITY_FACTOR
    return (Estimate(float(b), float(b * r[k]), "m/s^2"), float(curve.tau[k]),
            (float(slope[k - 1]), float(slope[k])), k, "")


def axis_noise(curve: AllanCurve) -> AxisNoise:
    """Read density, bias instability and random walk off one Allan curve."""
    if curve.tau.size < 3:
        raise DataError(
            f"the recording gives only {curve.tau.size} averaging times; the noise figures need at least 3",
            "record longer (a few minutes)",
        )
    slope, u_slope = _slopes(curve)
    tol = np.maximum(SLOPE_TOLERANCE, SLOPE_SIGMAS * u_slope)
    on_white = np.abs(slope + 0.5) <= tol
    # The white-noise line is the first stretch (from short tau) of >= 2 slopes at -1/2:
    # a digital low-pass filter flattens the shortest taus, flicker and drift the longest.
    runs = [r for r in _runs(on_white) if r[1] - r[0] >= 2]
    if not runs:
        raise DataError(
            "no white-noise region (slope -1/2) in the Allan deviation",
            "check the sensor was still and the record is at least a minute long",
        )
    first, stop = runs[0]
    points = np.arange(first, stop + 1)       # slope k joins points k and k+1
    r = curve.relative_uncertainty
    a_k = curve.adev[points] * np.sqrt(2.0 * curve.tau[points])
    w = curve.edf[points]
    density = float(np.sum(w * a_k) / np.sum(w))
    density_u = density * float(np.min(r[points]))
    notes: list[str] = []

    bias, bias_tau, bias_slopes, k_min, reason = _bias_instability(curve, density, slope, int(points[-1]))
    if bias is None:
        notes.append(f"bias instability not reached: {reason}")

    # Rate random walk: >= 2 slopes at +1/2 after the minimum, clearly above it.
    random_walk = None
    after = np.arange(k_min, slope.size)
    rising = np.abs(slope[after] - 0.5) <= tol[after]
    rw_runs = [(after[a], after[b - 1] + 1) for a, b in _runs(rising) if b - a >= 2]
    if rw_runs:
        lo, hi = rw_runs[-1]
        pts = np.arange(lo, hi + 1)
        edf_rw = np.array([random_walk_edf(curve.n_samples, float(curve.m[k])) for k in pts])
        # 2 sd (random-walk edf) above the minimum: the long-tau points have few degrees of freedom.
        if curve.adev[pts[-1]] > curve.adev[k_min] * (1.0 + 2.0 * _relative(float(edf_rw[-1]))):
            k_k = curve.adev[pts] * np.sqrt(3.0 / curve.tau[pts])
            k_val = float(np.sum(edf_rw * k_k) / np.sum(edf_rw))
            random_walk = Estimate(k_val, k_val * _relative(float(np.max(edf_rw))), "m/s^2/sqrt(s)")
    if random_walk is None:
        notes.append("rate random walk not seen: no +1/2 slope at long tau (record longer to see it)")
    return AxisNoise(
        density=Estimate(density, density_u, "m/s^2/sqrt(Hz)"),
        bias_instability=bias,
        bias_instability_tau=bias_tau,
        bias_instability_slopes=bias_slopes,
        random_walk=random_walk,
        white_points=points,
        notes=notes,
    )


@dataclass
class NoiseReport:
    """Noise figures of a still recording, per axis, and the curves for plotting."""

    rate: float
    n_samples: int
    duration: float
    curves: dict[str, AllanCurve]
    axes: dict[str, AxisNoise]
    recording_hash: str | None = None
    still_segment: dict | None = None    # start, stop, seconds, of_total (s) when only a stretch was read

    def arrays(self) -> dict[str, np.ndarray]:
        """What the TUI plots: tau, the ADEV per axis with its uncertainty, and the fitted white line."""
        out = {"tau": self.curves["x"].tau}
        for axis in AXES:
            c = self.curves[axis]
            out[f"adev_{axis}"] = c.adev
            out[f"adev_{axis}_uncertainty"] = c.adev * c.relative_uncertainty
            out[f"white_line_{axis}"] = self.axes[axis].density.value / np.sqrt(2.0 * c.tau)
        return out

    def to_profile_dict(self, date: str) -> dict:
        """The ``noise`` section of a profile (schema v1)."""
        return {
            "method": "overlapping Allan deviation, octave-spaced tau",
            "convention": "density one-sided: sigma(tau) = density / sqrt(2 tau); "
                          "bias instability = min sigma / 0.664 (IEEE 952); random walk: sigma = K sqrt(tau / 3)",
            "rate": float(self.rate),
            "duration": float(self.duration),
            "n_samples": int(self.n_samples),
            "recording_hash": self.recording_hash,
            "date": date,
            "axes": {axis: self.axes[axis].to_dict() for axis in AXES},
        }

    def to_json_dict(self, date: str) -> dict:
        """The profile section, with the still stretch read and where each bias instability was read (or why not)."""
        out = self.to_profile_dict(date)
        out["still_segment"] = self.still_segment
        for axis in AXES:
            out["axes"][axis].update(self.axes[axis].reading())
        return out


def noise_figures(rec: Recording, span: tuple[float, float] | None = None) -> NoiseReport:
    """Allan deviation and noise figures of a still recording (any units with a known scale).

    ``span`` (start, stop) in s: read only the samples with start <= t <= stop (the still stretch of a
    recording with disturbances; the caller decides which); the report states it as ``still_segment``
    and keeps the whole recording's hash.
    """
    rec = rec.to_si()
    recording_hash = rec.content_hash()
    still_segment = None
    if span is not None:
        inside = np.flatnonzero((rec.t >= span[0]) & (rec.t <= span[1]))
        whole = rec.duration
        rec = rec.slice(int(inside[0]), int(inside[-1]) + 1) if inside.size else rec.slice(0, 0)
        still_segment = {"start": float(span[0]), "stop": float(span[1]), "seconds": rec.duration,
                         "of_total": whole}
    n = len(rec)
    if n < MIN_SAMPLES:
        raise DataError(f"the recording has {n} samples; noise figures need at least {MIN_SAMPLES}",
                        "record a few minutes of the sensor lying still")
    gaps = rec.meta.get("gaps") or []
    if gaps:
        # the longest unbroken stretch is often long enough (a daemon's weeks hold hours between gaps)
        cuts = sorted({0, n, *(min(max(int(g["index"]), 0), n) for g in gaps)})
        a, b = max(zip(cuts[:-1], cuts[1:], strict=True), key=lambda ab: rec.t[ab[1] - 1] - rec.t[ab[0]])
        raise DataError(
            f"the recording has {len(gaps)} gap(s) in its samples; an Allan deviation needs an unbroken record",
            f"the longest unbroken stretch is t = {rec.t[a]:.1f}-{rec.t[b - 1]:.1f} s "
            f"({rec.t[b - 1] - rec.t[a]:.0f} s, seconds from the first sample read): pass --start/--stop to "
            "analyse it, or record again without lost samples",
        )
    dt = np.diff(rec.t)
    median = float(np.median(dt))
    if np.any(dt > 1.5 * median):
        k = int(np.argmax(dt > 1.5 * median))
        raise DataError(
            f"the timestamps jump by {dt[k]:.4g} s at t = {rec.t[k]:.3f} s ({dt[k] / median:.1f} sample periods)",
            "an Allan deviation needs evenly spaced samples; record again without gaps",
        )
    rate = rec.rate
    for i, axis in enumerate(AXES):
        if np.ptp(rec.acc[:, i]) == 0:
            raise DataError(
                f"axis {axis} never changes ({rec.acc[0, i]:g} m/s^2 throughout): no noise to measure",
                "the sensor's noise is below one count at this range, or the axis is stuck",
            )
    curves = {axis: allan_deviation(rec.acc[:, i], rate) for i, axis in enumerate(AXES)}
    axes = {axis: axis_noise(curves[axis]) for axis in AXES}
    return NoiseReport(rate, n, rec.duration, curves, axes, recording_hash, still_segment)
