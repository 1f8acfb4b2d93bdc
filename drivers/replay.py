"""replay://FILE: play a recording (CSV, .npz, or segments: a .parquet file or a directory) back as a device.

Options:
    pace=realtime|fast   at the recorded rate (default) or as fast as possible
    units=m/s2|g|mg|counts  units of the file when it does not say (default m/s^2)
    rate=HZ              sample rate for a file without a t column
    block=N              samples per block (default 256)
    loop=1               start again at the end (an endless device)
    start=T, stop=T      play only that stretch: seconds from the first sample, or an ISO-8601 UTC
                         time (recordings that carry UTC time)

Samples become int16 counts again at the scale the file records, or at the
finest standard range (2, 4, 8, 16 g) that holds the data.  The recording's gaps
are replayed where they were, each with the cause it records, so what is recorded
from a replay says why each gap happened as the original did.
"""

from __future__ import annotations

import time

import numpy as np

from accelrig.acquisition.block import Block
from accelrig.acquisition.driver import DeviceInfo, Driver
from accelrig.errors import DataError, DeviceError
from accelrig.recording import load_recording
from accelrig.units import MEMS_RANGES_G, STANDARD_GRAVITY, scale_for_range


class ReplayDriver(Driver):
    scheme = "replay"
    description = "play back a recorded CSV or .npz file as a device"

    def __init__(self, url):
        super().__init__(url)
        self._counts = None
        self._pos = 0
        self._seq = 0
        self._loops = 0

    def known_options(self) -> set[str]:
        return {"pace", "units", "rate", "block", "loop", "start", "stop"}

    def open(self) -> DeviceInfo:
        url = self.url
        url.check_known(self.known_options())
        if not url.target:
            raise DeviceError("replay:// needs a file", "e.g. replay://run.csv")
        self.pace = url.get_choice("pace", ("realtime", "fast"), "realtime")
        self.block = url.get_int("block", 256, low=1, high=65536)
        self.loop = url.get_choice("loop", ("0", "1", "no", "yes", "false", "true"), "0") in ("1", "true", "yes")
        rec = load_recording(url.target, units=url.get_str("units"),
                             rate=url.get_float("rate", low=1.0, high=100000.0, unit="Hz"),
                             start=url.get_str("start"), stop=url.get_str("stop"))
        if len(rec) < 2:
            raise DataError(f"{url.target}: a replay needs at least two samples")
        scale = rec.meta.get("scale")
        if rec.units == "counts":
            if not scale:
                raise DataError(f"{url.target}: the file is in counts but records no scale",
                                "add 'scale' to its metadata or convert it to m/s^2")
            counts = rec.acc
        else:
            si = rec.to_si().acc
            if not scale:
                peak = float(np.max(np.abs(si))) / STANDARD_GRAVITY
                range_g = next((r for r in MEMS_RANGES_G if peak < r * 0.999), MEMS_RANGES_G[-1])
                scale = scale_for_range(range_g)
            counts = np.rint(si / scale)
        self._counts = np.clip(counts, -32768, 32767).astype(np.int16)
        self._t = rec.t - rec.t[0]
        self._period = float(self._t[-1] + (self._t[-1] - self._t[0]) / (len(rec) - 1))
        self._channels = rec.channels
        self._scale = float(scale)
        # the source's gaps are facts of the stream: each one is replayed, with its recorded cause, on the
        # block it precedes (several at one place, or after the last sample: on empty blocks of their own)
        self._gaps: dict[int, list[tuple[int, str | None]]] = {}
        for g in rec.meta.get("gaps") or []:
            if isinstance(g, dict) and "index" in g and "missing" in g and int(g["missing"]):
                cause = g.get("cause")
                self._gaps.setdefault(min(int(g["index"]), len(rec)), []).append(
                    (int(g["missing"]), str(cause) if cause else None))
        self._t0 = time.monotonic()
        rate = rec.rate
        # the replayed device is the one that made the recording: its identity, chip,
        # and whether its chip already removed part of the bias (flashed offsets)
        self.info = DeviceInfo(
            driver="replay", url=url.raw, chip=str(rec.meta.get("chip", "replay")),
            identity=str(rec.meta.get("identity") or rec.meta.get("device") or url.target),
            range_g=float(rec.meta.get("range_g") or round(self._scale * 32768 / STANDARD_GRAVITY, 3)),
            scale=self._scale, requested_rate=rate, nominal_rate=float(rec.meta.get("nominal_rate", rate)),
            who_am_i=rec.meta.get("who_am_i"), channels=tuple(rec.channels),
            hardware_bias_removed=(None if rec.meta.get("hardware_bias_removed") is None
                                   else list(rec.meta["hardware_bias_removed"])),
            extra={"source": url.target, "meta": rec.meta},
        )
        return self.info

    @property
    def at_end(self) -> bool:
        return self._counts is not None and not self.loop and self._pos >= len(self._counts)

    def read(self, timeout: float = 0.1) -> list[Block]:
        if self._counts is None:
            raise DeviceError("the replay device is not open")
        n_total = len(self._counts)
        if self.at_end:
            return []
        if self.pace == "fast":
            stop = min(self._pos + self.block, n_total)
        else:
            elapsed = time.monotonic() - self._t0 - self._loops * self._period
            stop = int(np.searchsorted(self._t, elapsed, side="right"))
            if stop <= self._pos:
                time.sleep(timeout if stop >= n_total else min(timeout, max(self._t[self._pos] - elapsed, 0.0)))
                elapsed = time.monotonic() - self._t0 - self._loops * self._period
                stop = int(np.searchsorted(self._t, elapsed, side="right"))
        blocks = []
        host = time.monotonic()
        while self._pos < stop:
            end = min(stop, self._pos + self.block)
            # a block ends where a recorded gap begins, so the gap lands on the right sample
            later_gaps = [i for i in self._gaps if self._pos < i < end]
            if later_gaps:
                end = min(later_gaps)
            gaps = self._gaps.get(self._pos, [])
            blocks += self._gap_blocks(gaps[:-1], host)
            missing, cause = gaps[-1] if gaps else (0, None)
            sl = slice(self._pos, end)
            offset = self._loops * self._period
            blocks.append(Block(
                seq=self._seq, counter=self._loops * n_total + self._pos, host_time=host,
                counts=self._counts[sl], scale=self._scale, t=self._t[sl] + offset,
                gap_before=missing, channels={k: v[sl] for k, v in self._channels.items()}, gap_cause=cause,
            ))
            self._seq += 1
            self._pos = end
        if self._pos >= n_total:   # gaps the recording ends with
            blocks += self._gap_blocks(self._gaps.get(n_total, []), host)
        if self.loop and self._pos >= n_total:
            self._pos = 0
            self._loops += 1
        return blocks

    def _gap_blocks(self, gaps: list[tuple[int, str | None]], host: float) -> list[Block]:
        """Empty blocks carrying these gaps (one block carries one gap)."""
        blocks = []
        for missing, cause in gaps:
            blocks.append(Block(
                seq=self._seq, counter=self._loops * len(self._counts) + self._pos, host_time=host,
                counts=np.empty((0, 3), np.int16), scale=self._scale, t=np.empty(0), gap_before=missing,
                channels={k: np.empty(0) for k in self._channels}, gap_cause=cause,
            ))
            self._seq += 1
        return blocks

    def close(self) -> None:
        self._counts = None
