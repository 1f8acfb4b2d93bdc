"""What the still samples say about the noise and the offset: correlation in time, per-axis sd, drift.

Every pose mean's uncertainty rests on the noise within the poses.  The fits take each pose as its
mean and the covariance of that mean; this module measures what that covariance must be, from the
data, with the one residual check of the project (``accelrig.estimation.residuals``):

correlation   per axis, the still samples of all poses (each pose's own mean removed) are one noise
              process seen in stretches: ``pooled_whiteness`` gives the integrated autocorrelation
              time tau (samples) and the Ljung-Box test.  When the policy calls it correlated (the
              test rejects at 1 % and u would grow by more than 10 %), each pose mean's covariance is
              the sample covariance scaled by sqrt(tau_j tau_k) (the long-run covariance): the
              effective sample count n / tau.  Why not the batch-means sandwich: a pose mean is a
              location estimate, whose variance is exactly sigma^2 tau / n; the sandwich would need
              blocks of 20 tau (400 samples at tau = 20) and at least 20 of them per pose, 8000
              samples where a 4-s pose at 200 Hz holds 800.  tau pooled over the run's poses has a
              quarter of the single pose's scatter.  Noise slower than tau can see (1/f) is caught by
              the halves of the poses (``_halves``), which widen each mean and add a between-pose wander
              (1/f law) that the fits use as a floor of their pose repeatability.
              Per pose and per axis the whiteness is recorded
              too (``details["poses"]``), for the operator to see where it came from.
slower        when the correlation still runs at the longest lag tau is read at (``slow_memory``: a memory as
              long as a hold), or the halves of the poses differ more than tau predicts (a slow wander under a
              white floor, which tau does not see), n / tau is too small and neighbouring holds share part of
              the noise: a model
              of the noise (``SlowNoise``, white + exponentially correlated, fitted to the holds' variogram)
              gives each hold mean's covariance and the covariance between holds, which the fits add through
              a sandwich; it replaces the halves' factor and wander.  Its level is checked against the holds'
              gravity magnitudes (``slow_model_check``) and scaled up when they scatter more.  A wander seen
              by the halves only is then checked for whether any hold shows its memory (``_memory_shown``):
              when none does, the offsets stand for the run's own level of it, and a warning says so.
per axis      each pose keeps its own 3 x 3 sample covariance (no pooled sigma): a z axis twice as
              noisy as x weighs its own rows in the six-face and multi-position fits.
drift         an offset that moves during the run is invisible in one pose's mean but biases the
              calibration.  Two looks: (1) the trend within the poses, the least-squares slope of
              every axis against time pooled over the poses (its u from the same tau), tested against
              zero; (2) a face (or orientation) held again later: the difference of the two poses'
              means along gravity (a tilt changes it only to second order, covered by the stated
              measured tilt difference) against its noise.  Either one significant at 1 % is a warning
              naming what was seen.  The revisits also measure the drift rate of their axes: the
              procedure (which has a first fit's calibration to make the magnitudes tilt-free) refers
              every pose mean to the middle of the run with it, whether significant or not (a
              correction only when significant would leave the drift just below the test's reach as a
              bias of up to 2 u), and propagates the rate's u into the result's.
              A drift slower than the within-pose trends can resolve is caught only by a revisit:
              with every face held once a slow drift of the offset is indistinguishable from the
              faces' tilts (each axis's offset is its own face pair's, at that pair's time), and the
              trend within a pose is about 5x too coarse to bound it at the offsets' precision, whatever
              the hold length (both scale alike).  Such a run is calibrated, with a warning that says
              drift was not checked and how large a drift could go unseen (``_unchecked``); the
              wizard asks the operator to end on the face they began with, and the docs say why.
shape         the revisits fit a straight line; whether the drift follows it is read from each pose's
              own slope (``drift_bend``): regressed on time they give the rate at the middle of the run
              and how fast it changes (the curvature), tested against the line; the curvature they show,
              or else a stated type B allowance from the largest rate the revisits allow, enters u.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from accelrig.estimation.distributions import chi2 as chi2_dist
from accelrig.estimation.gravity_fit import PoseStats, _student_variance_factor, axis_aligned_fit, face_tilts
from accelrig.estimation.residuals import ALPHA, Whiteness, pooled_variogram, pooled_whiteness, whiteness
from accelrig.geometry import AXES
from accelrig.result import Correction

# The slow-noise model's variogram is read at lags up to this share of the shortest hold used: beyond it too few
# pairs of samples remain in a hold to read it (at 3/4 a quarter of the hold's samples, pooled over the holds).
VARIOGRAM_REACH = 0.75
VARIOGRAM_LAGS = 30          # log-spaced lags from 1 sample to the reach


@dataclass
class SlowNoise:
    """Noise slower than a hold, per axis (x, y, z): white plus an exponentially correlated part (a first-order
    Gauss-Markov / AR(1) process), fitted to the still samples' variogram (``fit_slow_noise``).

    Why a model: a hold mean's variance is then known whatever the hold's length against the noise's memory
    (n / tau needs tau measured within a hold, which a memory as long as the hold does not allow: tau read
    over a quarter of the hold is a lower bound), and so is the covariance between the means of two holds
    (their shared slow part), which the fits take through a sandwich (``gravity_fit``).  Why this model: it
    has a level (the sill) that the noise returns to, which is what an offset is; a noise whose variogram
    still rises at the longest lag the holds show has no level the holds can see (``bounded``), and its
    sill is an extrapolation.

    V(k) = white + sill (1 - exp(-k dt / time)) for k >= 1: ``white`` the variance of the part uncorrelated
    from one sample to the next, ``sill`` the variance of the slow part, ``time`` its correlation time (s).
    """

    white: np.ndarray
    sill: np.ndarray
    time: np.ndarray
    rate: float
    reach: float                         # the longest lag the variogram was read at, s
    lags: np.ndarray                     # s
    observed: np.ndarray                 # (3, lags) the pooled variogram, (m/s^2)^2
    fitted: np.ndarray                   # (3, lags) the model's

    @property
    def bounded(self) -> np.ndarray:
        """Per axis: the variogram levels off within the lags the holds show (the correlation time is shorter
        than the reach), so the slow part's variance is measured, not extrapolated."""
        return self.time <= self.reach

    def mean_variances(self, times: list[np.ndarray]) -> np.ndarray:
        """(P, 3) variance of each hold mean per axis under the model: white / n + sill / n^2 sum_ij
        exp(-|t_i - t_j| / time) over the hold's samples (evenly spaced at its median interval)."""
        from scipy.signal import lfilter

        out = np.zeros((len(times), 3))
        for i, t in enumerate(times):
            n = len(t)
            step = float(np.median(np.diff(t))) if n > 1 else 1.0 / self.rate
            for k in range(3):
                rho = float(np.exp(-step / self.time[k]))
                # sum over the pairs i < j of rho^(j - i): y_j = rho (y_j-1 + 1)
                pairs = float(np.sum(lfilter([0.0, rho], [1.0, -rho], np.ones(n))))
                out[i, k] = self.white[k] / n + self.sill[k] * (n + 2.0 * pairs) / n**2
        return out

    def mean_covariance(self, times: list[np.ndarray]) -> np.ndarray:
        """(3 P, 3 P) covariance of the P hold means (rows pose-major: 3 i + axis) under the model, exact for
        the holds' own sample counts and times: ``mean_variances`` on the diagonal, and between two holds (i
        before j) sill mean_i exp(-(end_i - t) / time) mean_j exp(-(t - start_j) / time) exp(-(start_j - end_i)
        / time): the exponential's memory factors over the gap."""
        p = len(times)
        cov = np.diag(self.mean_variances(times).ravel())
        for k in range(3):
            if self.sill[k] <= 0:
                continue
            tail = np.array([float(np.mean(np.exp(-(t[-1] - t) / self.time[k]))) for t in times])
            head = np.array([float(np.mean(np.exp(-(t - t[0]) / self.time[k]))) for t in times])
            for i in range(p):
                for j in range(p):
                    if i != j and times[j][0] >= times[i][-1]:
                        gap = float(times[j][0] - times[i][-1])
                        cov[3 * i + k, 3 * j + k] = cov[3 * j + k, 3 * i + k] = (
                            self.sill[k] * tail[i] * head[j] * float(np.exp(-gap / self.time[k])))
        return cov

    def with_time(self, time: float) -> SlowNoise:
        """The same model with a longer memory and the same slope at short lags (sill / time per axis, what the
        holds measure when the memory outlasts them): sill and time grow together."""
        return replace(self, sill=self.sill / self.time * time, time=np.full(3, float(time)))

    def to_dict(self) -> dict:
        return {"model": "white + exponentially correlated (first-order Gauss-Markov), fitted to the variogram",
                "white_sd": np.sqrt(self.white).tolist(), "slow_sd": np.sqrt(self.sill).tolist(),
                "correlation_time_s": self.time.tolist(), "reach_s": self.reach,
                "bounded": self.bounded.tolist(), "lags_s": self.lags.tolist(),
                "variogram": self.observed.tolist(), "variogram_fitted": self.fitted.tolist()}


