"""Bounded ring buffer: one producer, any number of readers with their own cursors.

Memory is preallocated once (counts int16, times float64, extra channels
float64) and never grows, whatever the run length.  Every sample has an
absolute index; a reader keeps the index of the next sample it wants.

* A reader that falls more than ``capacity`` samples behind learns exactly
  how many samples it lost (``Chunk.lost``); it never receives a sample that
  was being overwritten while it copied (seqlock-style check: the producer
  announces the slots it is about to write before writing them).
* Gaps reported by the driver (``Block.gap_before``, with ``Block.gap_cause``
  when the driver knows it) are kept with the index of the sample that
  follows them and reach every reader, including a reader that overran and
  skipped past them (then as ``Chunk.skipped_gap``).  A gap after the newest
  sample (an empty block: a stream that ended with a loss) reaches readers
  at once, at the end of their chunk.
"""

from __future__ import annotations

import bisect
import threading
from dataclasses import dataclass, field

import numpy as np

from accelrig.acquisition.block import Block
from accelrig.errors import DeviceError


@dataclass
class Chunk:
    """What one read returns: consecutive samples from ``first_index`` on.

    lost         samples this reader missed because it fell behind (overrun)
    gaps         (position in this chunk, samples missing before it, cause) from the driver;
                 missing count -1 means the driver knew of a gap but not its size; cause None:
                 the driver did not say (its kind says where it loses samples); position n:
                 after the chunk's last sample
    skipped_gap  driver-reported missing samples inside the stretch this reader
                 lost by overrun (so no gap is ever unaccounted for)
    """

    first_index: int
    counts: np.ndarray
    t: np.ndarray
    scale: float
    channels: dict[str, np.ndarray] = field(default_factory=dict)
    lost: int = 0
    gaps: list[tuple[int, int, str | None]] = field(default_factory=list)
    skipped_gap: int = 0

    @property
    def n(self) -> int:
        return self.t.size

    def acceleration(self) -> np.ndarray:
        """Uncalibrated samples in m/s^2 (counts x nominal scale)."""
        return self.counts.astype(float) * self.scale

    @property
    def acc(self) -> np.ndarray:
        """The samples in m/s^2, under the name a Recording uses: procedures take either as a chunk."""
        return self.acceleration()


class RingBuffer:
    def __init__(self, capacity: int, scale: float, channel_names: tuple[str, ...] = ()):
        if capacity < 1:
            raise ValueError("capacity must be positive")
        self.capacity = int(capacity)
        self.scale = float(scale)
        self.channel_names = tuple(channel_names)
        # np.full writes every slot now (np.zeros' pages would become resident only as the ring
        # first fills): a process that runs for weeks shows its whole size from the start
        self._counts = np.full((self.capacity, 3), 0, dtype=np.int16)
        self._t = np.full(self.capacity, 0.0)
        self._channels = {name: np.full(self.capacity, 0.0) for name in self.channel_names}
        self._head = 0       # samples completely written
        self._reserved = 0   # samples whose slots the producer has started to overwrite
        self._gap_index: list[int] = []   # index of the sample following each gap
        self._gap_size: list[int] = []    # samples missing there (-1: unknown)
        self._gap_cause: list[str | None] = []   # why, where the driver said
        self._gap_cum: list[int] = []     # known missing samples up to and including each gap
        self._gap_base = 0                # known missing samples in gaps already forgotten
        self._gap_forgotten = 0           # gaps already forgotten (list position + this = gap number)
        self._gap_lock = threading.Lock()
        self.gap_events = 0
        self.blocks_written = 0

    @property
    def head(self) -> int:
        """Absolute index one past the newest sample."""
        return self._head

    @property
    def nbytes(self) -> int:
        return self._counts.nbytes + self._t.nbytes + sum(a.nbytes for a in self._channels.values())

    def write(self, block: Block) -> None:
        """Append a block (producer side only)."""
        if block.scale != self.scale:
            raise DeviceError(
                f"block scale {block.scale} differs from the buffer's {self.scale}",
                "the device range changed mid-stream; reopen the device",
            )
        missing_channels = set(self.channel_names) - set(block.channels)
        if missing_channels:
            raise DeviceError(f"block lacks channel(s) {', '.join(sorted(missing_channels))}")
        n = block.n
        # announced before the gap: a reader that sees a gap at the head with nothing reserved past
        # it knows no samples are on their way behind it (the block was empty)
        self._reserved = self._head + n
        if block.gap_before:
            with self._gap_lock:
                size = int(block.gap_before)
                previous = self._gap_cum[-1] if self._gap_cum else self._gap_base
                self._gap_index.append(self._head)
                self._gap_size.append(size)
                self._gap_cause.append(block.gap_cause)
                self._gap_cum.append(previous + max(size, 0))
                self.gap_events += 1
                # Bound the list: old gaps are forgotten but stay in the cumulative
                # count, so a reader that overran past them still gets them in skipped_gap.
                drop = bisect.bisect_left(self._gap_index, self._head - 2 * self.capacity)
                if drop > 1024:
                    self._gap_base = self._gap_cum[drop - 1]
                    self._gap_forgotten += drop
                    del self._gap_index[:drop], self._gap_size[:drop], self._gap_cause[:drop], self._gap_cum[:drop]
        counts, t = block.counts, block.t
        channels = block.channels
        if n > self.capacity:  # only the newest capacity samples can be kept
            skip = n - self.capacity
            counts, t = counts[skip:], t[skip:]
            channels = {k: v[skip:] for k, v in channels.items()}
            self._reserved = self._head + skip
            self._head += skip
            n = self.capacity
        start = self._head
        self._reserved = start + n
        pos = start % self.capacity
        first = min(n, self.capacity - pos)
        self._counts[pos:pos + first] = counts[:first]
        self._t[pos:pos + first] = t[:first]
        for name in self.channel_names:
            self._channels[name][pos:pos + first] = channels[name][:first]
        if first < n:
            rest = n - first
            self._counts[:rest] = counts[first:]
            self._t[:rest] = t[first:]
            for name in self.channel_names:
                self._channels[name][:rest] = channels[name][first:]
        self._head = start + n
        self.blocks_written += 1

    def _cum_gap_to(self, pos: int) -> int:
        """Known missing samples in all gaps before list position ``pos`` (call under _gap_lock)."""
        return self._gap_cum[pos - 1] if pos > 0 else self._gap_base

    def reader(self, from_oldest: bool = False) -> Reader:
        """A new independent reader: from now on, or from the oldest sample still held."""
        start = max(self._head - self.capacity, 0) if from_oldest else self._head
        return Reader(self, start)

    def _copy(self, start: int, stop: int) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
        idx = np.arange(start, stop) % self.capacity
        if stop - start > 0 and idx[0] + (stop - start) <= self.capacity:
            sl = slice(int(idx[0]), int(idx[0]) + stop - start)
            return (self._counts[sl].copy(), self._t[sl].copy(),
                    {k: v[sl].copy() for k, v in self._channels.items()})
        return self._counts[idx], self._t[idx], {k: v[idx] for k, v in self._channels.items()}



