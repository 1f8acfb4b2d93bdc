"""Absolute UTC time for every sample a device delivers: host clock anchored, device clock rate measured.

Drivers time samples on their own base (``Block.t``): a simulated device on
its device clock from 0, the I2C and firmware drivers on the host's monotonic
clock by regression.  Whatever the base, one connection's ``t`` is continuous,
so the daemon maps it to UTC per connection:

* the anchor: the first block's arrival (monotonic -> UTC through one reading
  of ``time.time() - time.monotonic()``, taken when the connection starts, so a
  later wall-clock step cannot tear a connection's timeline) is the time of
  the block's last sample;
* the rate: a running least-squares line of arrival time against the time of
  each block's last sample gives host seconds per device second (``ratio``)
  once ``min_span`` seconds are seen; later samples advance by
  ``ratio x dt`` from the previous sample, so a better estimate never makes
  the timeline jump;
* a slew: the mapped time is pulled toward the line (which follows the host
  clock) by at most ``max_slew`` (200 ppm) of each step, as NTP slews a clock,
  so weeks of drift between device and host crystal never accumulate.

The driver's ``t`` may step back when its own alignment changes (the
firmware link switching to host alignment, an I2C FIFO fit restarting): the
step is then taken as half a period, so time always increases, the slew takes
the difference back, and ``describe`` counts such steps.

A ratio further than ``max_drift`` (0.1 %) from 1 means the blocks are not
arriving in real time (a device fed as fast as it is read): the device clock
is then used alone (ratio 1, no slew) and ``alignment`` says so.

``measured_rate`` is the device's sample rate on the host clock: samples
(delivered and the known missing ones) per host second, from a second line
of arrival time against sample index.
"""

from __future__ import annotations

import time

import numpy as np

from accelrig.acquisition.timebase import RunningLine


class UtcClock:
    def __init__(self, nominal_rate: float, min_span: float = 5.0, max_drift: float = 1e-3, max_slew: float = 2e-4):
        self.nominal_rate = float(nominal_rate)
        self.min_span = min_span
        self.max_drift = max_drift
        self.max_slew = max_slew
        self.wall_offset = time.time() - time.monotonic()  # UTC seconds = monotonic + wall_offset
        self._time_line = RunningLine()    # arrival (monotonic) vs t of the block's last sample
        self._index_line = RunningLine()   # arrival (monotonic) vs index of the block's last sample
        self._index = 0                    # samples so far, known missing ones included
        self._last_t: float | None = None  # t of the last sample mapped
        self._last_utc = 0.0               # its UTC
        self.ratio = 1.0
        self.alignment = "host clock (anchored at the first block; too little data for the rate yet)"
        self.anchor_utc: float | None = None
        self.min_step = 0.5 / self.nominal_rate   # the shortest step between samples taken as real
        self.steps_back = 0                       # steps shorter than that (see map)
        self.largest_step_back = 0.0              # s, the largest amount by which a step fell short

    def map(self, t: np.ndarray, arrival: float, missing_before: int = 0) -> np.ndarray:
        """UTC seconds of samples with times ``t`` (one block or chunk), which arrived at ``arrival``
        (time.monotonic); ``missing_before``: samples the device reported lost just before them."""
        n = t.size
        if n == 0:   # an empty block carrying a gap (a stream that ended with a loss): the gap still counts
            self._index += max(missing_before, 0)
            return np.empty(0)
        arrival_utc = arrival + self.wall_offset
        self._index += max(missing_before, 0) + n
        self._index_line.add(float(self._index - 1), arrival_utc)
        self._time_line.add(float(t[-1]), arrival_utc)
        first = self._last_t is None
        if first:
            # the block left the device after its last sample was taken
            self.anchor_utc = arrival_utc - float(t[-1] - t[0])
            self._last_t, self._last_utc = float(t[0]), self.anchor_utc
        self._update_ratio()
        steps = np.diff(t, prepend=self._last_t)
        short = steps < self.min_step
        short[0] &= not first
        if short.any():
            # The driver's time base stepped back (its own alignment changed): time must still
            # increase, so such a step counts as half a period and the slew takes the rest back.
            self.steps_back += int(np.count_nonzero(short))
            self.largest_step_back = max(self.largest_step_back, float(np.max(self.min_step - steps[short])))
            steps[short] = self.min_step
            steps[0] = 0.0 if first else steps[0]
            # the line through the old time base would bias the rate: start a new one (the ratio
            # found so far stays in use until the new line spans min_span)
            self._time_line = RunningLine()
            self._time_line.add(float(t[-1]), arrival_utc)
        utc = self._last_utc + self.ratio * np.cumsum(steps)
        if self.alignment.startswith("host clock (regression") and self._time_line.span() >= self.min_span:
            # slew toward the line through the arrivals, at most max_slew of the span mapped
            slope = self._time_line.slope()
            target = self._time_line.y_at(float(t[-1]), slope)
            span = float(t[-1]) - self._last_t
            error = target - utc[-1]
            limit = self.max_slew * max(span, 0.0)
            correction = float(np.clip(error, -limit, limit))
            if correction and span > 0:
                utc += correction * (t - self._last_t) / span
        self._last_t, self._last_utc = float(t[-1]), float(utc[-1])
        return utc

    def _update_ratio(self) -> None:
        if self._time_line.span() < self.min_span:
            return
        r = self._time_line.slope()
        if r is None:
            return
        if abs(r - 1.0) > self.max_drift:
            self.ratio = 1.0
            self.alignment = (f"device clock (blocks arrive at {r:.4g} x device time: not in real time; "
                              "UTC anchored at the first block only)")
            return
        self.ratio = r
        self.alignment = "host clock (regression of arrival times on device time, slewed at most 200 ppm)"

    @property
    def measured_rate(self) -> float | None:
        """Samples per host second (delivered + known missing), or None before min_span seconds."""
        if self._index_line.span() < 1 or self._time_line.span() < self.min_span:
            return None
        slope = self._index_line.slope()
        return 1.0 / slope if slope and slope > 0 else None

    def describe(self) -> dict:
        """What a segment records about its time base."""
        return {
            "time": "UTC seconds since 1970-01-01 (POSIX), per sample",
            "alignment": self.alignment,
            "anchor_utc": self.anchor_utc,
            "host_seconds_per_device_second": self.ratio,
            "measured_rate": self.measured_rate,
            "nominal_rate": self.nominal_rate,
            "driver_steps_back": self.steps_back,
            "largest_step_back": self.largest_step_back,
        }