def fit_slow_noise(samples: list[np.ndarray], times: list[np.ndarray]) -> SlowNoise:
    """``SlowNoise`` of the holds' still samples (raw m/s^2, (n, 3) each, with their times): per axis the
    variogram pooled over the holds (``pooled_variogram``) at VARIOGRAM_LAGS log-spaced lags up to
    VARIOGRAM_REACH of the shortest hold, and the model fitted to it in log space (each lag's relative error
    counts alike: the variogram's scatter grows with its level).  One correlation time for the three axes (the
axes of one sensor share the physics of their wander, as ``fit_power_law``'s exponent; per axis it scatters
by a factor of 2-3 over 2-s holds), a white and a slow level per axis.  The correlation time is searched up to
    1000 x the reach: past the reach the fit only knows the slope sill / time (how fast the noise wanders),
    and the time it returns is then not a measurement (``bounded``)."""
    from scipy.optimize import least_squares

    rate = float(1.0 / np.median(np.concatenate([np.diff(t) for t in times if len(t) > 1])))
    reach_n = max(int(VARIOGRAM_REACH * min(len(t) for t in times)), 2)
    lags = np.unique(np.geomspace(1, reach_n, VARIOGRAM_LAGS).astype(int))
    observed = np.array([pooled_variogram([x[:, k] for x in samples], lags) for k in range(3)])
    v = np.maximum(observed, 1e-300)

    def model(theta):
        white, sill = np.exp(theta[0:3]), np.exp(theta[3:6])
        return white[:, None] + sill[:, None] * -np.expm1(-lags[None, :] / np.exp(theta[6]))

    floor, top = np.log(v[:, 0]) - 30.0, np.log(v[:, -1]) + 30.0
    start = np.concatenate([np.log(v[:, 0]), np.log(np.maximum(v[:, -1] - v[:, 0], 1e-3 * v[:, 0])),
                            [np.log(reach_n / 3.0)]])
    sol = least_squares(lambda theta: (np.log(model(theta)) - np.log(v)).ravel(), start,
                        bounds=(np.r_[floor, floor, np.log(0.1)], np.r_[top, top, np.log(1000.0 * reach_n)]))
    white, sill = np.exp(sol.x[0:3]), np.exp(sol.x[3:6])
    # the slow part's level shared by the axes, each axis's own a floor of it: under a white floor a slow part
    # whose rise over the lags a hold shows is within the variogram's scatter fits to nothing on one axis and
    # to its level on the next (held-out white 0.03 + AR(1) 0.01 m/s^2 over 25 s: one axis's sill fitted ~0 in
    # 1 run in 20, its offset's u then 10x too small); an axis of the sensor is not assumed quieter than the
    # three together show, only noisier where its own variogram says so
    shared = least_squares(lambda theta: (np.log(model(np.r_[theta[0:3], np.full(3, theta[3]), sol.x[6]]))
                                          - np.log(v)).ravel(),
                           np.r_[sol.x[0:3], np.mean(sol.x[3:6])],
                           bounds=(np.r_[floor, np.min(floor)], np.r_[top, np.max(top)]))
    sill = np.maximum(sill, float(np.exp(shared.x[3])))
    fitted = white[:, None] + sill[:, None] * -np.expm1(-lags[None, :] / np.exp(sol.x[6]))
    time = np.full(3, np.exp(sol.x[6]) / rate)
    return SlowNoise(white, sill, time, rate, reach_n / rate, lags / rate, observed, fitted)


