"""The one way blocks become a Recording: a Recorder reads a ring buffer and keeps what it read.

A Recorder owns one reader of a ring buffer.  ``poll()`` takes what arrived
(and hands it back, so a wizard feeds the same chunk to its procedure);
``recording()`` builds the Recording of everything taken so far.  Gaps the
driver reported are kept in the recording's metadata (``gaps``: sample index
and number missing) and never papered over.  Attached to a Session
(``Recorder.attach``) the reader is lossless: the pump waits for it rather
than overwrite samples it has not taken.

Taken samples are kept in memory (``_keep``), or, given a writer, streamed
instead: memory stays bounded whatever the duration.  ``_stream`` is the one
place chunks and the gaps in them become writer calls (``write`` for each run
of samples, ``gap`` at each gap, with its cause and duration), for
``accelrig record -o DIR``, the TUI's captures and the daemon alike.  The
writer is a ``segments.SegmentWriter`` or anything with its ``write`` and
``gap`` (the daemon's device, which adds its own bookkeeping around one).
Times go to it in UTC: the chunk's own (``utc_times``, a driver that maps
them itself) or anchored to the host clock at the first chunk (stated in the
segments' ``time_anchor``).
"""

from __future__ import annotations

import dataclasses
import threading
import time
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

from accelrig.acquisition.driver import DeviceInfo, Driver
from accelrig.acquisition.ringbuffer import Chunk, Reader, RingBuffer
from accelrig.errors import DeviceError
from accelrig.recording import Recording, default_meta

if TYPE_CHECKING:
    from accelrig.acquisition.session import Session
    from accelrig.segments import SegmentWriter


REPLAYED_GAP = "gap in the replayed recording (it records no cause)"


def gap_cause(info: DeviceInfo) -> str:
    """Why a gap the driver reported happened, in words: where a driver of this kind loses samples."""
    if info.driver in ("i2c", "i2c-sim"):
        return "FIFO overflow (samples lost in the chip before they were read)"
    if info.driver == "replay":   # a replay repeats each gap's recorded cause; this is for those without one
        return REPLAYED_GAP
    if info.link_stats is not None:
        return "frames lost on the link (corrupt or dropped)"
    return "samples lost by the device or link"


# the cause of the gap that follows a reconnect (the link went down and came back: the samples the device took
# meanwhile were never sent); it starts "disconnected", as recording.loss_of sorts causes
RECONNECT_CAUSE = "disconnected: the link went down and was re-established"


