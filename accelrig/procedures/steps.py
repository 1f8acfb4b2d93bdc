"""One step capture for the rigs that run in steps (slider-crank speeds, rotary settings), files and streams alike.

A step is taken one of two ways:

* **marked**: the source carries a ``step`` channel, the index of the step
  running steadily (negative while the motor settles).  A run of one index is
  a step once a different value follows it, or the source ends;
* **timed**: the operator arms a capture (``arm(seconds)``) while the rig runs
  steadily; the next ``seconds`` of samples are the step (``seconds=None``:
  everything until the source ends, which is how an unmarked file is one step).

Samples are held only while they may still belong to a step, so memory stays
bounded by one step whatever the run length.  Chunks are anything with ``t``,
``acc`` (n, 3) and ``channels`` (a ring-buffer Chunk or a Recording); a step
comes back as a Recording with the source's ``meta``, and the same stream cut
into any chunks gives the same steps.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from accelrig.errors import DataError
from accelrig.recording import Recording


@dataclass
class Step:
    """One captured step: ``index`` from the ``step`` channel (None when timed), its samples."""

    index: int | None
    recording: Recording


class StepCapture:
    """Cuts a stream into steps; ``where`` names the source in messages (a file name)."""

    def __init__(self, meta: dict | None = None, where: str = "the source"):
        self.meta = dict(meta or {})
        self.where = where
        self.marked: bool | None = None   # decided by the first chunk: does it carry a 'step' channel?
        self.seconds: float | None = None  # armed timed capture (None with ``armed`` set: until the end)
        self.armed = False
        self.taken: set[int] = set()       # marked indexes already taken (each must be one block of samples)
        self._parts: list[tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]] = []

    # ------------------------------------------------------------------ timed capture
    def arm(self, seconds: float | None) -> None:
        """Take the next ``seconds`` of samples (None: all until ``finish``) as a step.

        A source that turns out to mark its steps ignores the arming: its marks decide.
        """
        if self.marked:
            raise DataError(f"{self.where} marks its steps in its 'step' channel: each is taken when it ends")
        self.armed, self.seconds, self._parts = True, seconds, []

    @property
    def progress(self) -> float | None:
        """0..1 of an armed timed capture, None when none is running."""
        if not self.armed or self.seconds is None:
            return None
        if not self._parts:
            return 0.0
        return min((self._parts[-1][0][-1] - self._parts[0][0][0]) / self.seconds, 1.0)

    # ------------------------------------------------------------------ feeding
    def feed(self, chunk) -> list[Step]:
        """New samples; returns the steps they complete."""
        if chunk.t.size == 0:
            return []
        if self.marked is None:
            self.marked = "step" in chunk.channels
            self.armed = self.armed and not self.marked
        if self.marked:
            self._parts.append((chunk.t, chunk.acc, dict(chunk.channels)))
            return self._complete_runs(end=False)
        if not self.armed:
            return []  # between captures the stream is only watched
        self._parts.append((chunk.t, chunk.acc, dict(chunk.channels)))
        t0 = self._parts[0][0][0]
        if self.seconds is None or self._parts[-1][0][-1] - t0 < self.seconds:
            return []
        t, acc, channels = self._joined()
        keep = t - t0 <= self.seconds
        self.armed, self._parts = False, []
        return [Step(None, self._recording(t[keep], acc[keep], {k: v[keep] for k, v in channels.items()}))]

    def finish(self) -> list[Step]:
        """The source ended: the last marked step, or the capture armed until the end."""
        if self.marked:
            return self._complete_runs(end=True)
        if self.armed and self.seconds is None and self._parts:
            self.armed = False
            t, acc, channels = self._joined()
            self._parts = []
            return [Step(None, self._recording(t, acc, channels))]
        self.armed, self._parts = False, []
        return []

    # ------------------------------------------------------------------ inside
    def _joined(self):
        t = np.concatenate([p[0] for p in self._parts])
        acc = np.concatenate([p[1] for p in self._parts])
        channels = {name: np.concatenate([p[2][name] for p in self._parts]) for name in self._parts[0][2]}
        return t, acc, channels

    def _recording(self, t, acc, channels) -> Recording:
        return Recording(t, acc, "m/s^2", channels, dict(self.meta))

    def _complete_runs(self, end: bool) -> list[Step]:
        """Runs of one ``step`` value; the last is complete only at the end of the source."""
        if not self._parts:
            return []
        t, acc, channels = self._joined()
        step = channels["step"]
        edges = np.flatnonzero(np.diff(step)) + 1
        starts = np.concatenate([[0], edges])
        stops = np.concatenate([edges, [step.size]])
        if not end:
            starts, stops = starts[:-1], stops[:-1]
        steps = []
        consumed = 0
        for a, b in zip(starts, stops, strict=True):
            consumed = b
            value = step[a]
            if value < 0:
                continue  # the motor settling between steps
            if int(value) in self.taken:
                # steps are numbered from 1 in every message; the column's own (0-based) value beside it
                raise DataError(f"{self.where}: step {int(value) + 1} (step column value {value:g}) is not one "
                                "contiguous block of rows", "one block per step, in time order")
            self.taken.add(int(value))
            steps.append(Step(int(value), self._recording(t[a:b], acc[a:b],
                                                          {k: v[a:b] for k, v in channels.items()})))
        rest = slice(consumed, None)
        self._parts = [(t[rest], acc[rest], {k: v[rest] for k, v in channels.items()})] if consumed < t.size else []
        return steps