@dataclass
class StillNoise:
    """The noise of a run's still samples, per axis (x, y, z)."""

    axes: list[Whiteness]                 # pooled over the poses, per axis
    sd: np.ndarray                        # per-axis sd, pooled within poses, m/s^2
    per_pose: list[list[Whiteness | None]]  # [pose][axis]; None for a pose too short to test
    drift: dict = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)

    @property
    def correlated(self) -> bool:
        return any(w.correlated for w in self.axes) or self.slow_factor > 1.0

    slow_factor: float = 1.0              # > 1 when pose halves disagree beyond tau (slower noise)
    wander_var: float = 0.0               # additive per-pose variance between poses from that slow noise
    # (slow_factor, wander_var) as the halves set them, kept when the slow-noise model replaces them (``_slow_model``)
    halves_widening: tuple[float, float] = (1.0, 0.0)
    # each pose's two halves (``_halves``): (pose index, samples in a half, the halves' mean difference per axis)
    halves: list[tuple[int, int, np.ndarray]] = field(default_factory=list)
    # noise slower than a hold (``slow_memory``): the model of it (``fit_slow_noise``) and the covariance of the
    # pose means it gives, (3 P, 3 P) pose-major; None when tau measured within the poses describes the noise
    slow: SlowNoise | None = None
    pose_mean_cov: np.ndarray | None = None
    pose_counts: np.ndarray = field(default_factory=lambda: np.zeros(0))
    pose_sd: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))   # each pose's own sample sd per axis
    # the offset's drift rate per raw axis (m/s^2 per s) measured by faces held again, and its u; u = 0 on an
    # axis without such a face (not measured: the rate there is 0 by assumption, and warned).  Set by the
    # procedure (``procedure._drift_rates``), which measures it from a first fit's calibrated magnitudes
    drift_rate: np.ndarray = field(default_factory=lambda: np.zeros(3))
    drift_rate_u: np.ndarray = field(default_factory=lambda: np.zeros(3))
    # each pose's own trend (the least-squares slope of each axis within the pose, m/s^2 per s), its u and the
    # pose's centre time: a model-free reading of how fast the offsets move at that moment (``drift_bend``)
    pose_slopes: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    pose_slope_u: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    pose_centres: np.ndarray = field(default_factory=lambda: np.zeros(0))
    # the drift tests made (trend, revisits, shape, bend): name -> (p value, the warning if it is to be given)
    drift_tests: dict[str, tuple[float, str]] = field(default_factory=dict)

    def drift_test(self, name: str, p: float, warning: str) -> None:
        """Record one drift test's p value and the warning it gives when the family rejects it."""
        self.drift_tests[name] = (p, warning)

    def drift_warnings(self) -> list[str]:
        """The drift tests' warnings, at a family-wise level ALPHA (Holm): up to four tests of one question
        (did the offset move?) each at ALPHA would warn a steady sensor in about 4 % of runs, not 1 %.
        Holm: the k-th smallest of the m p values rejects at ALPHA / (m - k + 1), as long as all smaller ones
        did.  Recorded in ``drift["family"]``.  Only the warnings go through the family: a test that rejects
        on its own still widens u where it does (``procedure._referred_to_middle``, ``drift_bend``)."""
        order = sorted(self.drift_tests, key=lambda name: self.drift_tests[name][0])
        rejected = set()
        for k, name in enumerate(order):
            if self.drift_tests[name][0] >= ALPHA / (len(order) - k):
                break
            rejected.add(name)
        self.drift["family"] = {"method": "Holm", "alpha": ALPHA,
                                "tests": {name: p for name, (p, _) in self.drift_tests.items()},
                                "warned": [name for name in self.drift_tests if name in rejected]}
        return [w for name, (_, w) in self.drift_tests.items() if name in rejected]

    @property
    def tau(self) -> np.ndarray:
        """Factor on the variance of a pose mean, per axis: tau where correlated (1 where white), times
        the slow-noise factor when the halves of the poses disagree beyond it; with the slow-noise model, the
        factor its pose means' variances have over sd^2 / n, averaged over the poses."""
        if self.pose_mean_cov is not None:
            return self.model_tau
        return np.array([max(w.tau, 1.0) if w.correlated else 1.0 for w in self.axes]) * self.slow_factor

    @property
    def tau_any(self) -> np.ndarray:
        """The tau measured, per axis, whether or not the policy calls it material (for tests of a slope)."""
        if self.pose_mean_cov is not None:
            return self.model_tau
        return np.array([max(w.tau, 1.0) for w in self.axes]) * self.slow_factor

    @property
    def model_tau(self) -> np.ndarray:
        """Per axis, the slow-noise model's pose-mean variance over sd^2 / n, averaged over the poses."""
        variances = np.diag(self.pose_mean_cov).reshape(-1, 3)
        return np.mean(variances * self.pose_counts[:, None], axis=0) / np.maximum(self.sd**2, 1e-300)

    def pose_covariance_scale(self, i: int) -> np.ndarray:
        """3 x 3 factors on pose i's sample covariance that make it (over n) its mean's covariance: sqrt(f_j f_k),
        f the ratio of the mean's variance to sd^2 / n per axis (the slow-noise model's for that pose when there
        is one, else tau: ``mean_covariance_scale``)."""
        if self.pose_mean_cov is None:
            return self.mean_covariance_scale()
        variance = np.diag(self.pose_mean_cov)[3 * i:3 * i + 3]
        root = np.sqrt(variance * self.pose_counts[i] / np.maximum(self.pose_sd[i] ** 2, 1e-300))
        return np.outer(root, root)

    def between_pose_covariance(self) -> np.ndarray | None:
        """(3 P, 3 P): the covariance between different poses' means (their shared slow noise; the diagonal
        blocks zero: each pose's own is in its PoseStats), None without the slow-noise model."""
        if self.pose_mean_cov is None:
            return None
        between = self.pose_mean_cov.copy()
        for i in range(len(self.pose_counts)):
            between[3 * i:3 * i + 3, 3 * i:3 * i + 3] = 0.0
        return between

    def mean_covariance_scale(self) -> np.ndarray:
        """3 x 3 factors on a sample covariance that make it the long-run covariance: sqrt(tau_j tau_k)."""
        root = np.sqrt(self.tau)
        return np.outer(root, root)

    @property
    def short_correlated(self) -> bool:
        """Correlated at lags within a pose (tau material on some axis), as opposed to slow noise only."""
        return any(w.correlated for w in self.axes)

    def slow_model_note(self) -> str:
        """What the slow-noise model did to u, in words ("" without one)."""
        if self.slow is None:
            return ""
        check = self.drift.get("slow_noise", {}).get("between_holds")
        checked = (", not checked against the holds (no degree of freedom to spare)" if check is None else
                   f"; its memory lengthened from {check['fitted_time_s']:.2g} s to the scatter of the holds' gravity "
                   f"magnitudes, {check['ratio']:.2g}x the variogram's" if check["variance_factor"] > 1.0 else
                   "; the scatter of the holds' gravity magnitudes does not exceed it")
        return (f"each pose mean's u and the share of it that the poses have in common from a model of the noise "
                f"(white + correlated over {float(self.slow.time[0]):.2g} s, fitted to the holds' variogram{checked}): "
                f"{np.sqrt(self.tau.max()):.1f}x the white-noise u of a pose mean")

    def describe(self) -> str:
        taus = "/".join(f"{w.tau:.1f}" for w in self.axes)
        if self.slow is not None and not any(w.correlated and not w.resolved for w in self.axes):
            ratio = self.drift.get("pose_halves", {}).get("ratio", 1.0)
            return (f"white at short lags (integrated autocorrelation time x/y/z {taus} samples), but the halves of the "
                    f"poses differ {np.sqrt(ratio):.1f}x more than that predicts (noise slower than a hold under a "
                    f"white floor): {self.slow_model_note()}")
        if self.slow is not None:
            return (f"correlated for longer than a hold can show (integrated autocorrelation time x/y/z {taus} samples "
                    f"read within the holds, a lower bound): {self.slow_model_note()}")
        if not self.correlated:
            return f"white within the poses (integrated autocorrelation time x/y/z {taus} samples)"
        slow = (f"the halves of the poses differ {np.sqrt(self.slow_factor):.1f}x more than "
                f"{'that' if self.short_correlated else 'white noise'} predicts (noise slower than a pose: "
                "1/f, a wander)")
        widened = f"{np.sqrt(self.tau.max()):.1f}x the white-noise u"
        if not self.short_correlated:
            return (f"white at short lags (integrated autocorrelation time x/y/z {taus} samples), but {slow}: "
                    f"each pose mean's u is widened to {widened}")
        return (f"correlated in time within the poses (integrated autocorrelation time x/y/z {taus} samples, "
                f"lag-1 autocorrelation {'/'.join(f'{w.lag1:.2f}' for w in self.axes)}): each pose mean's u "
                f"is from the effective sample count n / tau{'; ' + slow + ', which widens it too' if self.slow_factor > 1 else ''}"
                f": {widened}")

    def to_dict(self) -> dict:
        return {"correlated": self.correlated, "sd": self.sd.tolist(), "slow_factor": self.slow_factor,
                "wander_sd": float(np.sqrt(self.wander_var)),
                "tau_samples": [w.tau for w in self.axes], "mean_variance_factor": self.tau.tolist(),
                "axes": {a: w.to_dict() for a, w in zip(AXES, self.axes, strict=True)},
                "slow_model": self.slow is not None,
                "drift": self.drift, "description": self.describe()}


def still_noise(samples: list[np.ndarray], times: list[np.ndarray], faces: list[str | None]) -> StillNoise:
    """Check the still samples of the poses used (raw m/s^2, (n, 3) each, with their times).  The faces held
    again are checked once a first fit's calibration reads them free of the hand's tilt (``drift_checks``)."""
    centred = [x - x.mean(axis=0) for x in samples]
    axes = pooled_axes(samples)
    dof = sum(len(c) - 1 for c in centred)
    sd = np.sqrt(sum(np.sum(c**2, axis=0) for c in centred) / max(dof, 1))
    per_pose = [[whiteness(c[:, k]) if len(c) >= 10 else None for k in range(3)] for c in centred]
    noise = StillNoise(axes, sd, per_pose)
    noise.pose_counts = np.array([len(x) for x in samples], dtype=float)
    noise.pose_sd = np.array([np.std(x, axis=0, ddof=1) for x in samples]).reshape(-1, 3)
    span = float(max(t[-1] for t in times) - min(t[0] for t in times)) if times else 0.0
    pose_seconds = float(np.mean([t[-1] - t[0] for t in times])) if times else 0.0
    _halves(noise, centred, span / pose_seconds if pose_seconds > 0 else 1.0)
    _slow_model(noise, samples, times)
    _trend(noise, samples, times)
    _unchecked(noise, times, faces)
    _memory(noise, times)
    return noise


SETTLE_HINT = ("let the sensor settle at a steady temperature (powered, still) before calibrating, or hold each "
               "face several times longer")


def slow_memory(axes: list[Whiteness], times: list[np.ndarray]) -> str | None:
    """What to say when the noise's correlation outlasts what a pose can show (``Whiteness.resolved``), else None.

    tau is read over lags up to a quarter of the shortest pose; when the correlation still runs there, tau is
    a lower bound, each pose mean's u (from n / tau) too small, and neighbouring poses share the wander, so
    their scatter around the fit does not show it either (held-out AR(1) noise with a 3-10 s memory: errors of
    up to 15 u, and poses refused as tilted off their face: a wander that holds through a pose reads as a tilt)."""
    slow = [axis for axis, w in zip(AXES, axes, strict=True) if w.correlated and not w.resolved]
    if not slow or not times:
        return None
    worst = max((w for w in axes if not w.resolved), key=lambda w: w.tau)
    shortest = float(min(t[-1] - t[0] for t in times))
    return (f"the noise wanders more slowly than a hold can show ({', '.join(slow)}): its correlation still runs at "
            f"lag {worst.window} (a quarter of the shortest hold, {shortest:.1f} s), so its integrated time is more "
            f"than the {worst.tau:.0f} samples measured there")


WANDER_HINT = ("let the sensor settle powered at a steady temperature until its offset holds still, then calibrate "
               "again: holding the faces longer or placing them flatter does not help an offset that wanders")


