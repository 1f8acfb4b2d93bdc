"""Time sources shared by a chip driver and a chip emulator, and the clock alignment.

A driver never calls ``time`` directly: it asks an injected time source, so a
test can hand the same emulated clock to the driver (its host clock) and to the
register-level emulator (its sample clock) and run 60 s of "real time" in a
few seconds of CPU without sleeping.

Sample times come from the sample counter, aligned to the host clock by
regression (the chip's oscillator is only +-1 %; the delivered rate is
estimated, never assumed).
"""

from __future__ import annotations

import math
import time

import numpy as np


class HostClock:
    """The real host clock: time.monotonic and time.sleep."""

    emulated = False

    def now(self) -> float:
        return time.monotonic()

    def sleep(self, seconds: float) -> None:
        if seconds > 0:
            time.sleep(seconds)

    def spend(self, seconds: float) -> None:
        """Time a bus transfer takes.  On real hardware the transfer itself takes it."""


class EmulatedClock:
    """A clock that moves only when told to: sleeping advances it instantly.

    ``spend`` is called by an emulated bus for the duration of each transfer,
    so bus load shows up in the driver's timing as it would on hardware.
    ``wake_jitter`` (s) adds a random late wake-up to every sleep (the host
    scheduler), drawn from ``rng``; it is what makes alignment by regression
    necessary rather than decorative.
    """

    emulated = True

    def __init__(self, start: float = 0.0, wake_jitter: float = 0.0, rng: np.random.Generator | None = None):
        self._now = float(start)
        self.wake_jitter = wake_jitter
        self._rng = rng or np.random.default_rng(0)

    def now(self) -> float:
        return self._now

    def sleep(self, seconds: float) -> None:
        late = abs(self._rng.standard_normal()) * self.wake_jitter if self.wake_jitter > 0 else 0.0
        self._now += max(seconds, 0.0) + late

    def spend(self, seconds: float) -> None:
        self._now += max(seconds, 0.0)


class CounterClockFit:
    """Host time as a straight line in the sample counter, by least squares.

    At each poll the driver adds (samples received so far in this segment,
    host time at which the FIFO count was read).  The newest sample was taken
    between one sample period before that time and that time, so sample ``p``
    (0-based, counted in the segment) is placed at ``a + b (p + 0.5)``.

    A FIFO reset starts a new *segment*: one slope (the sample period, pooled
    over all segments) and one intercept per segment, so a gap of unknown size
    does not bend the line.  Running centred sums keep memory and time per poll
    constant however long the run.
    """

    def __init__(self, nominal_rate: float):
        self.nominal_period = 1.0 / nominal_rate
        self._sxx_done = 0.0   # pooled sums of finished segments
        self._sxy_done = 0.0
        self._syy_done = 0.0
        self._points_done = 0
        self._segments_done = 0
        self._n = 0
        self.new_segment()

    def new_segment(self) -> None:
        if self._n > 0:
            self._sxx_done += self._sxx
            self._sxy_done += self._sxy
            self._syy_done += self._syy
            self._points_done += self._n
            self._segments_done += 1
        self._n = 0
        self._mx = 0.0
        self._my = 0.0
        self._sxx = 0.0
        self._sxy = 0.0
        self._syy = 0.0
        self._y0 = None  # host times are stored relative to the segment's first one (precision)

    def add(self, counter_end: float, host_time: float) -> None:
        if self._y0 is None:
            self._y0 = host_time
        x, y = float(counter_end), host_time - self._y0
        self._n += 1
        dx = x - self._mx
        dy = y - self._my
        self._mx += dx / self._n
        self._my += dy / self._n
        self._sxx += dx * (x - self._mx)
        self._sxy += dx * (y - self._my)
        self._syy += dy * (y - self._my)

    @property
    def points(self) -> int:
        return self._n

    @property
    def period(self) -> float:
        """Estimated sample period, s (nominal until two polls span some samples)."""
        sxx = self._sxx_done + self._sxx
        if sxx < 1.0:
            return self.nominal_period
        return (self._sxy_done + self._sxy) / sxx

    @property
    def rate(self) -> float:
        return 1.0 / self.period

    @property
    def rate_uncertainty(self) -> float:
        """Standard uncertainty of ``rate`` (Hz) from the regression residuals; nan if too few polls."""
        sxx = self._sxx_done + self._sxx
        dof = self._points_done + self._n - (self._segments_done + 1) - 1
        if sxx < 1.0 or dof < 1:
            return math.nan
        b = self.period
        ss_res = (self._syy_done + self._syy) - b * (self._sxy_done + self._sxy)
        s2 = max(ss_res, 0.0) / dof
        sd_period = math.sqrt(s2 / sxx)
        return sd_period / b**2

    def times(self, positions: np.ndarray) -> np.ndarray:
        """Host times of samples at ``positions`` (floats, counted in the current segment)."""
        if self._y0 is None:
            raise RuntimeError("CounterClockFit.times called before any poll in the segment")
        b = self.period
        a = self._my - b * self._mx
        return self._y0 + a + b * (np.asarray(positions, dtype=float) + 0.5)
