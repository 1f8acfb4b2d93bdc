"""Sample times for links that send a device sample counter and a device timestamp.

The delivered rate is estimated, never assumed: a least-squares line through
(first-sample counter, device timestamp) of every frame gives the sample
period on the device's clock (firmware timestamp jitter averages out), and a
second line through (device timestamp, host receive time) gives how fast
the device clock runs against the host's.  Sample k then sits at

    t_k = t_j + ratio * period * (k - j)

on the host's monotonic clock, j the last sample timed (the first one at the
arrival of its frame, less the frame's length), pulled toward the line
through the first sample with today's estimates by at most ``MAX_SLEW`` of
each step: a better estimate, or host alignment switching on or off, never
makes the timeline jump between blocks, and it still ends on the line.  A crystal is good to far better than
``max_drift`` (500 ppm); a fitted ratio outside that says the frames are not
arriving in real time (an emulated run fed as fast as the host reads, or a
device that buffered) and the device clock is then used alone, which
``alignment`` reports.
"""

from __future__ import annotations

import numpy as np

# The most a timeline may be pulled toward a better estimate, as a fraction of the time it
# covers: consecutive samples stay within 1 % of the period apart (a sample clock's own
# tolerance), where a jump of a fraction of a period would look like a lost sample.
MAX_SLEW = 0.01


class RunningLine:
    """Running least-squares line y = a + b x (sums kept about the first point for precision)."""

    def __init__(self):
        self.n = 0
        self.x0 = self.y0 = 0.0
        self.sx = self.sy = self.sxx = self.sxy = 0.0
        self.lo = self.hi = 0.0

    def add(self, x: float, y: float) -> None:
        if self.n == 0:
            self.x0, self.y0 = x, y
        dx, dy = x - self.x0, y - self.y0
        self.n += 1
        self.sx += dx
        self.sy += dy
        self.sxx += dx * dx
        self.sxy += dx * dy
        self.lo, self.hi = min(self.lo, dx), max(self.hi, dx)

    def slope(self) -> float | None:
        den = self.n * self.sxx - self.sx * self.sx
        if self.n < 2 or den <= 0:
            return None
        return (self.n * self.sxy - self.sx * self.sy) / den

    def span(self) -> float:
        return self.hi - self.lo

    def y_at(self, x: float, slope: float | None = None) -> float:
        """The line's value at ``x`` (``slope``: one already computed, to save the work)."""
        b = self.slope() if slope is None else slope
        if b is None:
            return self.y0 + (self.sy / self.n if self.n else 0.0)
        return self.y0 + (self.sy - b * self.sx) / self.n + b * (x - self.x0)


class StreamClock:
    def __init__(self, nominal_rate: float, max_drift: float = 500e-6, min_host_span: float = 5.0):
        self.nominal_period = 1.0 / nominal_rate
        self.max_drift = max_drift
        self.min_host_span = min_host_span
        self._period_prior = self.nominal_period
        self.alignment = "device clock (too little data for host alignment yet)"
        self._reset()

    def _reset(self) -> None:
        self._counter_line = RunningLine()   # device time vs counter
        self._host_line = RunningLine()      # host time vs device time
        self._anchor_counter: int | None = None
        self._anchor_host = 0.0
        self._last_t: float | None = None
        self._last_counter: int | None = None   # the counter of the sample at _last_t (None: re-anchor)

    def restart(self) -> None:
        """The device restarted (its counter and clock went back): re-anchor at the next frame."""
        self._period_prior = self.period
        last = self._last_t
        self._reset()
        self._last_t = last

    @property
    def period(self) -> float:
        """Sample period on the device clock, s (estimated)."""
        p = self._counter_line.slope()
        return p if p is not None and p > 0 else self._period_prior

    @property
    def ratio(self) -> float:
        """Host seconds per device second (1 when host alignment is not possible)."""
        if self._host_line.span() < self.min_host_span:
            self.alignment = "device clock (too little data for host alignment yet)"
            return 1.0
        r = self._host_line.slope()
        if r is None or abs(r - 1.0) > self.max_drift:
            self.alignment = (f"device clock (host receive times run at {r:.4g} x device time: "
                              "frames are not arriving in real time)")
            return 1.0
        self.alignment = "host clock (regression of receive times on device timestamps)"
        return r

    @property
    def delivered_rate(self) -> float:
        """Samples per host second."""
        return 1.0 / (self.period * self.ratio)

    def observe(self, counter: int, n: int, device_time: float, host_time: float) -> None:
        """One frame: unwrapped counter and device time (s) of its first sample, arrival time."""
        self._counter_line.add(float(counter), device_time)
        # the frame left the device after its last sample was taken
        self._host_line.add(device_time + (n - 1) * self.period, host_time)
        if self._anchor_counter is None:
            self._anchor_counter = counter
            anchor = host_time - (n - 1) * self.period
            if self._last_t is not None and anchor <= self._last_t:
                anchor = self._last_t + self.period
            self._anchor_host = anchor

    def times(self, counter: int, n: int) -> np.ndarray:
        step = self.ratio * self.period
        k = np.arange(counter, counter + n, dtype=float)
        if self._last_counter is None:
            t = self._anchor_host + step * (k - self._anchor_counter)
        elif n:
            elapsed = k - self._last_counter
            t = self._last_t + step * elapsed
            error = self._anchor_host + step * (k[-1] - self._anchor_counter) - t[-1]
            limit = MAX_SLEW * step * elapsed[-1]
            t += min(max(error, -limit), limit) * (elapsed / elapsed[-1])
        else:
            t = np.empty(0)
        if n:
            self._last_t, self._last_counter = float(t[-1]), counter + n - 1
        return t