def offset_wander(stats: list[PoseStats], g: float, axes: list[Whiteness]) -> str | None:
    """Why poses read off their faces when it is the sensor's offset that wanders, not the placement: what to say
    in place of "pose off a face", else None.

    A tilt turns gravity: the reading across the face moves by g sin(angle), its magnitude stays g.  An offset
    that wanders moves the reading by the same amount along every axis: across the face (where it reads as a
    tilt) and along gravity, so it shows in the gravity magnitudes, which no tilt changes.  The magnitudes
    |D (m - o)| of an axis-aligned fit (``axis_aligned_fit``, 6 parameters, P - 6 degrees of freedom) are
    tested against each pose mean's noise (n / tau along gravity).  When they disagree (p < ALPHA), their excess
    is the wander's variance along one axis (w^2); the wander explains the worst pose's angle when
    g sin(angle) is within what two axes' wander of that size reach among P poses, sqrt(chi^2_2 quantile at
    1 - ALPHA / P) x the wander's upper bound (its chi^2 on P - 6 dof at ALPHA).  A pose truly off its face
    keeps its magnitude and is refused as placed (held-out random walk 0.01 m/s^2/sqrt(s) over a 110 s run:
    offsets 0.1 m/s^2 apart read as 0.6 degree tilts; magnitudes 0.05 m/s^2 off g, 40x their noise)."""
    means = np.array([s.mean for s in stats]).reshape(-1, 3)
    aligned = axis_aligned_fit(means, g)
    dof = len(stats) - 6
    if aligned is None or dof <= 0:
        return None
    gains, offsets = aligned
    vectors = (means - offsets) * gains
    magnitudes = np.linalg.norm(vectors, axis=1) - g
    tau = np.sqrt([max(w.tau, 1.0) if w.correlated else 1.0 for w in axes])
    scale = np.outer(tau, tau)
    variance = np.array([float((d * gains) @ (s.mean_cov * scale) @ (d * gains))
                         for d, s in zip(vectors / np.linalg.norm(vectors, axis=1, keepdims=True), stats, strict=True)])
    chi2 = float(np.sum(magnitudes**2 / variance))
    p = float(chi2_dist.sf(chi2, dof))
    if p >= ALPHA:
        return None
    wander = float(np.sqrt(max(np.sum(magnitudes**2 - variance) / dof, 0.0)))
    upper = wander * float(np.sqrt(dof / chi2_dist.isf(1.0 - ALPHA, dof)))
    reach = float(np.sqrt(chi2_dist.isf(ALPHA / len(stats), 2))) * upper
    worst = max(face_tilts(stats, g), key=lambda t: t.angle_deg)
    across = g * float(np.sin(np.radians(worst.angle_deg)))
    if across > reach:
        return None
    return (f"the sensor's offset wanders: the poses' gravity magnitudes (which a tilt does not change) scatter "
            f"{wander:.2g} m/s^2 about g, {wander / float(np.sqrt(np.mean(variance))):.0f}x their noise (χ² = "
            f"{chi2:.3g} for {dof} degrees of freedom), and an offset wandering that much across the other axes "
            f"reads as a tilt: {worst.name} {worst.angle_deg:.1f} degrees from {worst.face} ({across:.2g} m/s^2 across "
            "it) is the offset's wander, not the placement")


def pooled_axes(samples: list[np.ndarray]) -> list[Whiteness]:
    """``pooled_whiteness`` of each axis over the poses' samples, each pose's own mean removed."""
    centred = [x - x.mean(axis=0) for x in samples]
    return [pooled_whiteness([c[:, k] for c in centred]) for k in range(3)]


def _slow_model(noise: StillNoise, samples: list[np.ndarray], times: list[np.ndarray]) -> None:
    """Noise slower than a hold: each pose mean's covariance, and the covariance between the poses' means, from the
    slow-noise model (``fit_slow_noise``) instead of n / tau.  It replaces the halves' factor and wander (the 1/f
    extrapolation, ``_halves``): the model holds what they stood for, the part of the noise a pose's own tau does
    not see, and the share of it that neighbouring poses have in common.

    Used when either look sees such noise: the correlation still runs at the longest lag tau is read at
    (``slow_memory``), or the halves of the poses differ more than tau predicts (``_halves``, significant at
    ALPHA).  The second is what sees a slow wander under a white floor: white noise at 0.03 m/s^2 hides an AR(1)
    part of 0.01 m/s^2 with a 25 s memory from tau (read 1.1-1.3 samples, resolved), yet that part moves the
    hold means several times their white u, and the 1/f extrapolation of the halves' excess reads it 2-3x low
    (held-out: offsets covered 62-70 %, errors up to 9 u)."""
    memory = slow_memory(noise.axes, times) is not None
    if not memory and noise.slow_factor <= 1.0:
        return
    noise.slow = fit_slow_noise(samples, times)
    noise.pose_mean_cov = noise.slow.mean_covariance(times)
    noise.halves_widening = (noise.slow_factor, noise.wander_var)
    noise.slow_factor, noise.wander_var = 1.0, 0.0
    noise.drift["slow_noise"] = {**noise.slow.to_dict(), "seen_by": "memory" if memory else "halves"}


def halves_explained(noise: StillNoise, model: SlowNoise, times: list[np.ndarray]) -> dict:
    """Does the variogram's model account for how far the poses' halves differ (``_halves``)?

    Each hold's two half means differ by d, with variance var_A + var_B - 2 cov_AB under the model
    (``mean_covariance`` of the two halves).  The halves average a hold's samples, so under a white floor they see a
    slow part that the variogram within the holds does not: white 0.03 + AR(1) 0.01 m/s^2 over 25 s makes the halves
    differ ~1.8x the white prediction, while the variogram at 3/4 of a hold rises ~1 % above its floor, within its
    own scatter, and its fitted memory is then anything from 0.2 s to its search bound.  sum d^2 / var against
    chi^2 with one degree of freedom per pose and axis: rejected at ALPHA, the holds do not show the wander's memory
    (the model fitted to the variogram is not a measurement of it)."""
    chi2, count = 0.0, 0
    for i, half, d in noise.halves:
        t = times[i]
        cov = model.mean_covariance([t[:half], t[half:2 * half]])
        var = np.diag(cov)[:3] + np.diag(cov)[3:] - 2.0 * np.diag(cov[:3, 3:])
        chi2 += float(np.sum(d**2 / np.maximum(var, 1e-300)))
        count += 3
    return {"chi2": chi2, "dof": count, "ratio": chi2 / max(count, 1),
            "p_value": float(chi2_dist.sf(chi2, count)) if count else 1.0}


# A hold shows a memory when its two halves lie at least two memories apart (their centres are half the hold
# apart): a memory up to this share of the longest hold.  And the halves tell a memory from a level only when
# they see the wander at two separations at least MEMORY_SHOWN_SPREAD apart (the longest hold against the median
# one): a memory shorter than both gives the same excess at both, a wander slower than both a larger one at the
# longer (holds of one length, 4.5-6 s: a memory read as 1.1 s passed the halves, the truth was 25 s, b_z 7 u off)
MEMORY_SHOWN_SHARE = 0.25
MEMORY_SHOWN_SPREAD = 2.0


