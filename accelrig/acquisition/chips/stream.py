"""Polling a chip's FIFO into Blocks: burst reads, overflow handling, timing, resampling.

Every poll: read the overflow status (reading clears it), read FIFO_COUNT,
burst-read the whole frames with one I2C_RDWR transaction.  A read polls for
``DELIVER_EVERY`` s and delivers one Block per run of samples with no gap in it
(the polls' samples joined), so what lies downstream works per 50 ms, not per
poll.  A poll does only its bus transfers and the bookkeeping that needs the
moment of its count: the frames are resampled and timed once per run, at the
end of the read (or before a FIFO reset), which costs per call far more than
per sample and gives the same samples however the stream is cut.  So each
poll holds the interpreter for a short while, and the polls of many devices
in one process come when they are due.  An overflow (the
status bit, or a count that is not whole frames: in overwrite mode the FIFO
loses frame alignment) resets the FIFO; the next block carries the gap.

Timing.  The sample counter is aligned to the host clock by regression
(``CounterClockFit``: one slope, the sample period, pooled over the whole
stream; one intercept per stretch between FIFO resets), which measures the
delivered rate; it is checked against what the configuration should give, so
a wrong datasheet fact shows up as an error rather than as mis-timed data.
Sample times, though, are not read off the regression block by block: a line
through a few polls moves by a fraction of a period with every poll added,
and those moves would be steps at block joins that no gap explains.  Instead
each sample is one measured period after the one before (continuous by
construction), pulled toward where the recent polls place the sample clock
(``_sample_time``) by at most ``MAX_SLEW`` of the time elapsed, once there
are ``SLEW_AFTER_POLLS`` polls to go by.

A FIFO reset does not stop the chip's sample clock, so the first sample
after it lies on the same grid as the samples before, a whole number of
measured periods after the last one: that number is found from when the
reset happened (the first sample is taken within one period after it) and
from the first poll (its newest sample was taken before the count was read),
and the gap is that number less one, its duration whole periods.
"""

from __future__ import annotations

import numpy as np

from accelrig.acquisition.block import Block
from accelrig.acquisition.chips.base import FRAME_BYTES, AccelChip, RatePlan
from accelrig.acquisition.chips.decimate import RationalResampler
from accelrig.acquisition.chips.timing import CounterClockFit
from accelrig.acquisition.timebase import MAX_SLEW
from accelrig.errors import DeviceError

# The internal oscillator is +-1 % (datasheets); beyond this the configuration
# is not delivering what we think (e.g. the FIFO rate in filter bypass).
RATE_TOLERANCE = 0.03
# Seconds of samples before the measured rate is trusted enough to judge it.
RATE_CHECK_AFTER = 1.0
# Sample times follow the polls only once this many place the sample clock (fewer
# would move it with the host's scheduling jitter)...
SLEW_AFTER_POLLS = 10
# ...and by at most MAX_SLEW of the time elapsed (timebase.py says why).
# Polls whose counts place the sample clock (see FifoStream._sample_time): about a second
# at the default poll interval (the envelope tightens as period / polls; a rate error of
# 1e-5, what the regression reaches within seconds, moves it by 1 % of a period over 1000).
BOUND_POLLS = 96
# Seconds of samples a read delivers (several polls), as sim:// does in realtime pace.
DELIVER_EVERY = 0.05


