"""Capture checks for the tilted wheel, run before any fit, and the cheap look at the
data they need (noise level, turns, speed, gravity modulation).

Each refusal is a CalibrationError whose one line tells the operator what was
wrong with the spin and what to do.  The same survey feeds the operator
events of WheelProcedure while the wheel turns.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from accelrig.errors import CalibrationError, DataError
from accelrig.estimation.stats import robust_sd
from accelrig.recording import count_scale
from accelrig.units import STANDARD_GRAVITY, saturated

MIN_TURNS = 10.0          # 20 half-turn speed samples for a 4-coefficient speed law, 16 to spare
MIN_GRAVITY_SNR = 5.0     # g sin(alpha) over the noise sd: the phase is tracked by gravity
MIN_CENTRIPETAL_SNR = 3.0  # change of r w^2 over the run, in noise sds: what ties gain to r
MIN_SPEED_CHANGE = 0.02   # relative change of w^2: with a constant speed, r w^2 is an offset
MAX_GAP_IN_HALF_TURN = 0.25  # a gap this long (share of the half turn) could hide two crossings
MAX_TIME_JITTER = 0.25    # timestamp scatter as a fraction of the sample period
DETREND_DEGREE = 6        # r w(t)^2 is a sixth-degree polynomial under the cubic law
# A wheel at rest: over REST_WINDOW_S windows the signal scatters by less than REST_SCATTER times the
# noise sd (a turning wheel swings gravity through every axis).  A rest at the end longer than
# MIN_REST_S (and MIN_REST_SHARE of the run) is a stop the speed law (eq. 2, a cubic) cannot follow.
REST_WINDOW_S = 1.0
REST_SCATTER = 3.0
MIN_REST_S = 2.0
MIN_REST_SHARE = 0.02
SURVEY_CHUNK = 65536      # samples the survey reads at a time
NOISE_INSTANTS = 1 << 18  # the noise look uses at most this many second differences, spread over the run


@dataclass
class WheelSurvey:
    """What a quick look at a wheel recording shows (no model fit)."""

    n_samples: int
    duration: float
    period: float                 # median sample period, s
    noise_sd: float               # per-sample white noise, m/s^2 (second differences)
    axis: np.ndarray              # unit vector, sensor frame, of the least-varying direction (the wheel axis)
    turns: float                  # |net wheel angle| / 2 pi
    gravity_amplitude: float      # amplitude of the rotating gravity component, m/s^2
    speed_start: float            # |w| over the first tenth of the run, rad/s
    speed_end: float              # |w| over the last tenth, rad/s
    gaps: int = 0                 # number of gaps in the timestamps
    missing: int = 0              # samples missing in those gaps
    jitter: float = 0.0           # robust sd of the sample period, s
    saturated: dict = field(default_factory=dict)  # axis name -> count
    angle: np.ndarray | None = field(default=None, repr=False)  # unwrapped wheel angle per sample, rad

    @property
    def mean_speed(self) -> float:
        return 2 * np.pi * self.turns / self.duration if self.duration > 0 else 0.0

    def centripetal_change(self, radius: float) -> float:
        return radius * abs(self.speed_start**2 - self.speed_end**2)


def noise_sd(acc: np.ndarray) -> float:
    """White-noise sd per sample from second differences (a slow signal cancels; var(d2) = 6 sigma^2).

    Median absolute deviation, so a few jumps do not count as noise.  A record longer than
    NOISE_INSTANTS is looked at every k-th instant, evenly over the run: the sd is then known to
    0.2 % already, and the look costs no (n, 3) array of differences.
    """
    n = acc.shape[0]
    if n < 5:
        return 0.0
    stride = max(1, -(-(n - 2) // NOISE_INSTANTS))
    if stride == 1:
        d2 = np.diff(acc, n=2, axis=0)
    else:
        i = np.arange(0, n - 2, stride)
        d2 = acc[i] - 2.0 * acc[i + 1] + acc[i + 2]
    mad = robust_sd(d2, axis=0)
    return float(np.sqrt(np.mean(mad**2) / 6.0))


def timestamp_figures(t: np.ndarray) -> tuple[float, int, int, float]:
    """(median period, number of gaps, samples missing in them, robust sd of the period)."""
    dt = np.diff(t)
    period = float(np.median(dt))
    gap = dt > 1.5 * period
    missing = int(np.sum(np.rint(dt[gap] / period) - 1))
    regular = dt[~gap]
    jitter = float(robust_sd(regular, center=period)) if regular.size else 0.0
    return period, int(np.count_nonzero(gap)), missing, jitter


def saturation(acc: np.ndarray, meta: dict) -> dict:
    """Saturated samples per axis (units.saturated) when the metadata give the count scale;
    otherwise looks for a flat top (the extreme value held by several samples)."""
    out = {}
    scale = count_scale(meta)
    for k, name in enumerate("xyz"):
        col = acc[:, k]
        if scale is not None:
            count = int(np.count_nonzero(saturated(col, scale)))
        else:
            count = 0
            for extreme in (col.max(), col.min()):
                held = int(np.count_nonzero(col == extreme))
                if held >= 5:
                    count += held
        if count:
            out[name] = count
    return out


def survey(t: np.ndarray, acc: np.ndarray, meta: dict | None = None, g: float = STANDARD_GRAVITY,
           keep_angle: bool = True) -> WheelSurvey:
    """The quick look: noise, wheel axis, turns, speeds, gravity modulation, timestamps, saturation.

    The record is read chunk by chunk (SURVEY_CHUNK samples): beyond the input, the look holds
    the wheel angle per sample only when ``keep_angle`` (the live speed trace draws it)."""
    t = np.asarray(t, dtype=float)
    acc = np.asarray(acc, dtype=float)
    n = t.size
    if n < 50:
        raise DataError(f"the recording holds {n} samples; a wheel calibration needs a run of many turns")
    period, gaps, missing, jitter = timestamp_figures(t)
    sigma = noise_sd(acc)
    mean = acc.mean(axis=0)
    scatter = np.zeros((3, 3))
    for part in _survey_chunks(n):
        centred = acc[part] - mean
        scatter += centred.T @ centred
    _, vecs = np.linalg.eigh(scatter)
    axis = vecs[:, 0]                       # least variance: the wheel axis seen by the sensor (step A)
    span = max(t[-1] - t[0], 1e-9)

    def tau(part: slice) -> np.ndarray:
        return (t[part] - t[0]) / span * 2 - 1

    def plane(part: slice) -> np.ndarray:   # gravity turns in this plane
        return (acc[part] - mean) @ vecs[:, 1:]

    # Gravity amplitude: remove the centripetal drift closely (degree 6: r w^2 under the cubic law).
    steep = _legendre_fit(tau, plane, n, DETREND_DEGREE)
    total, total_sq = np.zeros(2), np.zeros(2)
    for part in _survey_chunks(n):
        rest = plane(part) - np.polynomial.legendre.legvander(tau(part), DETREND_DEGREE) @ steep
        total += rest.sum(axis=0)
        total_sq += np.einsum("nk,nk->k", rest, rest)
    variance = total_sq / n - (total / n) ** 2
    amplitude = float(np.sqrt(max(np.sum(variance) - 2 * sigma**2, 0.0)))
    # Turns: the angle of the gravity vector in the plane.  Only the circle's centre has to stay
    # inside it, so a gentle detrend (degree 2) does, and it keeps the few slow turns of a weak
    # spin; a 0.1 s moving average keeps noise from adding spurious wraps.
    width = max(1, int(round(0.1 / period)))
    kernel = np.ones(width) / width
    gentle = _legendre_fit(tau, plane, n, 2)
    angle = np.empty(n) if keep_angle else None
    tenth = max(n // 10, 2)
    head, tail = _SlopeSums(0, tenth), _SlopeSums(n - tenth, n)
    first = last = 0.0
    for part in _survey_chunks(n):
        # the moving average of this chunk sees ``width`` samples beyond each of its ends (zeros beyond the
        # record's, as np.convolve's "same" mode): the same values as one pass over the whole record
        lo, hi = max(part.start - width, 0), min(part.stop + width, n)
        wide = slice(lo, hi)
        flat = plane(wide) - np.polynomial.legendre.legvander(tau(wide), 2) @ gentle
        smooth = [np.convolve(flat[:, k], kernel, mode="same")[part.start - lo:part.stop - lo] for k in range(2)]
        raw = np.arctan2(smooth[1], smooth[0])
        # unwrapped as one series: the chunk continues from the last unwrapped angle of the one before
        piece = np.unwrap(np.concatenate([[last], raw]))[1:] if part.start else np.unwrap(raw)
        if part.start == 0:
            first = float(piece[0])
        last = float(piece[-1])
        if angle is not None:
            angle[part] = piece
        head.add(part, t, piece)
        tail.add(part, t, piece)
    duration = float(t[-1] - t[0])
    turns = float(abs(last - first) / (2 * np.pi))
    return WheelSurvey(
        n_samples=n, duration=duration, period=period, noise_sd=sigma, axis=axis, turns=turns,
        gravity_amplitude=amplitude, speed_start=abs(head.slope()), speed_end=abs(tail.slope()),
        gaps=gaps, missing=missing, jitter=jitter, saturated=saturation(acc, meta or {}), angle=angle,
    )


def _survey_chunks(n: int, size: int | None = None):
    size = size or SURVEY_CHUNK
    for lo in range(0, n, size):
        yield slice(lo, min(lo + size, n))


def _legendre_fit(tau, y, n: int, degree: int) -> np.ndarray:
    """Least-squares Legendre coefficients (degree + 1, k) of y(part) in tau(part), normal equations
    summed chunk by chunk (Legendre columns on [-1, 1] keep them well conditioned)."""
    normal = np.zeros((degree + 1, degree + 1))
    rhs = None
    for part in _survey_chunks(n):
        basis = np.polynomial.legendre.legvander(tau(part), degree)
        normal += basis.T @ basis
        rhs = basis.T @ y(part) if rhs is None else rhs + basis.T @ y(part)
    return np.linalg.lstsq(normal, rhs, rcond=None)[0]


class _SlopeSums:
    """Least-squares slope of y over t for the samples lo .. hi - 1, summed as chunks pass by (each sum
    taken about the first sample of the range, which keeps the sums free of cancellation)."""

    def __init__(self, lo: int, hi: int):
        self.lo, self.hi = lo, hi
        self.origin: tuple[float, float] | None = None
        self.sums = np.zeros(5)            # count, sum x, sum y, sum x^2, sum x y

    def add(self, part: slice, t: np.ndarray, y: np.ndarray) -> None:
        lo, hi = max(self.lo, part.start), min(self.hi, part.stop)
        if hi <= lo:
            return
        x, yy = t[lo:hi], y[lo - part.start:hi - part.start]
        if self.origin is None:
            self.origin = (float(x[0]), float(yy[0]))
        x, yy = x - self.origin[0], yy - self.origin[1]
        self.sums += [x.size, x.sum(), yy.sum(), x @ x, x @ yy]

    def slope(self) -> float:
        count, sx, sy, sxx, sxy = self.sums
        denom = sxx - sx * sx / count if count else 0.0
        return float((sxy - sx * sy / count) / denom) if denom > 0 else 0.0


def stopped_at(t: np.ndarray, acc: np.ndarray, noise: float, period: float) -> float | None:
    """Time from which the wheel stood still to the end of the recording, or None when it
    kept turning (or rested only briefly).  Looks at windows from the end backwards."""
    width = max(int(round(REST_WINDOW_S / period)), 5)
    n = t.size
    limit = REST_SCATTER * max(noise, 1e-12)
    stop = None
    moved = False
    for end in range(n, width - 1, -width):
        window = acc[end - width:end]
        if np.max(np.std(window, axis=0)) > limit:
            moved = True
            break
        stop = float(t[end - width])
    if stop is None or not moved:   # never seen turning: the capture checks say why (tilt, spin)
        return None
    rest = float(t[-1]) - stop
    if rest < max(MIN_REST_S, MIN_REST_SHARE * (float(t[-1]) - float(t[0]))):
        return None
    return stop


def rested_until(t: np.ndarray, acc: np.ndarray, noise: float, period: float) -> float | None:
    """Time until which the wheel stood still from the recording's first sample (the rest before the push the
    wizard asks for), or None when the record starts turning or rests less than REST_WINDOW_S.  The mirror of
    ``stopped_at``, windows looked at from the start; the last still window before the motion is left out too,
    since a hand's push starts gently and may move the wheel a little within it."""
    width = max(int(round(REST_WINDOW_S / period)), 5)
    limit = REST_SCATTER * max(noise, 1e-12)
    still = 0
    for lo in range(0, t.size - width + 1, width):
        if np.max(np.std(acc[lo:lo + width], axis=0)) > limit:
            break
        still += 1
    else:
        return None          # never seen turning: not a rest before a spin
    if still < 2:
        return None
    return float(t[(still - 1) * width])