def _memory_shown(noise: StillNoise, times: list[np.ndarray]) -> None:
    """A wander under a white floor (the model engaged by the halves of the poses): do the holds show its memory?

    The variogram within the holds rises only by a few % of the white floor over a hold, so the memory the model
    carries comes from that rise and the holds' gravity magnitudes, and both match a memory of a few seconds as
    well as one of tens: the magnitudes' scatter rises with the memory while the holds' means wander apart, then
    falls once neighbouring holds share the wander and the fit's offsets take it.  The offsets stand for the run's
    own level of the wander either way (their u from the model covers it: held-out white 0.03 + AR(1) 0.01 m/s^2
    over 25 s, 100 % of the runs); how far that level lies from the long-term one depends on the memory, which a
    run of short holds does not measure (the same runs: the memory read 1-16 s, the long-term offsets covered
    78 %, up to 7 u off).  The holds show it when some hold is long enough (MEMORY_SHOWN_SHARE) and longer than
    most (MEMORY_SHOWN_SPREAD), and the halves of the poses, long and short, differ as the model says
    (``halves_explained``, at ALPHA); else a warning says what
    the offsets stand for and how far a slower wander's long-term level can lie, the wander's rise over the run at
    the rate the halves show (what a memory as long as the run gives).  Recorded in
    ``drift["slow_noise"]["memory_shown"]``."""
    lengths = np.array([t[-1] - t[0] for t in times])
    longest, median = float(lengths.max()), float(np.median(lengths))
    time = float(noise.slow.time[0])
    check = halves_explained(noise, noise.slow, times)
    short_enough = time <= MEMORY_SHOWN_SHARE * longest and longest >= MEMORY_SHOWN_SPREAD * median
    explained = not (check["p_value"] < ALPHA and check["ratio"] > 1.0)
    record = {"longest_hold_s": longest, "median_hold_s": median, "time_s": time, "halves": check,
              "shown": short_enough and explained}
    noise.drift["slow_noise"]["memory_shown"] = record
    if record["shown"]:
        return
    span = float(max(t[-1] for t in times) - min(t[0] for t in times))
    # adjacent half means a apart differ by (4/3) s a beyond their white part, for a wander rising as s per second
    rates = [(float(d @ d) / 3.0 - float(np.mean(noise.sd**2)) * 2.0 / half) / (4.0 / 3.0 * half / noise.slow.rate)
             for _, half, d in noise.halves]
    reach = float(np.sqrt(max(float(np.mean(rates)), 0.0) * span))
    record["rise_over_run_sd"] = reach
    why = (f"holds of {median:.1f} s (the longest {longest:.1f} s) cannot tell it from a longer one"
           if not short_enough else
           f"the halves of the poses differ {np.sqrt(check['ratio']):.1f}x more than it accounts for (χ² = "
           f"{check['chi2']:.3g} for {check['dof']} degrees of freedom)")
    noise.warnings.append(
        f"the noise wanders under its white floor more slowly than the holds can show: its memory is read as "
        f"{time:.2g} s, but {why}: the offsets stand for the run's own level of that wander (their u allows for "
        f"that memory); a slower wander's long-term level can lie up to about {reach:.2g} m/s^2 from it (its rise "
        f"over the {span:.0f} s run at the rate the holds show): {SETTLE_HINT}")


# The memory the holds' scatter asks for may be at most this share of the run (first hold to last): beyond it the
# run's own average of the slow noise, which the offsets carry, has a variance of more than a third of the noise's
# level, and that share rests on a memory several times longer than anything the run can show.
SLOW_MEMORY_SHARE = 0.2


def slow_model_check(noise: StillNoise, chi2: float, dof: int, samples: list[np.ndarray],
                     times: list[np.ndarray]) -> str | None:
    """The slow-noise model against the holds themselves (``_between_holds``); a refusal's text when the noise
    cannot be bounded.  A model the halves of the poses engaged (a wander under a white floor) is then checked for
    whether the holds show its memory at all (``_memory_shown``)."""
    said = _between_holds(noise, chi2, dof, samples, times)
    if said is None and noise.slow is not None and noise.drift["slow_noise"]["seen_by"] == "halves":
        _memory_shown(noise, times)
    return said


def _between_holds(noise: StillNoise, chi2: float, dof: int, samples: list[np.ndarray],
                   times: list[np.ndarray]) -> str | None:
    """The slow-noise model against the holds themselves; a refusal's text when the noise cannot be bounded.

    ``chi2`` and ``dof``: a first fit's lack of fit, the poses' gravity magnitudes against their variances from
    the model (tilt-free: each hold mean's noise along gravity).  The variogram within the holds reads the slow
    part low when its memory is as long as a hold: its level is an extrapolation from lags up to 3/4 of the
    shortest hold, and the pose detector trims the ends of a hold where the noise had wandered off the plateau,
    which are the largest excursions (held-out AR(1) noise with a 1.7 s memory, holds kept 2 s: the hold means
    scatter 2.3x the model's variance; with 5 s, 7x).  The magnitudes see that scatter directly.  When their
    chi^2 exceeds its degrees of freedom (widened by the Student factor of those few dof), the model's memory is
    lengthened, its slope at the lags the holds show kept (``SlowNoise.with_time``), until the hold means'
    variance is that much larger; the model is a floor, never shortened.  A longer memory also raises what
    neighbouring holds and the whole run share (the run's average, which moves the offsets and which no
    scatter shows), which a plain scaling of the variances would leave at the variogram's reading.  When the
    memory asked for exceeds SLOW_MEMORY_SHARE of the run, the run cannot bound it: the text to refuse with.
    Done before the drift's rates and curvatures are fitted: they would take the degrees of freedom that show
    it.  Recorded in ``drift["slow_noise"]["between_holds"]``."""
    if noise.slow is None or dof <= 0 or not np.isfinite(chi2):
        return None
    from scipy.optimize import brentq

    ratio = float(chi2 / dof)
    factor = ratio * _student_variance_factor(dof) if ratio > 1.0 else 1.0
    record = {"chi2": float(chi2), "dof": int(dof), "ratio": ratio, "p_value": float(chi2_dist.sf(chi2, dof)),
              "variance_factor": factor, "fitted_time_s": float(noise.slow.time[0])}
    noise.drift["slow_noise"]["between_holds"] = record
    span = float(max(t[-1] for t in times) - min(t[0] for t in times))
    if factor <= 1.0:
        record["time_s"] = float(noise.slow.time[0])
        if noise.drift["slow_noise"]["seen_by"] == "halves" and record["time_s"] > SLOW_MEMORY_SHARE * span:
            _halves_instead(noise, record, record["time_s"], span, samples, times)
        return None
    fitted = noise.slow
    target = factor * float(np.mean(fitted.mean_variances(times)))

    def excess(log_time: float) -> float:
        return float(np.mean(fitted.with_time(float(np.exp(log_time))).mean_variances(times))) - target

    low, high = np.log(float(fitted.time[0])), np.log(max(100.0 * span, float(fitted.time[0])))
    time = float(np.exp(brentq(excess, low, high, xtol=1e-3))) if excess(high) > 0 else float(np.exp(high))
    noise.slow = fitted.with_time(time)
    noise.pose_mean_cov = noise.slow.mean_covariance(times)
    record["time_s"] = time
    noise.drift["slow_noise"].update(noise.slow.to_dict())
    if time <= SLOW_MEMORY_SHARE * span:
        return None
    if noise.drift["slow_noise"]["seen_by"] == "halves":
        _halves_instead(noise, record, time, span, samples, times)
        return None
    slow = [a for a, w in zip(AXES, noise.axes, strict=True) if w.correlated and not w.resolved]
    axes = f" ({', '.join(slow)})" if slow else ""
    return (f"the noise wanders more slowly than a hold can show{axes}: the holds' gravity magnitudes scatter "
            f"{ratio:.1f}x what the noise within the holds predicts (χ² = {chi2:.3g} for {dof} degrees of freedom), "
            f"which takes {_memory_asked(time, span)}: "
            "the run's own average of that noise, which the offsets carry, cannot be bounded from it")


def _memory_asked(time: float, span: float) -> str:
    """The memory the holds ask for, as words: beyond the run itself its size is not measured (an extrapolation
    to "10113 s" of a 101 s run reads as a finding it is not)."""
    if time > span:
        return f"a memory longer than the whole {span:.0f} s run"
    return f"a memory of about {time:.0f} s, more than {SLOW_MEMORY_SHARE:.0%} of the {span:.0f} s run"


def _halves_instead(noise: StillNoise, record: dict, time: float, span: float, samples: list[np.ndarray],
                    times: list[np.ndarray]) -> None:
    """The slow-noise model seen by the halves only (tau resolved within the holds) asks for a memory the run cannot
    bound: a wander with no level the run shows (a random walk, 1/f^1.5) under a white floor.  The halves' 1/f
    widening and the drift's fitted terms stand for it, as they do without the model (held-out random walk
    0.002/sqrt(s) + white 0.03: covered 92-98 %; with the model, u 2.6x the errors' sd and a memory of thousands
    of seconds), with a warning that names it, rather than a refusal of a run that calibrates."""
    record["fallback"] = "the halves' widening: the memory asked for is more than the run can bound"
    noise.slow, noise.pose_mean_cov = None, None
    noise.slow_factor, noise.wander_var = noise.halves_widening
    _trend(noise, samples, times)      # its u was the model's: now the halves' widening's
    noise.warnings.append(
        f"the noise is correlated for longer than a hold can show under its white floor: the holds' variogram and "
        f"gravity magnitudes (χ² = {record['chi2']:.3g} for {record['dof']} degrees of freedom) ask for "
        f"{_memory_asked(time, span)}: the offsets stand for the run's own "
        f"level of that wander (as for a drift), their u widened from the halves of the poses (1/f), which may read "
        f"a wander this slow low: {SETTLE_HINT}")