class Reader:
    """One consumer's cursor into a RingBuffer."""

    def __init__(self, buffer: RingBuffer, start: int):
        self.buffer = buffer
        self.cursor = start
        self.lost_total = 0
        with buffer._gap_lock:
            pos = bisect.bisect_left(buffer._gap_index, start)
            self._gap_cum_reported = buffer._cum_gap_to(pos)   # known missing samples accounted for
            self._gap_next = buffer._gap_forgotten + pos       # number of the first gap not yet reported

    @property
    def pending(self) -> int:
        """Samples written that this reader has not read (may exceed capacity: then some are lost)."""
        return self.buffer.head - self.cursor

    def read(self, max_samples: int | None = None) -> Chunk:
        buf = self.buffer
        head = buf._head
        start = max(self.cursor, head - buf.capacity)
        stop = head if max_samples is None else min(head, start + max_samples)
        counts, t, channels = buf._copy(start, stop)
        # Anything the producer began overwriting during the copy is not trusted.
        valid_from = buf._reserved - buf.capacity
        if start < valid_from:
            cut = min(valid_from, stop) - start
            counts, t = counts[cut:], t[cut:]
            channels = {k: v[cut:] for k, v in channels.items()}
            start += cut
            if stop < start:
                stop = start
        lost = start - self.cursor
        skipped_gap = 0
        gaps: list[tuple[int, int]] = []
        if buf.gap_events:
            with buf._gap_lock:
                index = buf._gap_index
                # not reported yet: from the first gap at ``start`` on, less those reported at the end of the last chunk
                mid = max(bisect.bisect_left(index, start), self._gap_next - buf._gap_forgotten)
                # gaps before ``start`` that this reader never saw (it overran past them)
                skipped_gap = buf._cum_gap_to(mid) - self._gap_cum_reported
                # a gap at ``stop`` goes with the sample after it, unless no sample is on its way (the end)
                at_end = stop == head and buf._reserved == head
                hi = max((bisect.bisect_right if at_end else bisect.bisect_left)(index, stop), mid)
                gaps = [(index[i] - start, buf._gap_size[i], buf._gap_cause[i]) for i in range(mid, hi)]
                self._gap_cum_reported = buf._cum_gap_to(hi)
                self._gap_next = buf._gap_forgotten + hi
        self.cursor = stop
        self.lost_total += lost
        return Chunk(start, counts, t, buf.scale, channels, lost, gaps, skipped_gap)