# The free coast's start.  Over REST_WINDOW_S windows the points in the wheel plane lie on the circle gravity
# draws, whose centre is the centripetal term r w^2 (plus the offsets): it moves only one way while the wheel
# coasts (towards the centre of the slowest turns), and away from it while a hand drives the wheel.  A window
# whose points spread across their best line by less than REST_SCATTER noise sds, or whose arc spans less
# than MIN_COAST_ARC, or whose circle's radius is off the run's by more than
# CIRCLE_RADIUS_TOL, shows no usable circle (a wheel at rest or barely turning).  The coast starts after the
# centre's highest point, or after a later rise by more than PUSH_RISE of gravity's circle within PUSH_WINDOWS
# windows (a second stroke): a slow noise or a drift moves it by some hundredths of that.
MIN_COAST_ARC = np.pi / 2
CIRCLE_RADIUS_TOL = 0.3
PUSH_RISE = 0.05
PUSH_WINDOWS = 2          # ... within this many windows
MAX_MERGE = 8             # windows a circle is fitted over, at most (a full turn of a slow wheel)
COAST_BLOCK = 256         # windows looked at together


def coasting_from(t: np.ndarray, acc: np.ndarray, noise: float, period: float) -> float | None:
    """Time from which the wheel coasts freely to the end of the recording (or to a stop), or None when it
    coasts from the first sample.  Before it the wheel rested or a hand drove it (a push, or several): the
    centre of gravity's circle, r w^2 along the radius, last rose there (see PUSH_RISE)."""
    width = max(int(round(REST_WINDOW_S / period)), 5)
    count = t.size // width
    if count < 3:
        return None
    mean = acc.mean(axis=0)
    scatter = np.zeros((3, 3))
    for part in _survey_chunks(t.size):
        centred = acc[part] - mean
        scatter += centred.T @ centred
    plane = np.linalg.eigh(scatter)[1][:, 1:]        # the wheel plane: all but the least-varying direction
    limit = REST_SCATTER * max(noise, 1e-12)
    arc = np.zeros(count)
    moving = np.zeros(count, dtype=bool)
    normals = np.zeros((count, 3, 3))
    rhs = np.zeros((count, 3))
    for lo in range(0, count, COAST_BLOCK):
        hi = min(lo + COAST_BLOCK, count)
        p = (acc[lo * width:hi * width].reshape(hi - lo, width, 3) - mean) @ plane
        middle = p.mean(axis=1, keepdims=True)
        x = p - middle
        # an arc, not a point (a wheel at rest) nor a straight stroke (a wheel barely turning, whose noise alone
        # would bend a circle through it): the points spread across their best line by more than the noise
        cov = np.einsum("wni,wnj->wij", x, x) / width
        across = 0.5 * (cov[:, 0, 0] + cov[:, 1, 1]) - np.hypot(0.5 * (cov[:, 0, 0] - cov[:, 1, 1]), cov[:, 0, 1])
        moving[lo:hi] = across > limit**2
        # Kasa's circle: |p|^2 = 2 c.p + k, least squares; its normal equations add up over windows
        design = np.concatenate([2 * p, np.ones(p.shape[:2] + (1,))], axis=2)
        normals[lo:hi] = np.einsum("wni,wnj->wij", design, design)
        rhs[lo:hi] = np.einsum("wni,wn->wi", design, np.einsum("wnk,wnk->wn", p, p))
        ok = moving[lo:hi]
        if np.any(ok):   # the arc one window spans, seen from its own circle's centre
            c = np.linalg.solve(normals[lo:hi][ok], rhs[lo:hi][ok][..., None])[:, :2, 0]
            ang = np.unwrap(np.arctan2(p[ok, :, 1] - c[:, None, 1], p[ok, :, 0] - c[:, None, 0]), axis=1)
            arc[lo:hi][ok] = np.ptp(ang, axis=1)
    # each window's circle from as many windows as make a full turn (at most MAX_MERGE): a full turn of the
    # ellipse a sensor's unequal gains draw has the ellipse's centre, a part of it does not
    merge = np.minimum(np.ceil(2 * np.pi / np.maximum(arc, 1e-9)), MAX_MERGE).astype(int)
    merge = np.minimum(merge, count - np.arange(count))
    stack_n = np.concatenate([np.zeros((1, 3, 3)), np.cumsum(normals, axis=0)])
    stack_r = np.concatenate([np.zeros((1, 3)), np.cumsum(rhs, axis=0)])
    stack_m = np.concatenate([[0], np.cumsum(moving)])
    stack_a = np.concatenate([[0.0], np.cumsum(arc)])
    ends = np.arange(count) + merge
    usable = moving & (stack_m[ends] - stack_m[:-1] == merge) & (stack_a[ends] - stack_a[:-1] >= MIN_COAST_ARC)
    centre = np.full((count, 2), np.nan)
    radius = np.full(count, np.nan)
    if np.any(usable):
        k = np.flatnonzero(usable)
        sol = np.linalg.solve(stack_n[ends[k]] - stack_n[k], (stack_r[ends[k]] - stack_r[k])[..., None])[..., 0]
        r2 = sol[:, 2] + np.einsum("wk,wk->w", sol[:, :2], sol[:, :2])
        good = r2 > 0
        centre[k[good]] = sol[good, :2]
        radius[k[good]] = np.sqrt(r2[good])
    seen = np.isfinite(radius)
    if np.count_nonzero(seen) < 3:
        return None
    typical = float(np.median(radius[seen]))
    seen &= np.abs(radius - typical) <= CIRCLE_RADIUS_TOL * typical
    index = np.flatnonzero(seen)
    if index.size < 3:
        return None
    # how far above the last turns' centre: r (w^2 - w_last^2) along the radius, and falling while coasting.
    # Signed, along the way the centre moved from the fastest turns: a speed law that dips below the last
    # turns' speed before it ends (paper 002's Table I cubic does, at about 65 s) takes the centre past the
    # last one and back, and a distance would read that return as a push
    offset = centre[index] - centre[index[-1]]
    far = offset[int(np.argmax(np.einsum("ij,ij->i", offset, offset)))]
    height = offset @ (far / max(float(np.linalg.norm(far)), 1e-12))
    rise = PUSH_RISE * typical
    # the turns each window leaves after it: a coast must follow a push, with the MIN_TURNS a fit needs
    turns_after = np.cumsum(arc[::-1])[::-1] / (2 * np.pi)
    last = int(np.argmax(height))
    for k in range(last + 1, index.size):
        # a later stroke that did not reach the first one's speed: a fast rise (a hand's push takes seconds,
        # while a slow cubic like the paper's Table I law may turn up by a few tenths of a m/s^2 over a minute).
        # Not in the record's last turns: there the Table I cubic, speeding up again, rises as fast as a late
        # stroke would (0.33 m/s^2 over two windows against 0.34 on draw 60, whose last window read as a push and
        # left a coast of one sample), and a stroke there would leave no coast to fit anyway
        order = np.arange(index.size)
        earlier = height[(index >= index[k] - PUSH_WINDOWS) & (order >= last) & (order < k)]
        if earlier.size and height[k] > earlier.min() + rise and turns_after[index[k]] >= MIN_TURNS:
            last = k
    if index[last] == 0:
        return None
    # the push ends within the window where the centre stopped rising (its mean speed is the highest): the coast
    # from half a window after it
    end = min((index[last] + merge[index[last]]) * width + width // 2, t.size - 1)
    return float(t[end])


def turn_speeds(t: np.ndarray, angle: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """|w| over each full turn of the survey's angle, one value every half turn:
    (midpoint times, speeds rad/s).  A full turn, not a half, because the angle of
    gravity seen from a slightly wrong circle centre runs fast on one half turn and
    slow on the other; over a whole turn that cancels."""
    swept = np.abs(angle - angle[0])
    # the swept angle is monotone up to noise; the running maximum makes it strictly usable for interp
    swept = np.maximum.accumulate(swept)
    marks = np.arange(np.pi, swept[-1], np.pi)
    if marks.size < 3:
        return np.zeros(0), np.zeros(0)
    crossings = np.interp(marks, swept, t)
    span = crossings[2:] - crossings[:-2]
    return 0.5 * (crossings[2:] + crossings[:-2]), 2 * np.pi / span


def check_capture(s: WheelSurvey, radius: float | None, g: float = STANDARD_GRAVITY) -> list[str]:
    """Refuse a recording the wheel model cannot calibrate from; return warnings for the rest.

    Order: what the operator must fix first comes first (timestamps, clipping,
    no tilt, too few turns, too slow).
    """
    warnings = []
    if s.jitter > MAX_TIME_JITTER * s.period:
        raise CalibrationError(
            f"the timestamps are irregular: the sample period scatters by {s.jitter * 1e3:.2f} ms "
            f"around {s.period * 1e3:.2f} ms",
            "record with device timestamps (sample counter), not host receive times",
        )
    if s.gaps:
        warnings.append(f"{s.gaps} gap(s) in the timestamps ({s.missing} samples missing); "
                        "the fit uses the timestamps, so the gaps only cost data")
    if s.saturated:
        which = ", ".join(f"{count} on {axis}" for axis, count in s.saturated.items())
        raise CalibrationError(
            f"samples at full scale ({which}): the wheel spun too fast for the sensor range",
            "spin the wheel slower or record with a larger range (e.g. range 4 g)",
        )
    if s.gravity_amplitude < MIN_GRAVITY_SNR * s.noise_sd:
        tilt_deg = np.rad2deg(np.arcsin(min(s.gravity_amplitude / g, 1.0)))
        need = np.rad2deg(np.arcsin(min(MIN_GRAVITY_SNR * s.noise_sd / g, 1.0)))
        raise CalibrationError(
            f"the tilt is too small for gravity to modulate the signal: gravity swings by "
            f"{s.gravity_amplitude:.3f} m/s^2 per turn (tilt about {tilt_deg:.1f} deg), "
            f"the noise sd is {s.noise_sd:.3f} m/s^2",
            f"tilt the wheel axis at least {max(need, 1.0):.0f} deg from the vertical (45 deg is best) and spin again",
        )
    if s.turns < MIN_TURNS:
        raise CalibrationError(
            f"too few turns: the wheel turned {s.turns:.1f} times in {s.duration:.1f} s, "
            f"the calibration needs at least {MIN_TURNS:.0f}",
            "spin the wheel harder and record until it has made enough turns",
        )
    mean_sq = 0.5 * (s.speed_start**2 + s.speed_end**2)
    change = abs(s.speed_start**2 - s.speed_end**2)
    if radius is not None:
        seen = s.centripetal_change(radius)
        if seen < MIN_CENTRIPETAL_SNR * s.noise_sd:
            raise CalibrationError(
                f"the rotation is too slow for the centripetal term to be seen: r w^2 changed by "
                f"{seen:.3f} m/s^2 over the run (speed {s.speed_start:.2f} -> {s.speed_end:.2f} rad/s), "
                f"at least {MIN_CENTRIPETAL_SNR:g} x the noise sd ({MIN_CENTRIPETAL_SNR * s.noise_sd:.3f} m/s^2) is needed",
                "spin the wheel faster and record while it slows down",
            )
    if mean_sq > 0 and change / mean_sq < MIN_SPEED_CHANGE:
        raise CalibrationError(
            f"the wheel speed hardly changed ({s.speed_start:.2f} -> {s.speed_end:.2f} rad/s): "
            "at a constant speed the centripetal term cannot be told from the offset",
            "spin the wheel by hand and let it coast down while recording",
        )
    return warnings


# ----------------------------------------------------------------------- half turns


def zero_crossings(t: np.ndarray, y: np.ndarray, smooth: int, hysteresis: float) -> tuple[np.ndarray, np.ndarray]:
    """Times and directions (+1 up, -1 down) of the zero crossings of a noisy oscillation.

    ``y`` is smoothed by a centred moving average of ``smooth`` samples; a new
    crossing counts only once the signal has gone beyond +-``hysteresis``,
    so noise near zero cannot split one crossing into several.
    """
    if smooth > 1:
        kernel = np.ones(smooth) / smooth
        y = np.convolve(y, kernel, mode="same")
    state = np.where(y > hysteresis, 1, np.where(y < -hysteresis, -1, 0))
    idx = np.flatnonzero(state)
    if idx.size < 2:
        return np.empty(0), np.empty(0, dtype=int)
    filled = state[idx]
    change = np.flatnonzero(np.diff(filled) != 0)
    times, dirs = [], []
    for c in change:
        lo, hi = idx[c], idx[c + 1]      # last sample beyond the old side, first beyond the new
        seg = y[lo:hi + 1]
        up = filled[c + 1] > 0
        crossing = np.flatnonzero((seg[:-1] <= 0) & (seg[1:] > 0) if up else (seg[:-1] >= 0) & (seg[1:] < 0))
        if crossing.size == 0:
            continue
        i = lo + crossing[-1]
        frac = y[i] / (y[i] - y[i + 1])
        times.append(t[i] + frac * (t[i + 1] - t[i]))
        dirs.append(1 if up else -1)
    return np.asarray(times), np.asarray(dirs, dtype=int)


def half_turn_speeds(t: np.ndarray, y: np.ndarray, mean_speed: float, period: float,
                     gap_times: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The paper's Fig. 3 samples: the mean speed of each half turn, pi / (time between crossings).

    ``y`` is the zero-mean component A sin(theta(t)).  Returns (midpoint times,
    speeds in rad/s, crossing times, crossing directions).  A half turn is timed across
    gaps in the timestamps (the crossings keep their own times, so lost samples only cost
    data); it is dropped only when a gap in it lasts more than MAX_GAP_IN_HALF_TURN of it,
    long enough to hide a pair of crossings.  ``gap_times`` (the first sample after each gap)
    is accepted for callers that already know them; the gaps are measured from ``t``.
    """
    turn_time = 2 * np.pi / max(mean_speed, 1e-6)
    smooth = int(max(1, min(turn_time / 20 / period, 200)))
    amplitude = np.sqrt(2.0) * np.std(y)
    times, dirs = zero_crossings(t, y, smooth, 0.3 * amplitude)
    if times.size < 2:
        return np.empty(0), np.empty(0), times, dirs
    start, stop = times[:-1], times[1:]
    keep = dirs[1:] != dirs[:-1]
    dt = np.diff(t)
    gap = np.flatnonzero(dt > 1.5 * period)
    if gap.size:
        gap_end, gap_length = t[gap + 1], dt[gap]
        # the longest gap ending inside each half turn
        lo = np.searchsorted(gap_end, start, side="right")
        hi = np.searchsorted(gap_end, stop, side="left")
        longest = np.zeros(start.size)
        for i in np.flatnonzero(hi > lo):
            longest[i] = gap_length[lo[i]:hi[i]].max()
        keep &= longest <= MAX_GAP_IN_HALF_TURN * (stop - start)
    mid = 0.5 * (start + stop)[keep]
    speed = np.pi / (stop - start)[keep]
    return mid, speed, times, dirs
