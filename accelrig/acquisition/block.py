"""The unit a driver delivers: a batch of samples with its provenance."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True, slots=True)
class Block:
    """A batch of consecutive samples from one device.

    seq         block sequence number as the driver counts it (0, 1, 2, ...).
    counter     device sample counter of the first sample in the block.
    host_time   host monotonic clock (time.monotonic) when the block arrived, s.
    counts      raw samples, int16, shape (n, 3).
    scale       m/s^2 per count (nominal, from the range setting).
    t           sample times in seconds on the session's time base, shape (n,).
                Drivers derive them from the device counter / timestamp aligned
                to the host clock; they are never just n / nominal rate.
    gap_before  samples known to be missing right before this block (lost
                frames, FIFO overflow, reconnect); -1 if a gap happened but its
                size is unknown.  A gap is a fact in the stream, never papered over.
    channels    extra per-sample float channels (e.g. encoder angle ``theta``).
    gap_cause   why that gap happened, where the driver knows better than its kind
                (a replay repeats the cause its recording gives); None: the cause of
                its kind (recorder.gap_cause).
    A block may be empty: a stream that ended with a loss carries the gap after
    its last sample on one.
    """

    seq: int
    counter: int
    host_time: float
    counts: np.ndarray
    scale: float
    t: np.ndarray
    gap_before: int = 0
    channels: dict[str, np.ndarray] = field(default_factory=dict)
    gap_cause: str | None = None

    def __post_init__(self) -> None:
        if self.counts.ndim != 2 or self.counts.shape[1] != 3:
            raise ValueError(f"Block.counts must have shape (n, 3), got {self.counts.shape}")
        if self.counts.dtype != np.int16:
            raise ValueError(f"Block.counts must be int16, got {self.counts.dtype}")
        if self.t.shape != (self.counts.shape[0],):
            raise ValueError("Block.t must have one time per sample")
        for name, values in self.channels.items():
            if values.shape != (self.counts.shape[0],):
                raise ValueError(f"Block channel {name!r} must have one value per sample")

    @property
    def n(self) -> int:
        return self.counts.shape[0]

    def acceleration(self) -> np.ndarray:
        """Samples in m/s^2 at the nominal scale (uncalibrated)."""
        return self.counts.astype(float) * self.scale