def _memory(noise: StillNoise, times: list[np.ndarray]) -> None:
    """Warn when the noise outlasts a pose (``slow_memory``): no u is right then, the warning names the cause."""
    said = slow_memory(noise.axes, times)
    if said is None:
        return
    worst = max((w for w in noise.axes if not w.resolved), key=lambda w: w.tau)
    noise.drift["memory"] = {"window": worst.window, "tau_lower_bound": worst.tau}
    # said with what u holds for it once the slow-noise model is checked (``slow_model_check``): a warning
    # either way, since the model's level is an extrapolation beyond the holds
    noise.warnings.append(f"{said}; u allows for it from a model of the noise, but the noise's level beyond a "
                          f"hold is an extrapolation: {SETTLE_HINT}")


def _halves(noise: StillNoise, centred: list[np.ndarray], span_in_poses: float) -> None:
    """The model-free check of tau: each pose's two halves' means differ by d with var(d) = 4 sigma^2 tau / n
    when tau describes the noise.  Noise slower than the autocorrelation window sees (1/f, a wander) makes
    them differ more (ratio R, pooled over poses and axes, 3 P degrees of freedom).  When R is significant
    at ALPHA, each pose mean's variance becomes 1 + 2 (R - 1) k times the tau model's: R within the pose,
    and the rest as an additive per-pose variance ``wander_var`` (it does not shrink with the pose's length):
    the excess seen between the halves of a pose, extrapolated to the separation of the poses with the
    1/f law.  For 1/f noise (flat Allan variance) two means of length tau a distance D apart differ in variance by 2 h (2 ln 2 + ln(D / tau)),
    so relative to adjacent halves by k = 1 + ln(D / tau) / (2 ln 2), D / tau the run's span in pose
    lengths; and a pose mean's deviation from the run's level has half the variance of such a difference,
    where for white noise it has a quarter of the halves' (hence the 2)."""
    tau = np.array([max(w.tau, 1.0) if w.correlated else 1.0 for w in noise.axes])
    ratios, differences = [], []
    for i, c in enumerate(centred):
        half = len(c) // 2
        if half < 5:
            continue
        d = c[:half].mean(axis=0) - c[half:2 * half].mean(axis=0)
        ratios.append(half * d**2 / 2.0 / (noise.sd**2 * tau))     # ~ chi^2(1) per axis under the tau model
        differences.append((i, half, d))
    if not ratios:
        return
    noise.halves = differences
    ratios = np.array(ratios)
    dof = ratios.size
    ratio = float(ratios.mean())
    p = float(chi2_dist.sf(ratio * dof, dof))
    noise.drift["pose_halves"] = {"ratio": ratio, "dof": dof, "p_value": p}
    if p < ALPHA and ratio > 1.0:
        reach = 1.0 + np.log(max(span_in_poses, 1.0)) / (2.0 * np.log(2.0))
        noise.slow_factor = ratio
        # the rest of 2 (R - 1) k, beyond the (R - 1) inside each pose mean, is common to a pose whatever its
        # length: an additive per-pose variance (the fits' wander_var), per axis sigma^2 tau / n
        n_mean = float(np.mean([len(c) for c in centred]))
        unit = noise.sd**2 * np.array([max(w.tau, 1.0) if w.correlated else 1.0 for w in noise.axes]) / n_mean
        noise.wander_var = float(np.mean(unit)) * (ratio - 1.0) * (2.0 * reach - 1.0)
        noise.drift["pose_halves"]["extrapolated_to_span"] = reach
        noise.drift["pose_halves"]["wander_sd"] = float(np.sqrt(noise.wander_var))


def _trend(noise: StillNoise, samples, times) -> None:
    """Pooled within-pose slope per axis (m/s^2 per s) and its u; warn when it differs from zero at ALPHA.
    Each pose's own slope is kept too (``pose_slopes``), for the check of the drift's shape."""
    sxx = 0.0
    sxy = np.zeros(3)
    own, own_sxx = [], []
    for x, t in zip(samples, times, strict=True):
        dt = t - t.mean()
        sxx += float(dt @ dt)
        sxy += dt @ (x - x.mean(axis=0))
        own.append(dt @ (x - x.mean(axis=0)) / max(float(dt @ dt), 1e-300))
        own_sxx.append(float(dt @ dt))
    if sxx <= 0:
        return
    noise.pose_centres = np.array([float(np.mean(t)) for t in times])
    noise.pose_slopes = np.array(own)
    noise.pose_slope_u = noise.sd * np.sqrt(noise.tau_any[None, :] / np.maximum(np.array(own_sxx), 1e-300)[:, None])
    slope = sxy / sxx
    # var(slope) = sigma^2 tau / sum dt^2 for a process correlated over tau samples (long-run variance)
    u = noise.sd * np.sqrt(noise.tau_any / sxx)
    chi2 = float(np.sum((slope / u) ** 2))
    p = float(chi2_dist.sf(chi2, 3))
    noise.drift["trend"] = {"slope": slope.tolist(), "u": u.tolist(), "chi2": chi2, "p_value": p}
    warning = ""
    if p < ALPHA:
        k = int(np.argmax(np.abs(slope / u)))
        warning = (
            f"the offset drifts during the poses: {AXES[k]} moves {slope[k] * 60:+.3g} m/s^2 per minute "
            f"({abs(slope[k] / u[k]):.1f} u; all axes chi^2 {chi2:.1f} for 3, p = {p:.1g}): warming up? "
            "Let the sensor settle powered, or calibrate again later; the offsets hold for the middle of the run")
    noise.drift_test("trend", p, warning)


def offset_readings(samples: list[np.ndarray], faces: list[str | None], first: Correction) -> np.ndarray:
    """Per pose, its face axis's raw offset as the calibrated gravity magnitude reads it (m/s^2; NaN without a
    face): |C (m - b)| / s, s = d|C (m - b)| / d m_k of the face's first hold (about +-1 for -+k down).

    |C (m - b)| is g whatever the tilt, so the change of this reading between two holds of a face is the
    offset's change alone, without the hand's re-placement tilt, which the raw reading along gravity carries
    at first order through the axes' misalignment (g K_kj dtheta_j: 1 degree against 0.5 degree of
    misalignment moves it 1.5e-3 m/s^2, a pose mean's noise) and at second order through the tilt itself.
    The first fit's errors change it by a part in 1e4 of the tilt at most: far below the noise."""
    readings = np.full(len(samples), np.nan)
    for face in dict.fromkeys(f for f in faces if f is not None):
        idx = [k for k, f in enumerate(faces) if f == face]
        axis = AXES.index(face[1])
        vectors = [first.apply(samples[k].mean(axis=0)) for k in idx]
        sensitivity = float(vectors[0] @ first.matrix[:, axis]) / float(np.linalg.norm(vectors[0]))
        readings[idx] = [float(np.linalg.norm(v)) / sensitivity for v in vectors]
    return readings


def drift_checks(noise: StillNoise, samples: list[np.ndarray], times: list[np.ndarray], faces: list[str | None],
                 first: Correction) -> bool:
    """The faces held again, read on a first fit's calibrated magnitudes (``offset_readings``): the change
    between a face's first and last holds (``_revisits``) and the middle hold of a face held three times
    against the line through the other two (``_shape``).  False when no face was held again."""
    readings = offset_readings(samples, faces, first)
    _revisits(noise, readings, samples, times, faces)
    _shape(noise, readings, samples, times, faces)
    return bool(noise.drift.get("revisits"))