class Recorder:
    """Every sample one reader delivers, from the first ``poll()`` on.

    Progress figures, kept current by ``poll()``: ``samples``, ``seconds`` (device
    time spanned), ``rate`` (samples per second), ``missing`` (samples the device
    or link reported lost), ``gap_events``; ``full`` once a limit given to poll cut
    the stream.
    """

    def __init__(self, info: DeviceInfo, reader: Reader, session: Session | None = None,
                 writer: SegmentWriter | None = None, utc_times: bool = False):
        self.info = info
        self.reader = reader
        self.session = session
        self.writer = writer                # streams to disk instead of keeping in memory
        self.utc_times = utc_times          # chunk times are UTC seconds already
        self.gap_cause = gap_cause(info)
        self._utc_offset: int | None = None   # UTC epoch ns minus device time ns, set at the first chunk
        self._last_ns: int | None = None      # UTC ns of the last sample streamed
        self._lock = threading.Lock()  # poll() on one thread, recording() on another (the TUI's fit worker)
        self._counts: list[np.ndarray] = []
        self._t: list[np.ndarray] = []
        self._channels: dict[str, list[np.ndarray]] = {name: [] for name in info.channels}
        self._gaps: list[dict] = []
        self._t0: float | None = None
        self.samples = 0
        self.seconds = 0.0
        self.rate = 0.0
        self.missing = 0
        self.gap_events = 0
        self.full = False
        # every gap as {"missing", "cause", "seconds"}: seconds is the time missing (the samples either side,
        # less one nominal period), known once the sample after it arrives; what the summary and its loss
        # warning are made of (a gap of unknown size, missing -1, still has a duration)
        self.gap_log: list[dict] = []
        self._last_t: float | None = None            # device time of the last sample kept
        self._open_gaps: list[dict] = []             # gaps after the last sample kept, waiting for the next
        self._gap_span = 0.0                         # seconds between the samples either side of every gap
        self._gap_intervals = 0                      # sample intervals that span a gap
        self._reconnects = 0                         # the link's reconnects seen so far (its gaps' cause)
        self.last_arrival: float | None = None       # host monotonic time the last sample was taken
        # the gap from the last sample to the end of the recording (a link still down when it ended), or None
        self.open_end: dict | None = None

    @classmethod
    def attach(cls, session: Session, writer: SegmentWriter | None = None) -> Recorder:
        """A recorder on a lossless reader of ``session`` from its oldest sample: attached
        before ``session.start()`` it holds (or, with ``writer``, streams) every sample the device delivers."""
        return cls(session.info, session.reader(from_oldest=True, lossless=True), session, writer)

    @property
    def start(self) -> float | None:
        """Device time of the first sample kept, the recording's t = 0 (None before it)."""
        return self._t0

    def poll(self, seconds: float | None = None, samples: int | None = None) -> Chunk:
        """Take what arrived; returns it as one chunk.

        ``seconds`` (device time from the first sample) and ``samples`` limit what
        is kept in all; what lies beyond is dropped and ``full`` is set.
        """
        chunk = self.reader.read()
        if self.session is not None:
            self.session.notify_read()
        keep = chunk.n
        end_in_gap = False   # the time limit falls between the last sample kept and a gap's far side
        if keep and seconds is not None:
            t0 = self._t0 if self._t0 is not None else float(chunk.t[0])
            keep = int(np.searchsorted(chunk.t - t0, seconds, side="left"))
            end_in_gap = keep < chunk.n and (any(pos == keep for pos, *_ in chunk.gaps)
                                             or (keep == 0 and bool(self._open_gaps)))
        if samples is not None:
            keep = min(keep, samples - self.samples)
        if keep < chunk.n or (samples is not None and self.samples + keep >= samples):
            self.full = True
        if keep < chunk.n:
            chunk = dataclasses.replace(
                chunk, counts=chunk.counts[:keep], t=chunk.t[:keep],
                channels={name: values[:keep] for name, values in chunk.channels.items()},
                gaps=[gap for gap in chunk.gaps if gap[0] < keep])
        # a reconnect since the last poll explains the gap the time limit fell in (the link was down then)
        end_cause = self._cause_after_reconnect() if end_in_gap else None
        self._keep(chunk, self._causes(chunk))
        if end_cause is not None and self._last_t is not None:
            # the samples from the last one kept to the end asked for were lost: said, not left out
            self.end_gap(end_cause, self._t0 + seconds - self._last_t - 1.0 / self.info.nominal_rate)
        return chunk

    def _cause_after_reconnect(self) -> str:
        """The cause of a gap met now: a reconnect since the last one, or the device's usual way of losing samples."""
        stats = self.info.link_stats
        reconnects = stats.reconnects if stats is not None else 0
        if reconnects > self._reconnects:
            self._reconnects = reconnects
            return RECONNECT_CAUSE
        return self.gap_cause

    def _causes(self, chunk: Chunk) -> list[str]:
        """The cause of each of the chunk's gaps (the first after a reconnect is the link having been down)."""
        return [cause or (self._cause_after_reconnect() if i == 0 else self.gap_cause)   # a replay's own first
                for i, (_, _, cause) in enumerate(chunk.gaps)]

    def end_gap(self, cause: str, seconds: float) -> None:
        """The recording ended ``seconds`` after its last sample with no sample since, for ``cause`` (a link
        down, a device gone): a gap of unknown size after the last sample, so the time is counted as lost."""
        if self.open_end is not None or self._last_t is None:
            return
        seconds = max(float(seconds), 0.0)
        with self._lock:
            self.open_end = {"missing": -1, "cause": cause, "seconds": seconds}
            self.gap_log.append(self.open_end)
            self.gap_events += 1
            if self.writer is not None:
                from accelrig.segments import NS

                self.writer.gap(self._last_ns + int((seconds + 1.0 / self.info.nominal_rate) * NS), -1, cause,
                                seconds)
            else:
                self._gaps.append({"index": self.samples, "missing": -1, "cause": cause, "seconds": seconds})

    def silent_for(self) -> float:
        """Host seconds since the last sample was taken (0 before the first)."""
        return 0.0 if self.last_arrival is None else time.monotonic() - self.last_arrival

    def _keep(self, chunk: Chunk, causes: list[str]) -> None:
        with self._lock:
            if self.writer is not None:
                self._stream(chunk, causes)    # the gap records go to the writer, not to memory
            elif chunk.lost:  # cannot happen on a lossless reader, but never hide it
                self._gaps.append({"index": self.samples, "missing": chunk.lost, "cause": "reader overrun"})
            for (pos, missing, _), cause in zip(chunk.gaps, causes, strict=True):
                if self.writer is None:
                    self._gaps.append({"index": self.samples + pos, "missing": missing, "cause": cause})
                self.missing += max(missing, 0)
                self.gap_events += 1
            self._time_gaps(chunk, causes)
            if not chunk.n:
                return
            self.last_arrival = time.monotonic()
            if self._t0 is None:
                self._t0 = float(chunk.t[0])
            if self.writer is None:
                self._counts.append(chunk.counts)
                self._t.append(chunk.t)
                for name in self._channels:
                    self._channels[name].append(chunk.channels[name])
            self.samples += chunk.n
            self.seconds = float(chunk.t[-1] - self._t0)
            self._last_t = float(chunk.t[-1])
            # the rate of the stretches without gaps: a gap's time and its interval left out of both
            steady = self.seconds - self._gap_span
            self.rate = (self.samples - 1 - self._gap_intervals) / steady if steady > 0 else 0.0

    def _time_gaps(self, chunk: Chunk, causes: list[str]) -> None:
        """Log this chunk's gaps with the time each one lasted (from the samples either side)."""
        found = [(0, chunk.lost, "reader overrun")] if chunk.lost else []
        found += [(pos, missing, cause) for (pos, missing, _), cause in zip(chunk.gaps, causes, strict=True)]
        at: dict[int, list[dict]] = {}   # the gaps before each sample of the chunk (n: after its last)
        for pos, missing, cause in found:
            entry = {"missing": missing, "cause": cause, "seconds": None}
            self.gap_log.append(entry)
            at.setdefault(min(pos, chunk.n), []).append(entry)
        if chunk.n and self._open_gaps:
            at.setdefault(0, [])
        for pos in sorted(at):
            entries = at[pos]
            if pos == 0:   # the gaps after the previous chunk's last sample end here too
                entries, self._open_gaps = self._open_gaps + entries, []
            if pos >= chunk.n:
                self._open_gaps += entries       # timed by the next sample, in a later chunk
                continue
            before = float(chunk.t[pos - 1]) if pos > 0 else self._last_t
            self._close_gaps(entries, before, float(chunk.t[pos]))

    def _close_gaps(self, entries: list[dict], before: float | None, after: float) -> None:
        """Gaps between the samples at ``before`` and ``after`` (one interval, whatever their number)."""
        if before is None:   # before the first sample: no time to measure
            return
        self._gap_span += after - before
        self._gap_intervals += 1
        for e in entries:   # several gaps at one place share its time (counted once, by the first)
            e["seconds"] = max(after - before - 1.0 / self.info.nominal_rate, 0.0) if e is entries[0] else 0.0

    @property
    def missing_seconds(self) -> float:
        """Time the gaps took (known once the sample after each has arrived)."""
        return sum(g["seconds"] or 0.0 for g in self.gap_log)

    def _stream(self, chunk: Chunk, causes: list[str]) -> None:
        """Write a chunk to the writer: each run of samples, and each gap record at its place with its
        cause and duration (from the samples either side, less one period); times in UTC."""
        from accelrig.segments import NS, to_ns

        w = self.writer
        if self.utc_times:
            t = to_ns(chunk.t)
        else:
            if self._utc_offset is None and chunk.n:
                now = time.time_ns()
                # in integer ns: float64 epoch seconds would round the device's times to 0.24 us
                self._utc_offset = now - int(to_ns(chunk.t[-1:])[0])   # the chunk's last sample arrived just now
                w.meta["time_anchor"] = {"method": "host UTC clock when the first chunk arrived",
                                         "utc_ns": now, "device_time": float(chunk.t[-1])}
            t = to_ns(chunk.t) + (self._utc_offset or 0)
        if chunk.lost:
            w.gap(t[0] if chunk.n else time.time_ns(), chunk.lost, "reader overrun")
        start = 0
        for (pos, missing, _), cause in zip([*chunk.gaps, (chunk.n, None, None)], [*causes, ""], strict=True):
            if pos > start:
                w.write(t[start:pos], chunk.counts[start:pos],
                        {name: values[start:pos] for name, values in chunk.channels.items()} or None)
                self._last_ns = int(t[pos - 1])
            if missing is not None:
                at = int(t[pos]) if pos < chunk.n else time.time_ns()
                seconds = ((at - self._last_ns) / NS - 1.0 / self.info.nominal_rate
                           if self._last_ns is not None and pos < chunk.n else None)
                w.gap(at, missing, cause, seconds)
            start = pos

    def close(self) -> None:
        """Stop holding the session's pump back (what was taken stays)."""
        if self.session is not None:
            self.session.release(self.reader)

    def recording(self, units: str = "m/s^2") -> Recording:
        """Everything taken so far; ``units`` "m/s^2" (counts x nominal scale) or "counts".

        A recorder streaming to a SegmentWriter reads its segments back (the
        open one up to its last complete block): memory is spent only when asked.
        """
        with self._lock:
            if self.writer is not None:
                return self._read_back(units)
            if not self.samples:
                raise DeviceError(f"{self.info.url} delivered no samples")
            counts = np.concatenate(self._counts)
            t = np.concatenate(self._t) - self._t0
            channels = {name: np.concatenate(parts) for name, parts in self._channels.items()}
            gaps, missing = list(self._gaps), self.missing
        acc = counts.astype(float) if units == "counts" else counts.astype(float) * self.info.scale
        meta = recording_meta(self.info, t, gaps, missing)
        if self.session is not None and self.session.interrupted:
            meta["interrupted"] = self.session.interrupted
        return Recording(t, acc, units, channels, meta)

    def _read_back(self, units: str) -> Recording:
        from accelrig.recording import read_segments

        directory = getattr(self.writer, "directory", None)
        if directory is None:
            raise DeviceError(f"this recorder streamed {self.info.url} to a writer that cannot be read back")
        if not self.samples:
            raise DeviceError(f"{self.info.url} delivered no samples")
        rec = read_segments(directory, units="counts" if units == "counts" else None)
        if self.session is not None and self.session.interrupted:
            rec.meta["interrupted"] = self.session.interrupted
        return rec

    def take_until(self, pull: Callable[[], bool], seconds: float | None = None, samples: int | None = None,
                   on_progress: Callable[[Recorder], None] | None = None, progress_interval: float = 0.25) -> None:
        """Poll until ``seconds`` of device time or ``samples`` samples are kept, or the source ends.

        ``pull()`` brings new samples into the reader's ring (or waits for the
        pump to) and says whether the source has ended.
        """
        last_report = 0.0
        while True:
            ended = pull()
            self.poll(seconds, samples)
            done = ended or self.full
            now = time.monotonic()
            if on_progress is not None and (done or now - last_report >= progress_interval):
                on_progress(self)
                last_report = now
            if done:
                return


