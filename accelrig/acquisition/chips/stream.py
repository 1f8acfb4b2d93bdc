"""Polling a chip's FIFO into Blocks: burst reads, overflow handling, timing, resampling.

Every poll: read the overflow status (reading clears it), read FIFO_COUNT,
burst-read the whole frames with one I2C_RDWR transaction.  An overflow (the
status bit, or a count that is not whole frames: in overwrite mode the FIFO
loses frame alignment) resets the FIFO and starts a new timing segment; the
next block carries the gap, sized from the sample clock.  Sample times come
from the sample counter aligned to the host clock by regression, and the
delivered rate is estimated, then checked against what the configuration
should give, so a wrong datasheet fact shows up as an error rather than as
mis-timed data.
"""

from __future__ import annotations

import numpy as np

from accelrig.acquisition.block import Block
from accelrig.acquisition.chips.base import FRAME_BYTES, AccelChip, RatePlan
from accelrig.acquisition.chips.decimate import RationalResampler
from accelrig.acquisition.chips.timing import CounterClockFit
from accelrig.errors import DeviceError

# The internal oscillator is +-1 % (datasheets); beyond this the configuration
# is not delivering what we think (e.g. the FIFO rate in filter bypass).
RATE_TOLERANCE = 0.03
# Seconds of samples before the measured rate is trusted enough to judge it.
RATE_CHECK_AFTER = 1.0


class FifoStream:
    """Reads one configured chip's FIFO and delivers Blocks at the planned rate."""

    def __init__(self, chip: AccelChip, clock, plan: RatePlan, scale: float, poll_interval: float | None = None):
        self.chip = chip
        self.clock = clock
        self.plan = plan
        self.scale = scale
        capacity_frames = chip.spec.fifo_capacity // FRAME_BYTES
        # Poll well before the FIFO fills (about 42 ms at 2 kHz, 19 ms at 4.5 kHz).
        self.poll_interval = poll_interval or min(0.010, 0.4 * capacity_frames / plan.chip_rate)
        self.fit = CounterClockFit(plan.chip_rate)
        self.resampler = RationalResampler(plan.up, plan.down)
        self.notes: list[str] = []
        self.overflows = 0
        self.frames_read = 0
        self.max_fifo_count = 0
        self._seq = 0
        self._counter = 0               # next output sample index (includes gaps)
        self._segment_frames = 0        # frames received in the current segment
        self._last_time: float | None = None   # time of the last delivered sample
        self._pending_gap = False
        self._next_poll = 0.0
        self._started = 0.0
        self.started = False

    @property
    def delivered_rate(self) -> float:
        """Estimated delivered rate, Hz (from the sample counter against the host clock)."""
        return self.fit.rate * self.plan.up / self.plan.down

    @property
    def delivered_rate_uncertainty(self) -> float:
        return self.fit.rate_uncertainty * self.plan.up / self.plan.down

    def start(self) -> None:
        self.chip.fifo_start()
        self.started = True
        self._started = self.clock.now()
        self._restart_segment()
        self._next_poll = self.clock.now() + self.poll_interval

    def read(self, timeout: float) -> list[Block]:
        """Wait for the next poll (at most ``timeout`` s) and poll."""
        wait = self._next_poll - self.clock.now()
        if wait > timeout:
            self.clock.sleep(timeout)
            return []
        self.clock.sleep(wait)
        # A late poll is not made up for: the next one is an interval after this one.
        self._next_poll = max(self._next_poll + self.poll_interval, self.clock.now())
        return self.poll()

    def poll(self) -> list[Block]:
        chip = self.chip
        overflowed = chip.fifo_overflowed()
        count = chip.fifo_count()
        # The chip latches the count during the read transaction: take the time
        # after it, not before (before would place every sample a transfer early).
        count_time = self.clock.now()
        self.max_fifo_count = max(self.max_fifo_count, count)
        if count > chip.spec.fifo_capacity and not any("FIFO_COUNT" in n for n in self.notes):
            self.notes.append(
                f"FIFO_COUNT reached {count} bytes, more than the {chip.spec.fifo_capacity} B the datasheet "
                f"figure used here: this part has a larger FIFO (harmless; polling is sized for the smaller one)"
            )
        if overflowed or count % FRAME_BYTES:
            # Overwrite mode lost frames and frame alignment: discard, reset, mark a gap.
            self.overflows += 1
            chip.fifo_reset()
            # Frames kept arriving between the status read and the reset and may
            # have raised the flag again: that overflow is already dealt with.
            chip.fifo_overflowed()
            self._restart_segment()
            return []
        frames = count // FRAME_BYTES
        if frames == 0:
            self.fit.add(self._segment_frames, count_time)
            return []
        data = chip.fifo_read(frames * FRAME_BYTES)
        counts_in = np.frombuffer(data, dtype=">i2").reshape(frames, 3)
        first = self._segment_frames
        self._segment_frames += frames
        self.frames_read += frames
        self.fit.add(self._segment_frames, count_time)
        self._check_rate()
        if self.resampler.passthrough:
            out = counts_in.astype(np.int16)
            positions = np.arange(first, first + frames, dtype=float)
        else:
            y, positions = self.resampler.process(counts_in)
            if len(y) == 0:
                return []
            out = np.clip(np.rint(y), -32768, 32767).astype(np.int16)
        t = self.fit.times(positions)
        gap = 0
        if self._pending_gap:
            self._pending_gap = False
            if self._last_time is None:
                gap = 0
            else:
                gap = int(round((t[0] - self._last_time) * self.delivered_rate)) - 1
                gap = gap if gap >= 0 else -1   # a negative size would be nonsense: say unknown
            self._counter += max(gap, 0)
        block = Block(seq=self._seq, counter=self._counter, host_time=count_time, counts=out,
                      scale=self.scale, t=t, gap_before=gap)
        self._seq += 1
        self._counter += len(out)
        self._last_time = float(t[-1])
        return [block]

    def _restart_segment(self) -> None:
        self.fit.new_segment()
        self.resampler.reset()
        self._segment_frames = 0
        self._pending_gap = True

    def _check_rate(self) -> None:
        if self.clock.now() - self._started < RATE_CHECK_AFTER:
            return
        measured = self.fit.rate
        if abs(measured / self.plan.chip_rate - 1.0) > RATE_TOLERANCE:
            raise DeviceError(
                f"{self.chip.spec.label}: the FIFO fills at {measured:.1f} Hz, not the {self.plan.chip_rate:g} Hz "
                f"this configuration should give ({self.plan.describe()})",
                "the datasheet rate for this mode does not hold for this part; request a rate the DLPF "
                f"gives (<= {self.chip.spec.dlpf_base_rate:g} Hz)",
            )