def _revisits(noise: StillNoise, readings: np.ndarray, samples, times, faces) -> None:
    """A face held twice: the change of its axis's offset between the first and the last hold.

    The change is read on the calibrated magnitudes (``offset_readings``), so the two holds' different tilts
    do not enter it: its sd is the two means' noise along that axis (n / tau) and the slow-noise wander
    between poses.  The tilt change between the holds (the cross-axis change over g) is recorded."""
    found = []
    tau = noise.tau_any
    for face in dict.fromkeys(f for f in faces if f is not None):
        idx = [k for k, f in enumerate(faces) if f == face]
        if len(idx) < 2:
            continue
        a, b = idx[0], idx[-1]
        axis = AXES.index(face[1])
        cross = [k for k in range(3) if k != axis]
        d = (samples[b].mean(axis=0)[cross] - samples[a].mean(axis=0)[cross]) / np.linalg.norm(samples[a].mean(axis=0))
        change = float(readings[b] - readings[a])
        var = noise.sd[axis] ** 2 * tau[axis] * (1 / len(samples[a]) + 1 / len(samples[b]))
        var += 2.0 * noise.wander_var   # the two means' slow noise (1/f) too
        z = change / np.sqrt(var)
        found.append({"face": face, "first_pose": a, "last_pose": b,
                      "first": float(times[a].mean()), "last": float(times[b].mean()),
                      "change": change, "tilt_change_deg": float(np.degrees(np.sqrt(d @ d))),
                      "u": float(np.sqrt(var)), "z": float(z)})
    if not found:
        return
    noise.drift["revisits"] = found
    chi2 = float(sum(f["z"] ** 2 for f in found))
    p = float(chi2_dist.sf(chi2, len(found)))
    noise.drift["revisit_p_value"] = p
    warning = ""
    if p < ALPHA:
        worst = max(found, key=lambda f: abs(f["z"]))
        span = worst["last"] - worst["first"]
        warning = (
            f"the offset drifted during the run: {worst['face']} down read {worst['change']:+.4f} m/s^2 "
            f"along {worst['face'][1]} at t = {worst['last']:.0f} s against t = {worst['first']:.0f} s "
            f"({abs(worst['z']):.1f} u, {span:.0f} s apart): warming up? The offsets are referred to the middle "
            "of the run with the drift measured (as a straight line, its u included); let the sensor settle "
            "powered and calibrate again for the best result")
    noise.drift_test("revisits", p, warning)


# The middle hold of a face held three times must lie in the middle three fifths of the span between its first
# and last holds to tell a curve from a line: nearer to either end, the departure from the chord is too small
# against its noise (the three holds would measure a rate twice, not a shape).  And the three must cover at
# least half the run (first to last pose): a curvature measured over a short stretch, extrapolated to the
# whole run, would carry its u many times over into the offsets.  Both are in time, not in holds: the wizard
# ends on the faces held three times (poses.py) so that their holds span 0.7-0.85 of a run held at an even
# pace, and still over half of one whose six faces took twice as long as the rest.
MIDDLE_SHARE = (0.2, 0.8)
SHAPE_MIN_COVER = 0.5


def shape_holds(centres: list[float], faces: list[str | None]) -> dict[int, tuple[str, tuple[int, int, int], float]]:
    """Per axis, the face whose three holds can show the drift's shape (``_shape``), from the poses' centre
    times: held at least three times, its first and last holds covering at least SHAPE_MIN_COVER of the run
    (first to last pose centre), the hold nearest the middle of that span at a share w within MIDDLE_SHARE;
    of several such faces the one with the most central middle hold.  axis index -> (face, (first, middle,
    last) pose indices, w)."""
    run = float(max(centres) - min(centres)) if centres else 0.0
    best: dict[int, tuple[str, tuple[int, int, int], float]] = {}
    for face in dict.fromkeys(f for f in faces if f is not None):
        idx = [k for k, f in enumerate(faces) if f == face]
        if len(idx) < 3:
            continue
        t_a, t_b = centres[idx[0]], centres[idx[-1]]
        if t_b - t_a < SHAPE_MIN_COVER * run:
            continue
        j = min(range(1, len(idx) - 1), key=lambda i: abs(centres[idx[i]] - (t_a + t_b) / 2))
        w = (centres[idx[j]] - t_a) / (t_b - t_a)
        if not MIDDLE_SHARE[0] <= w <= MIDDLE_SHARE[1]:
            continue
        axis = AXES.index(face[1])
        if axis not in best or abs(w - 0.5) < abs(best[axis][2] - 0.5):
            best[axis] = (face, (idx[0], idx[j], idx[-1]), w)
    return best


def _shape(noise: StillNoise, readings: np.ndarray, samples, times, faces) -> None:
    """A face held three times, far apart: is its offset on the straight line through the first and last?

    The middle hold m (the one nearest the middle of the span, at share w of it from the first hold a to the
    last b) reads the first hold's offset plus its change (``offset_readings``: on the calibrated magnitudes,
    whatever the holds' tilts); a straight-line drift puts that change at w times the change to b, so the
    departure  D = (m - a) - w (b - a)  is zero whatever the rate.  Noise: sigma^2 tau (1/n_m + (1 - w)^2/n_a
    + w^2/n_b), plus the slow-noise wander of the three means.  D is the drift's curvature kappa (m/s^2 per
    s^2) times (t_m - t_a)(t_m - t_b) / 2: a thermal cycle that has come back by the last hold shows here at
    the offsets' own precision (the poses' own trends, ``drift_bend``, are about 5x coarser).  Per axis the
    face ``shape_holds`` picks is used; the departures are tested together (chi^2, one dof per axis, at
    ALPHA) and recorded in ``drift["shape"]``; the procedure fits the curvature on these axes
    (``procedure._referred_to_middle``).  Axes held again without such a face are listed as
    ``unchecked_axes``."""
    tau = noise.tau_any
    centres = [float(t.mean()) for t in times]
    best: dict[int, dict] = {}
    for axis, (face, (a, m, b), w) in shape_holds(centres, faces).items():
        t_a, t_m, t_b = centres[a], centres[m], centres[b]
        departure = float(readings[m] - readings[a]) - w * float(readings[b] - readings[a])
        var = noise.sd[axis] ** 2 * tau[axis] * (1 / len(samples[m]) + (1 - w) ** 2 / len(samples[a])
                                                  + w**2 / len(samples[b]))
        var += noise.wander_var * (1 + (1 - w) ** 2 + w**2)
        shape = (t_m - t_a) * (t_m - t_b) / 2.0
        best[axis] = {"face": face, "axis": face[1], "poses": [a, m, b], "times": [t_a, t_m, t_b],
                      "middle_share": w, "departure": departure, "u": float(np.sqrt(var)),
                      "z": departure / float(np.sqrt(var)),
                      "curvature": departure / shape, "curvature_u": float(np.sqrt(var)) / abs(shape)}
    revisited = sorted({r["face"][1] for r in noise.drift.get("revisits", [])})
    found = [best[k] for k in sorted(best)]
    record: dict = {"faces": found, "checked_axes": [e["axis"] for e in found],
                    "unchecked_axes": [a for a in revisited if a not in {e["axis"] for e in found}]}
    noise.drift["shape"] = record
    if not found:
        return
    chi2 = float(sum(e["z"] ** 2 for e in found))
    p = float(chi2_dist.sf(chi2, len(found)))
    record.update(chi2=chi2, dof=len(found), p_value=p)
    warning = ""
    if p < ALPHA:
        worst = max(found, key=lambda e: abs(e["z"]))
        t_a, t_m, t_b = worst["times"]
        warning = (
            f"the offset drift is not a straight line: {worst['face']} down read {worst['departure']:+.4f} m/s^2 "
            f"along {worst['axis']} at t = {t_m:.0f} s off the line through its holds at t = {t_a:.0f} and "
            f"{t_b:.0f} s ({abs(worst['z']):.1f} u; all axes chi^2 {chi2:.1f} for {len(found)}, p = {p:.1g}): "
            "a drift that comes and goes (temperature changing?). The offsets are referred to the middle of "
            "the run with the curve measured (its u included); let the sensor's temperature settle and "
            "calibrate again for the best result")
    noise.drift_test("shape", p, warning)