def record(
    driver: Driver,
    seconds: float | None = None,
    samples: int | None = None,
    units: str = "m/s^2",
    on_progress: Callable[[Recorder], None] | None = None,
    progress_interval: float = 0.25,
) -> Recording:
    """Record from an open driver, in this thread, until ``seconds`` of device time or ``samples`` samples.

    With neither, records until a finite source ends.  ``units`` "m/s^2"
    (counts x nominal scale) or "counts".  A device error propagates.
    """
    info = driver.info
    if info is None:
        raise DeviceError("record() needs an opened driver")
    # one driver read at a time passes through the ring: it must hold the largest read
    ring = RingBuffer(max(int(info.nominal_rate * 4), 1 << 16), info.scale, info.channels)
    recorder = Recorder(info, ring.reader())

    def pull() -> bool:
        for block in driver.read(timeout=0.1):
            ring.write(block)
        return driver.at_end

    recorder.take_until(pull, seconds, samples, on_progress, progress_interval)
    return recorder.recording(units)


def streaming_writer(info: DeviceInfo, directory, **options) -> SegmentWriter:
    """The SegmentWriter a Recorder streams a device into (``record -o``, the TUI's captures): the
    device's metadata as a recording states it, UTC times, segments named after the device's identity;
    ``options`` go to SegmentWriter (rotation, csv copies)."""
    import re

    from accelrig.segments import SegmentWriter

    meta = stream_meta(info)
    stem = re.sub(r"[^A-Za-z0-9_-]+", "-", info.identity or info.driver).strip("-_") or "device"
    return SegmentWriter(directory, stem=stem, meta=meta, scale=info.scale, channels=info.channels, **options)


def stream_meta(info: DeviceInfo) -> dict:
    """The metadata segments streamed from a device start with (``record -o``, the TUI's captures, the
    daemon): a recording's, in UTC; the rates are measured over what is read back (segments.read_arrays)."""
    meta = recording_meta(info, np.zeros(0), [], 0)
    meta.update(time_base="utc", delivered_rate=None, device_rate=None)
    return meta


def recording_meta(info: DeviceInfo, t: np.ndarray, gaps: list[dict], missing: int) -> dict:
    """A recording's metadata from the device that made it (the one place it is built).

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
        lost_samples=missing,
        lost_share=missing / (n + missing) if n + missing else 0.0,
    )
    if info.hardware_bias_removed is not None:  # flashed chip offsets (profiles.correction_for)
        meta["hardware_bias_removed"] = list(info.hardware_bias_removed)
    if info.truth is not None:
        meta["truth"] = info.truth
    if info.link_stats is not None:  # serial/BLE: what the link got wrong, counted (protocol.LinkStats)
        meta["link_stats"] = info.link_stats.as_dict()
        meta["clock_alignment"] = info.clock_alignment
    return meta
