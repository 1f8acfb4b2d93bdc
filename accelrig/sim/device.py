"""A simulated device: rig physics + sensor model + clock, delivering Blocks.

Used by the sim:// driver and directly by tests and benchmarks (``simulate``).
Everything is deterministic for a seed: the rig's script, the sensor truth and
the noise come from separate generators spawned from that seed, so changing
how the stream is cut into blocks changes nothing for white noise (coloured
noise draws in the order of the chunks computed, LOOKAHEAD samples or a
larger block at a time).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from accelrig import __version__
from accelrig.acquisition.block import Block
from accelrig.recording import Recording
from accelrig.sim.rigs.base import Rig
from accelrig.sim.sensor import SensorModel, SimClock

# Samples computed per call of the rig and sensor model by a streaming device (see SimDevice._take).
LOOKAHEAD = 512


@dataclass
class Faults:
    """Link faults to inject, for testing what sits downstream of a driver.

    drop_probability  chance that a block is lost (the next block carries the gap)
    disconnect_after  seconds of device time after which the device is gone
    """

    drop_probability: float = 0.0
    disconnect_after: float | None = None


class SimDevice:
    """Produces the sample stream of a simulated sensor on a simulated rig."""

    def __init__(
        self,
        rig: Rig,
        sensor: SensorModel,
        clock: SimClock,
        seed: int = 0,
        block_size: int = 256,
        faults: Faults | None = None,
    ):
        self.rig = rig
        self.sensor = sensor
        self.clock = clock
        self.seed = seed
        self.block_size = block_size
        self.faults = faults or Faults()
        seq = np.random.SeedSequence(seed)
        noise_seed, clock_seed, fault_seed = seq.spawn(3)
        self._noise_rng = np.random.default_rng(noise_seed)
        self._clock_rng = np.random.default_rng(clock_seed)
        self._fault_rng = np.random.default_rng(fault_seed)
        self.counter = 0          # next device sample index
        self.seq = 0              # next block sequence number
        self._pending_gap = 0
        self.total_samples = None if rig.duration is None else int(np.floor(rig.duration * clock.true_rate))
        self._response_t = sensor.response_matrix.T   # the part does not change while it streams
        # samples computed ahead (see _take): true times, reported times, counts, channels
        self._ahead: tuple = (np.empty(0), np.empty(0), np.empty((0, 3), dtype=np.int16), {})
        self._ahead_first = 0

    @property
    def exhausted(self) -> bool:
        return self.total_samples is not None and self.counter >= self.total_samples

    @property
    def disconnected(self) -> bool:
        limit = self.faults.disconnect_after
        return limit is not None and self.counter / self.clock.true_rate >= limit

    def samples_due(self, elapsed: float) -> int:
        """Samples the device has taken after ``elapsed`` seconds of device time."""
        n = int(np.floor(elapsed * self.clock.true_rate))
        if self.total_samples is not None:
            n = min(n, self.total_samples)
        return max(n - self.counter, 0)

    def next_block(self, n: int, host_time: float) -> Block | None:
        """Generate the next ``n`` samples; None if the block was 'lost on the link'."""
        if self.total_samples is not None:
            n = min(n, self.total_samples - self.counter)
        first = self.counter
        true_t, reported_t, counts, channels = self._take(first, n)
        self.counter += n
        seq = self.seq
        self.seq += 1
        if self.faults.drop_probability > 0 and self._fault_rng.random() < self.faults.drop_probability:
            self._pending_gap += n
            return None
        gap, self._pending_gap = self._pending_gap, 0
        return Block(
            seq=seq,
            counter=first,
            host_time=host_time,
            counts=counts,
            scale=self.sensor.scale,
            t=reported_t,
            gap_before=gap,
            channels={k: np.asarray(v, dtype=float) for k, v in channels.items()},
        )

    def lost_tail(self, host_time: float) -> Block | None:
        """Once the script has ended, the samples of its last blocks 'lost on the link' as an empty
        block carrying their gap (a gap is reported on the block after it, and none follows these);
        None when nothing is waiting to be reported."""
        if not self.exhausted or not self._pending_gap:
            return None
        gap, self._pending_gap = self._pending_gap, 0
        seq, self.seq = self.seq, self.seq + 1
        channels = {name: np.empty(0) for name in self.rig.channel_names}
        return Block(seq=seq, counter=self.counter, host_time=host_time, counts=np.empty((0, 3), dtype=np.int16),
                     scale=self.sensor.scale, t=np.empty(0), gap_before=gap, channels=channels)

    def _take(self, first: int, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict]:
        """Samples first .. first+n-1: (true times, reported times, counts, channels), copies.

        They are computed ``LOOKAHEAD`` at a time (a frame of a few dozen samples costs the
        rig and sensor model nearly what a few hundred do) and handed out in order; the
        clock's jitter and the white noise are drawn sample after sample either way, so the
        stream is the one block-by-block generation gives.  Samples skipped (the counter
        moved on while nobody listened) are dropped with what was computed for them.
        """
        ahead = self._ahead
        offset = first - self._ahead_first
        if not 0 <= offset <= len(ahead[0]):
            ahead, offset = (np.empty(0), np.empty(0), np.empty((0, 3), dtype=np.int16), {}), 0
        if offset + n > len(ahead[0]):
            kept = [a[offset:] for a in ahead[:3]]
            start = first + len(kept[0])
            m = max(n - len(kept[0]), LOOKAHEAD)
            if self.total_samples is not None:
                m = max(min(m, self.total_samples - start), 0)
            true_t, reported_t = self.clock.times(start, m, self._clock_rng)
            counts = self.sensor.sense(self.rig.specific_force(true_t), self._noise_rng, self.clock.true_rate,
                                       true_t, self._response_t)
            channels = self.rig.channels(true_t)
            kept_channels = {k: v[offset:] for k, v in ahead[3].items()} if len(kept[0]) else {}
            ahead = (np.concatenate([kept[0], true_t]), np.concatenate([kept[1], reported_t]),
                     np.concatenate([kept[2], counts]),
                     {k: np.concatenate([kept_channels[k], np.asarray(v, dtype=float)]) if k in kept_channels
                      else np.asarray(v, dtype=float) for k, v in channels.items()})
            self._ahead, self._ahead_first, offset = ahead, first, 0
        part = slice(offset, offset + n)
        return (ahead[0][part].copy(), ahead[1][part].copy(), ahead[2][part].copy(),
                {k: v[part].copy() for k, v in ahead[3].items()})

    def truth(self) -> dict:
        return {
            "seed": self.seed,
            "sensor": self.sensor.truth(),
            "clock": self.clock.truth(),
            "rig": self.rig.truth(),
        }

    def meta(self) -> dict:
        return {
            "device": f"sim://{self.rig.name}?seed={self.seed}",
            "chip": "sim",
            "range_g": self.sensor.range_g,
            "scale": self.sensor.scale,
            "requested_rate": self.clock.nominal_rate,
            "nominal_rate": self.clock.nominal_rate,
            "software_version": __version__,
            "start_time": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        }


def simulate(
    rig: Rig,
    sensor: SensorModel,
    clock: SimClock,
    seconds: float | None = None,
    seed: int = 0,
    units: str = "m/s^2",
    block_size: int = 4096,
) -> Recording:
    """Run a simulated device as fast as possible into a Recording (with its truth in meta).

    ``seconds`` defaults to the rig's scripted duration.  ``units`` "m/s^2"
    (counts x nominal scale, what a calibration takes as raw) or "counts".
    """
    device = SimDevice(rig, sensor, clock, seed=seed, block_size=block_size)
    if seconds is None:
        if rig.duration is None:
            raise ValueError("an endless rig needs seconds=")
        seconds = rig.duration
    n_total = int(np.floor(seconds * clock.true_rate))
    if device.total_samples is not None:
        n_total = min(n_total, device.total_samples)
    blocks = []
    while device.counter < n_total:
        blocks.append(device.next_block(min(block_size, n_total - device.counter), 0.0))
    counts = np.concatenate([b.counts for b in blocks])
    t = np.concatenate([b.t for b in blocks])
    channels = {name: np.concatenate([b.channels[name] for b in blocks]) for name in rig.channel_names}
    meta = device.meta()
    meta["delivered_rate"] = clock.true_rate
    meta["truth"] = device.truth()
    acc = counts.astype(float) if units == "counts" else counts.astype(float) * sensor.scale
    return Recording(t, acc, units, channels, meta)