def _unchecked(noise: StillNoise, times, faces) -> None:
    """Axes whose faces were each held once: say that their drift was not checked, and how much could hide.

    A revisit checks the drift of its own axis only (along the other two a tilt of the two holds looks the
    same).  The offset of axis k comes from the poses of its two faces, so it is the offset at their mean
    time; the result stands for the middle of the run.  A drift rate up to 2 u of the pooled within-pose
    trend goes unseen and shifts offset k by that rate times the distance of its face pair from the middle."""
    checked = sorted({f[1] for f in faces if f is not None and faces.count(f) >= 2})
    noise.drift["checked_axes"] = checked
    if not faces or any(f is None for f in faces) or "trend" not in noise.drift:
        return
    unchecked = [k for k, axis in enumerate(AXES) if axis not in checked]
    if not unchecked:
        return
    counts = np.array([len(t) for t in times], dtype=float)
    centres = np.array([float(np.mean(t)) for t in times])
    middle = float(np.average(centres, weights=counts))
    span = float(max(t[-1] for t in times) - min(t[0] for t in times))
    unseen_rate = 2.0 * np.asarray(noise.drift["trend"]["u"])
    shift = np.zeros(3)
    for k in unchecked:
        pair = [i for i, f in enumerate(faces) if f[1] == AXES[k]]
        shift[k] = unseen_rate[k] * abs(float(np.average(centres[pair], weights=counts[pair])) - middle)
    names = ", ".join(AXES[k] for k in unchecked[:-1]) + (" and " if len(unchecked) > 1 else "") + AXES[unchecked[-1]]
    noise.drift["unchecked"] = {"axes": [AXES[k] for k in unchecked], "unseen_rate": unseen_rate.tolist(),
                                "span_s": span, "offset_shift": shift.tolist()}
    noise.warnings.append(
        f"offset drift not checked along {names}: no face of {'that axis' if len(unchecked) == 1 else 'those axes'} "
        f"was held twice, and held once a slow drift looks like the faces' tilt. A drift the within-pose trends "
        f"would miss (up to {float(unseen_rate[unchecked].max()) * span:.2g} m/s^2 over the {span:.0f} s run) "
        f"would shift the offsets by up to {float(shift.max()):.2g} m/s^2; to check, put one face of each axis "
        "down again after the six faces (the wizard asks for it)")


def drift_bend(noise: StillNoise, anchors: dict[int, tuple[float, float]], middle: float,
               measured: list[int] | tuple[int, ...] = ()) -> dict:
    """Does the drift follow the straight line the revisits fitted?  What the poses' own trends say.

    A straight-line drift moves each offset at the fitted rate r at every moment, so every pose's own trend
    (its slope over its 4-6 s, ``pose_slopes``) must read r.  Per axis k held again the pose slopes are
    regressed on time, s_i = a + kappa (t_i - t_mid): the rate at the middle a, and how fast the rate
    changes, kappa (m/s^2 per s^2: the drift's curvature, the first term beyond a line).  Tested (chi^2,
    1 dof per axis, at ALPHA): kappa against 0 (a against r is recorded as ``level_z``; a pooled trend is
    ``_trend``'s to warn).  A significant result is warned as a drift that is not a straight line.

    The allowance, whether significant or not (not a correction: the slopes are about 5x coarser than the
    offsets).  GUM type B: over the run the rate may change by up to the largest rate the revisits allow,
    |r| + 2 u(r), either way: kappa rectangular within +-2 r_max / span (first to last pose).  When the
    test rejects, the curvature the trends show replaces it if larger: normal, sd sqrt(kappa^2 + u(kappa)^2),
    u(kappa) widened by the pose slopes' scatter about their line when that exceeds their noise.  The departure from the
    straight line that such a curvature makes is kappa (t - t_a) (t - t_b) / 2, zero at the two holds t_a, t_b
    that fix the axis's rate (``anchors``); the procedure propagates it through the fit (less its average over
    the run: the offsets stand for the run's average).  On the ``measured`` axes (a face held three times far
    apart: the procedure fits the curvature there, with its u) there is no allowance.  Returns the
    record (also in ``drift["bend"]``); empty when there are too few poses or no axis held again."""
    if not anchors or len(noise.pose_centres) < 4 or not np.all(noise.pose_slope_u[:, sorted(anchors)] > 0):
        return {}   # too few poses, or an axis without noise (its slopes have no u to weigh them by)
    t = noise.pose_centres - middle
    axes = sorted(anchors)
    kappa, kappa_u, level, level_u, scatter, dof = [], [], [], [], 0.0, 0
    for k in axes:
        w = 1.0 / noise.pose_slope_u[:, k] ** 2
        x = np.column_stack([np.ones_like(t), t])
        info = x.T @ (w[:, None] * x)
        cov = np.linalg.inv(info)
        coef = cov @ (x.T @ (w * noise.pose_slopes[:, k]))
        resid = noise.pose_slopes[:, k] - x @ coef
        scatter += float(np.sum(w * resid**2))
        dof += len(t) - 2
        level.append(float(coef[0]))
        kappa.append(float(coef[1]))
        level_u.append(float(np.sqrt(cov[0, 0])))
        kappa_u.append(float(np.sqrt(cov[1, 1])))
    kappa, kappa_u = np.array(kappa), np.array(kappa_u)
    level, level_u = np.array(level), np.array(level_u)
    rate, rate_u = noise.drift_rate[axes], noise.drift_rate_u[axes]
    z_kappa = kappa / kappa_u
    z_level = (level - rate) / np.sqrt(level_u**2 + rate_u**2)
    # the test is of the curvature alone: the level against the fitted rate is recorded, but a pooled trend
    # away from the rate is the within-pose trend check's to warn (``_trend``), not twice
    chi2 = float(np.sum(z_kappa**2))
    p = float(chi2_dist.sf(chi2, len(axes)))
    widen = float(np.sqrt(max(scatter / dof, 1.0))) if dof > 0 else 1.0
    span = float(noise.pose_centres.max() - noise.pose_centres.min())
    # type B: over the run the rate may change by up to the largest rate the revisits allow (|r| + 2 u(r)),
    # either way: the curvature rectangular within +-2 r_max / span (span: first to last pose)
    largest_rate = np.abs(rate) + 2.0 * rate_u
    assumed = 2.0 * largest_rate / max(span, 1e-9) / np.sqrt(3.0)
    seen = p < ALPHA
    allowance = np.maximum(assumed, np.sqrt(kappa**2 + (widen * kappa_u) ** 2)) if seen else assumed
    allowance[[j for j, k in enumerate(axes) if k in measured]] = 0.0
    # the largest departure from the straight line at a pose, per axis, at that sd
    departure = [float(allowance[j] * np.max(np.abs((noise.pose_centres - anchors[k][0])
                                                    * (noise.pose_centres - anchors[k][1]))) / 2.0)
                 for j, k in enumerate(axes)]
    record = {"axes": [AXES[k] for k in axes], "rate_at_middle": level.tolist(), "rate_at_middle_u": level_u.tolist(),
              "level_z": z_level.tolist(), "curvature": kappa.tolist(), "curvature_u": kappa_u.tolist(),
              "chi2": chi2, "dof": len(axes),
              "p_value": p, "slope_scatter_ratio": widen,
              "allowance": {"curvature_sd": allowance.tolist(),
                            "from": "trends" if seen else "largest rate",
                            "largest_rate": largest_rate.tolist(),
                            "distribution": ("normal (the curvature the trends show, and its u)" if seen else
                                             "rectangular (GUM type B: over the run the rate changes by up to "
                                             "+-the largest rate the faces held again allow)"),
                            "anchors_s": [list(anchors[k]) for k in axes], "largest_departure": departure,
                            "measured_axes": [AXES[k] for k in axes if k in measured]}}
    noise.drift["bend"] = record
    warning = ""
    if seen:
        j = int(np.argmax(np.abs(z_kappa)))
        warning = (
            f"the offset drift is not a straight line: along {AXES[axes[j]]} its rate changes by "
            f"{kappa[j] * 60:+.2g} m/s^2 per s each minute ({abs(z_kappa[j]):.1f} u; the poses' own trends, all "
            f"axes chi^2 {chi2:.1f} for {len(axes)}, p = {p:.1g}). "
            + (f"The u allows for a drift that curves (up to {max(departure):.2g} m/s^2 off the straight line at a "
               "pose, 1 sd), but a drift that turns back between the holds can be larger: "
               if max(departure) > 0 else
               "The u holds the curve the faces held three times measured, but a drift that turns back faster "
               "can be larger: ")
            + "let the sensor settle powered (temperature steady) and calibrate again")
    noise.drift_test("bend", p, warning)
    return record