class FifoStream:
    """Reads one configured chip's FIFO and delivers Blocks at the planned rate."""

    def __init__(self, chip: AccelChip, clock, plan: RatePlan, scale: float, poll_interval: float | None = None):
        self.chip = chip
        self.clock = clock
        self.plan = plan
        self.scale = scale
        capacity_frames = chip.spec.fifo_capacity // FRAME_BYTES
        # Poll when the FIFO is a third full (every 7.1 ms at 4 kHz, 6.3 ms at 4.5 kHz): a poll
        # may then come two thirds of a fill late (a loaded host) before frames are lost.  At
        # least every 10 ms at low rates, as before: the gap after an overflow is placed from
        # the first poll after the reset, and is exact in the tests at that interval.
        self.poll_interval = poll_interval or min(0.010, capacity_frames / plan.chip_rate / 3)
        self.fit = CounterClockFit(plan.chip_rate)
        self.resampler = RationalResampler(plan.up, plan.down)
        self.notes: list[str] = []
        self.overflows = 0
        self.frames_read = 0
        self.max_fifo_count = 0
        self._seq = 0
        self._counter = 0               # next output sample index (includes gaps)
        self._segment_frames = 0        # frames received since the last FIFO reset
        self._last_time: float | None = None   # time of the last delivered sample
        self._pending_gap = False
        # The timeline: a point on it (input position since the last reset, time).
        self._ref_pos = 0.0
        self._ref_time = 0.0
        # The regression's counter at the first frame since the last reset (None until placed).
        self._fit_offset: int | None = None
        self._grid_time: float | None = None   # time of the last frame before the last reset
        self._grid_index = 0                   # and its regression counter
        self._reset_window = (0.0, 0.0)        # host time before the last reset, and after its restarting write
        self._grid_unknown = False             # the first frames after the reset could not be placed on it
        # the last BOUND_POLLS polls (see _sample_time), a ring: regression counter of the newest
        # frame, host time after the count read; _bound_count of them are filled
        self._bound_k = np.zeros(BOUND_POLLS)
        self._bound_end = np.zeros(BOUND_POLLS)
        self._bound_count = 0
        self._run: list[bytes] = []    # FIFO bytes read since the last _finish_run (whole frames)
        self._run_first = 0            # their first frame's index since the last reset
        self._run_time = 0.0           # host time of the count of the newest poll among them
        self._next_poll = 0.0
        self._error: Exception | None = None   # raised by the next read (see read)
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
        before = self.clock.now()
        self.chip.fifo_start()
        self.started = True
        self._started = self.clock.now()
        self._restart_segment(before, self._started)
        self._next_poll = self.clock.now() + self.poll_interval

    def read(self, timeout: float) -> list[Block]:
        """Poll at the poll interval for about ``DELIVER_EVERY`` s (at most ``timeout`` s) and
        deliver what those polls read: one Block per run of samples with no gap in it.

        A block per poll would cost everything downstream (ring buffer, time mapping,
        writer) a hundred times a second per device for a dozen samples each.  An error
        in a later poll is raised by the next read, after the samples already read.
        """
        if self._error is not None:
            error, self._error = self._error, None
            raise error
        clock = self.clock
        end = clock.now() + timeout
        polls = max(1, round(DELIVER_EVERY / self.poll_interval))
        parts: list[tuple] = []
        for _ in range(polls):
            now = clock.now()
            wait = self._next_poll - now
            if wait > end - now:
                if not self._run and not parts:
                    clock.sleep(end - now)
                break
            clock.sleep(wait)
            # A late poll is not made up for: the next one is an interval after this one.
            self._next_poll = max(self._next_poll + self.poll_interval, clock.now())
            try:
                self._poll(parts)
            except Exception as exc:
                self._finish_run(parts)
                if not parts:
                    raise
                self._error = exc
                break
        self._finish_run(parts)
        return self._blocks(parts)

    def poll(self) -> list[Block]:
        """Poll the FIFO once: at most one Block (after a FIFO reset, none)."""
        parts: list[tuple] = []
        self._poll(parts)
        self._finish_run(parts)
        return self._blocks(parts)

    def _blocks(self, parts: list[tuple]) -> list[Block]:
        """Blocks from polls' (counter, counts, times, gap, host time): one per run with no gap."""
        blocks = []
        run: list[tuple] = []
        for part in [*parts, None]:
            if run and (part is None or part[3] != 0):
                counts = run[0][1] if len(run) == 1 else np.concatenate([p[1] for p in run])
                t = run[0][2] if len(run) == 1 else np.concatenate([p[2] for p in run])
                blocks.append(Block(seq=self._seq, counter=run[0][0], host_time=run[-1][4], counts=counts,
                                    scale=self.scale, t=t, gap_before=run[0][3]))
                self._seq += 1
                run = []
            if part is not None:
                run.append(part)
        return blocks

    def _poll(self, parts: list[tuple]) -> None:
        """One poll: the whole frames in the FIFO join the run being read (see ``_finish_run``).

        Only the bus transfers and the bookkeeping that needs the moment of the
        count happen here, so a poll holds the interpreter briefly (eight devices
        share it); resampling and sample times are done once per run.  An overflow
        finishes the run into ``parts`` before the FIFO is reset.
        """
        chip = self.chip
        clock = self.clock
        overflowed = chip.fifo_overflowed()
        count_start = clock.now()
        count = chip.fifo_count()
        # The chip latches the count during the read transaction: take the time
        # after it, not before (before would place every sample a transfer early).
        count_time = clock.now()
        if count > self.max_fifo_count:
            self.max_fifo_count = count
            if count > chip.spec.fifo_capacity and not any("FIFO_COUNT" in n for n in self.notes):
                self.notes.append(
                    f"FIFO_COUNT reached {count} bytes, more than the {chip.spec.fifo_capacity} B the datasheet "
                    f"figure used here: this part has a larger FIFO (harmless; polling is sized for the smaller one)"
                )
        if overflowed or count % FRAME_BYTES:
            # Overwrite mode lost frames and frame alignment: discard, reset, mark a gap.
            self.overflows += 1
            self._finish_run(parts)
            before = clock.now()
            after = chip.fifo_reset()
            # Frames kept arriving between the status read and the reset and may
            # have raised the flag again: that overflow is already dealt with.
            chip.fifo_overflowed()
            self._restart_segment(before, after)
            return
        frames = count // FRAME_BYTES
        if frames == 0:
            if self._fit_offset is not None:
                self.fit.add(self._fit_offset + self._segment_frames, count_time)
            return
        data = chip.fifo_read(frames * FRAME_BYTES)
        if not self._run:
            self._run_first = self._segment_frames
        self._run.append(data)
        self._run_time = count_time
        self._segment_frames += frames
        self.frames_read += frames
        if self._fit_offset is None:
            self._place_first_frame(count_start, count_time)
        newest = self._fit_offset + self._segment_frames
        self.fit.add(newest, count_time)
        slot = self._bound_count % BOUND_POLLS
        self._bound_k[slot] = newest - 1
        self._bound_end[slot] = count_time
        self._bound_count += 1
        if count_time - self._started >= RATE_CHECK_AFTER:
            self._check_rate()

    def _finish_run(self, parts: list[tuple]) -> None:
        """Resample and time the frames read since the last call (all from one FIFO segment) and append
        (counter, counts, times, gap before, host time of the newest poll) to ``parts`` if they yield samples.

        Once per read rather than per poll: the filter and the timeline cost per
        call far more than per sample, and their output does not depend on how
        the stream is cut.
        """
        if not self._run:
            return
        data = self._run[0] if len(self._run) == 1 else b"".join(self._run)
        self._run = []
        counts_in = np.frombuffer(data, dtype=">i2").reshape(-1, 3)
        if self.resampler.passthrough:
            out = counts_in.astype(np.int16)
            positions = np.arange(self._run_first, self._run_first + len(out), dtype=float)
        else:
            y, positions = self.resampler.process(counts_in)
            if len(y) == 0:
                return
            out = np.rint(y, out=y).clip(-32768, 32767, out=y).astype(np.int16)
        t = self._times(positions)
        gap = 0
        if self._pending_gap:
            self._pending_gap = False
            if self._last_time is None:
                gap = 0
            elif self._grid_unknown:
                gap = -1
            else:
                gap = int(round((t[0] - self._last_time) * self.delivered_rate)) - 1
                gap = gap if gap >= 0 else -1   # a negative size would be nonsense: say unknown
            self._counter += max(gap, 0)
        counter = self._counter
        self._counter += len(out)
        self._last_time = float(t[-1])
        parts.append((counter, out, t, gap, self._run_time))

    def _timeline_period(self) -> float:
        """The measured input period, kept within the rate check's tolerance of the planned one
        (a line through the first two polls can be far off; beyond the tolerance the check stops the stream)."""
        nominal = 1.0 / self.plan.chip_rate
        return min(max(self.fit.period, nominal / (1 + RATE_TOLERANCE)), nominal / (1 - RATE_TOLERANCE))

    def _place_first_frame(self, count_start: float, count_time: float) -> None:
        """Place the first frame after a FIFO reset (or the start) on the timeline and in the regression.

        What is certain: it was taken after the reset began and at most one
        period after the write that restarted the FIFO returned; the newest
        frame counted was taken before the count read returned.  What is
        likely: a register write takes effect, and the count is latched, at
        the end of the transfer, just before the host reads its clock after
        it; so the first frame is most likely within the period after the
        restarting write returned and the newest within the period before the
        count returned.  The
        estimate is the middle of where both likely windows overlap (of where
        the certain ones do, if the host was too late for an overlap).

        After a reset the chip's sample clock runs on, so the frame is the
        point of the old sample grid (whole periods after the last frame before
        the reset) nearest that estimate, and the regression carries on with
        its counter advanced by those periods.  Only at the start, or if that
        point would not be after the last frame (the clock is not what we
        think), does the regression start a new stretch with its own intercept.
        """
        b = self._timeline_period()
        newest = self._segment_frames - 1
        before, after = self._reset_window
        lowest, highest = max(before, count_start - (newest + 1) * b), min(after + b, count_time - newest * b)
        likely_low = max(after, count_time - (newest + 1) * b)
        if highest > likely_low:
            estimate = (likely_low + highest) / 2
        else:
            estimate = (lowest + highest) / 2 if highest > lowest else highest
        periods = round((estimate - self._grid_time) / b) if self._grid_time is not None else 0
        self._grid_unknown = self._grid_time is not None and periods < 1
        if periods < 1:
            self.fit.new_segment()
            self._bound_count = 0
            self._fit_offset, self._ref_time = 0, estimate
        else:
            self._fit_offset, self._ref_time = self._grid_index + periods, self._grid_time + periods * b
        self._ref_pos = 0.0

    def _times(self, positions: np.ndarray) -> np.ndarray:
        """Times of samples at ``positions`` (input frames since the reset, increasing, after ``_ref_pos``):
        one measured period apart from the timeline's last point, slewed toward the regression."""
        b = self._timeline_period()
        elapsed = positions - self._ref_pos
        t = self._ref_time + b * elapsed
        if self._bound_count >= SLEW_AFTER_POLLS and elapsed[-1] > 0:
            error = self._sample_time(self._fit_offset + float(positions[-1]), b) - float(t[-1])
            limit = MAX_SLEW * b * float(elapsed[-1])
            t += min(max(error, -limit), limit) * (elapsed / elapsed[-1])
        self._ref_pos, self._ref_time = float(positions[-1]), float(t[-1])
        return t

    def _sample_time(self, index: float, b: float) -> float:
        """Host time of the sample with regression counter ``index``, from the recent polls.

        Each poll's newest frame was taken before its count read returned,
        and by a random fraction of a period, plus the read's own delay: carried
        to ``index`` with the measured period, the earliest of those bounds over
        the last ``BOUND_POLLS`` polls is then later than the sample by about
        a period / (polls + 1) plus the shortest delay (the envelope a time
        protocol keeps for the same reason).  A least-squares line would take
        those one-sided delays, and a loaded host's long ones, as noise.
        """
        n = min(self._bound_count, BOUND_POLLS)
        k, end = self._bound_k[:n], self._bound_end[:n]
        return float((end + b * (index - k)).min()) - b / (n + 1)

    def _restart_segment(self, before: float, after: float) -> None:
        """After a FIFO reset (or the start), between host times ``before`` and ``after``."""
        if self._fit_offset is not None:
            # the last frame read before the reset (the resampler may not have used it yet)
            last = self._segment_frames - 1
            self._grid_time = self._ref_time + self._timeline_period() * (last - self._ref_pos)
            self._grid_index = self._fit_offset + last
        self._fit_offset = None
        self._reset_window = (before, after)
        self.resampler.reset()
        self._segment_frames = 0
        self._pending_gap = True

    def _check_rate(self) -> None:
        measured = self.fit.rate
        if abs(measured / self.plan.chip_rate - 1.0) > RATE_TOLERANCE:
            raise DeviceError(
                f"{self.chip.spec.label}: the FIFO fills at {measured:.1f} Hz, not the {self.plan.chip_rate:g} Hz "
                f"this configuration should give ({self.plan.describe()})",
                "the datasheet rate for this mode does not hold for this part; request a rate the DLPF "
                f"gives (<= {self.chip.spec.dlpf_base_rate:g} Hz)",
            )
