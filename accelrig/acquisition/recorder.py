"""Record a device into a Recording: driver -> ring buffer -> reader -> arrays.

The recorder pulls from the driver in its own thread, so it can never fall
behind the ring buffer; gaps the driver reports are kept in the recording's
metadata (``gaps``: sample index and number missing) and never papered over.
"""

from __future__ import annotations

import time
from typing import Callable

import numpy as np

from accelrig.acquisition.driver import DeviceInfo, Driver
from accelrig.acquisition.ringbuffer import RingBuffer
from accelrig.errors import DeviceError
from accelrig.recording import Recording, default_meta


class Progress:
    """What a progress line shows while recording."""

    def __init__(self):
        self.samples = 0
        self.seconds = 0.0
        self.rate = 0.0
        self.missing = 0     # samples the device or link reported lost
        self.gap_events = 0


def record(
    driver: Driver,
    seconds: float | None = None,
    samples: int | None = None,
    units: str = "m/s^2",
    on_progress: Callable[[Progress], None] | None = None,
    progress_interval: float = 0.25,
) -> Recording:
    """Record from an open driver until ``seconds`` of device time or ``samples`` samples.

    With neither, records until a finite source ends.  ``units`` "m/s^2"
    (counts x nominal scale) or "counts".
    """
    info = driver.info
    if info is None:
        raise DeviceError("record() needs an opened driver")
    capacity = max(int(info.nominal_rate * 4), 1 << 16)
    ring = RingBuffer(capacity, info.scale, info.channels)
    reader = ring.reader()
    parts_counts, parts_t = [], []
    parts_ch: dict[str, list[np.ndarray]] = {name: [] for name in info.channels}
    gaps: list[dict] = []
    prog = Progress()
    n = 0
    t0 = None
    last_report = 0.0
    done = False
    while not done:
        blocks = driver.read(timeout=0.1)
        for block in blocks:
            ring.write(block)
        chunk = reader.read()
        if chunk.lost:  # cannot happen with one thread pulling, but never hide it
            gaps.append({"index": n, "missing": chunk.lost, "cause": "reader overrun"})
        for pos, missing in chunk.gaps:
            gaps.append({"index": n + pos, "missing": missing, "cause": "device/link"})
            prog.missing += max(missing, 0)
            prog.gap_events += 1
        if chunk.n:
            counts, t = chunk.counts, chunk.t
            if t0 is None:
                t0 = float(t[0])
            keep = counts.shape[0]
            if seconds is not None:
                keep = int(np.searchsorted(t - t0, seconds, side="left"))
            if samples is not None:
                keep = min(keep, samples - n)
            if keep < counts.shape[0]:
                done = True
            parts_counts.append(counts[:keep])
            parts_t.append(t[:keep])
            for name in parts_ch:
                parts_ch[name].append(chunk.channels[name][:keep])
            n += keep
            prog.samples = n
            prog.seconds = float(t[keep - 1] - t0) if keep else prog.seconds
            prog.rate = (n - 1) / prog.seconds if prog.seconds > 0 else 0.0
        if samples is not None and n >= samples:
            done = True
        if driver.at_end:
            done = True
        now = time.monotonic()
        if on_progress is not None and (done or now - last_report >= progress_interval):
            on_progress(prog)
            last_report = now
    if n == 0:
        raise DeviceError(f"{info.url} delivered no samples")
    counts = np.concatenate(parts_counts)
    t = np.concatenate(parts_t) - t0
    acc = counts.astype(float) if units == "counts" else counts.astype(float) * info.scale
    meta = recording_meta(info, t, gaps, prog.missing)
    channels = {name: np.concatenate(parts) for name, parts in parts_ch.items()}
    return Recording(t, acc, units, channels, meta)


def recording_meta(info: DeviceInfo, t: np.ndarray, gaps: list[dict], missing: int) -> dict:
    """A recording's metadata from the device that made it (one place, for record() and TUI captures).

    ``t`` are the sample times from 0; ``gaps`` the gaps met; ``missing`` the
    samples they held (known sizes).
    """
    n = t.size
    span = float(t[-1]) if n > 1 else 0.0
    meta = default_meta(
        device=info.url,
        identity=info.identity,
        driver=info.driver,
        chip=info.chip,
        who_am_i=info.who_am_i,
        range_g=info.range_g,
        scale=info.scale,
        requested_rate=info.requested_rate,
        nominal_rate=info.nominal_rate,
        # delivered: samples that reached us per second; device: the sampling rate
        # including samples the link lost (gaps of known size)
        delivered_rate=(n - 1) / span if span > 0 else None,
        device_rate=(n - 1 + missing) / span if span > 0 else None,
        start_time=time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        gaps=gaps,
    )
    if info.extra.get("hardware_bias_removed") is not None:  # flashed chip offsets (profiles.correction_for)
        meta["hardware_bias_removed"] = list(info.extra["hardware_bias_removed"])
    if "truth" in info.extra:
        meta["truth"] = info.extra["truth"]
    if "link_stats" in info.extra:  # serial/BLE: what the link got wrong, counted (protocol.LinkStats)
        meta["link_stats"] = info.extra["link_stats"].as_dict()
        meta["clock_alignment"] = info.extra.get("clock_alignment")
    return meta
