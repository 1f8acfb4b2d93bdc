"""A live acquisition session: one device pumped into a ring buffer by a thread.

The TUI uses it now and the daemon will reuse it, so it knows nothing of any
user interface.  A Session

* opens a driver (``open``, synchronous: errors reach the caller as DeviceError),
* pumps its blocks into a bounded RingBuffer from its own thread (``start``),
* counts what a person must see: delivered rate, samples reported missing by
  the device or link, gap events, saturated samples, the connection state and
  the last error,
* survives a disconnect: the pump stops, the state says so, the error is kept,
  and everything a Recorder took so far stays available,
* hands out readers: plain ones (a live view that may fall behind and is told
  how much it lost) and lossless ones, which the pump waits for before it
  overwrites samples they have not read (a procedure fed from a fast simulated
  or replayed source must not lose data; a real device that is held back
  reports the loss itself as a gap, so nothing is ever hidden).
"""

from __future__ import annotations

import enum
import threading
import traceback
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from accelrig.acquisition.block import Block
from accelrig.acquisition.driver import DeviceInfo, Driver, driver_for
from accelrig.acquisition.recorder import Recorder
from accelrig.acquisition.ringbuffer import Reader, RingBuffer
from accelrig.errors import AccelrigError, DeviceError
from accelrig.units import saturated

if TYPE_CHECKING:
    from accelrig.segments import SegmentWriter


class State(enum.StrEnum):
    CLOSED = "closed"              # not opened yet
    OPEN = "open"                  # opened, not pumping
    STREAMING = "streaming"        # the pump thread is delivering
    ENDED = "ended"                # a finite source delivered everything
    DISCONNECTED = "disconnected"  # the device went away (DeviceError while reading)
    FAILED = "failed"              # an unexpected error in the pump (a bug; message kept)
    STOPPED = "stopped"            # stopped by the caller


@dataclass(frozen=True)
class SessionStats:
    """A consistent snapshot of the session's counters."""

    state: State
    samples: int                # samples received
    delivered_rate: float       # samples received per second of device time, recent window, Hz
    missing: int                # samples the device or link reported lost
    gap_events: int             # gaps reported (including gaps of unknown size)
    saturated: int              # samples with an axis saturated (units.saturated)
    last_error: str | None
    device_time: float          # s of device time since the first sample


class Session:
    """One device, one pump thread, one ring buffer."""

    RATE_WINDOW = 2.0  # s of device time over which the delivered rate is measured

    def __init__(self, url: str | None = None, driver: Driver | None = None, buffer_seconds: float = 30.0):
        if (url is None) == (driver is None):
            raise ValueError("give a device URL or a driver, not both")
        self.driver = driver if driver is not None else driver_for(url)
        self.url = self.driver.url.raw
        self.buffer_seconds = buffer_seconds
        self.info: DeviceInfo | None = None
        self.ring: RingBuffer | None = None
        self.state = State.CLOSED
        self.last_error: str | None = None
        self.interruption: Exception | None = None   # the error that ended the pump (a DeviceStalled says stalled)
        self._lock = threading.Lock()
        self._space = threading.Condition(self._lock)  # lossless readers made room
        self._stop = threading.Event()
        # Held around every driver call: stop() closes the device only between two reads.
        self._device_lock = threading.Lock()
        self._thread: threading.Thread | None = None
        self.recorder: Recorder | None = None   # set by open_and_start(record=True)
        self._lossless: list[Reader] = []
        self._samples = 0
        self._missing = 0
        self._gap_events = 0
        self._saturated = 0
        self._t_first: float | None = None
        self._t_last: float | None = None
        self._rate_marks: deque[tuple[float, int]] = deque()  # (device time, samples before it)

    # ------------------------------------------------------------------ lifecycle
    @classmethod
    def open_and_start(cls, url: str, buffer_seconds: float = 30.0, record: bool = False,
                       prepare: Callable[[Driver], None] | None = None,
                       writer: Callable[[DeviceInfo], SegmentWriter] | None = None) -> Session:
        """Open ``url`` and start pumping; with ``record`` a Recorder (``session.recorder``)
        is attached before the first sample, so it holds every sample.

        ``prepare`` gets the opened driver before the first sample is read
        (accelrig.profiles.flash.flash_url_profile writes the profile a URL
        names).  ``writer`` (with ``record``) makes the recorder's segment writer from the
        opened device's info: the recorder then streams to disk.  On any failure the session is stopped (the device released)
        and the AccelrigError raised.
        """
        session = cls(url, buffer_seconds=buffer_seconds)
        try:
            session.open()
            if prepare is not None:
                prepare(session.driver)
            if record:
                session.recorder = Recorder.attach(session, writer(session.info) if writer else None)
            session.start()
        except AccelrigError:
            session.stop()
            raise
        return session

    def open(self) -> DeviceInfo:
        """Connect the device (blocking); raises DeviceError with the driver's message."""
        if self.info is not None:
            return self.info
        try:
            self.info = self.driver.open()
        except BaseException:
            # Whatever stopped open() (a DeviceError, a driver bug, Ctrl-C) may have left a
            # half-open link behind (a pty and its thread, a BLE connection): release it.
            try:
                self.driver.close()
            except Exception:
                pass  # the open() error is the one worth reporting
            raise
        self.driver.info = self.info
        capacity = max(int(self.info.nominal_rate * self.buffer_seconds), 4096)
        self.ring = RingBuffer(capacity, self.info.scale, self.info.channels)
        self.state = State.OPEN
        return self.info

    def start(self) -> None:
        """Open if needed and start the pump thread."""
        self.open()
        if self._thread is not None:
            return
        self.state = State.STREAMING
        self._thread = threading.Thread(target=self._pump, name=f"accelrig pump {self.url}", daemon=True)
        self._thread.start()

    def stop(self, timeout: float = 2.0) -> None:
        """Stop pumping and release the device; what recorders took stays."""
        self._stop.set()
        with self._space:
            self._space.notify_all()
        thread = self._thread
        if thread is not None and thread is not threading.current_thread():
            thread.join(timeout)
            if thread.is_alive():
                # The pump is still inside driver.read(); say so, and keep the thread
                # handle so wait() can still join it and start() does not pump twice.
                with self._lock:
                    self.last_error = (f"the pump did not stop within {timeout:g} s: a driver read was "
                                       f"still running; the device was closed only after it returned")
        if self.state in (State.OPEN, State.STREAMING, State.CLOSED):
            self.state = State.STOPPED
        # The pump reads under the device lock: closing without it could pull the
        # device from under a read still in progress.
        with self._device_lock:
            self.driver.close()

    @property
    def running(self) -> bool:
        return self.state == State.STREAMING

    def wait(self, timeout: float | None = None) -> bool:
        """Wait for the pump to finish (end of a finite source, disconnect); True if it did."""
        if self._thread is None:
            return True
        self._thread.join(timeout)
        return not self._thread.is_alive()

    # ------------------------------------------------------------------ data
    def reader(self, from_oldest: bool = False, lossless: bool = False) -> Reader:
        """A new reader of the ring buffer.

        lossless  the pump waits rather than overwrite samples this reader has
                  not read yet; release it with ``release(reader)`` when done.
        """
        if self.ring is None:
            raise DeviceError("the session is not open")
        with self._lock:
            reader = self.ring.reader(from_oldest=from_oldest)
            if lossless:
                self._lossless.append(reader)
        return reader

    def release(self, reader: Reader) -> None:
        with self._space:
            if reader in self._lossless:
                self._lossless.remove(reader)
            self._space.notify_all()

    def notify_read(self) -> None:
        """Tell the pump a lossless reader made room (call after reading)."""
        with self._space:
            self._space.notify_all()

    @property
    def interrupted(self) -> str | None:
        """Why the device went away (disconnect, driver failure), or None."""
        return self.last_error if self.state in (State.DISCONNECTED, State.FAILED) else None

    def stats(self) -> SessionStats:
        with self._lock:
            rate = 0.0
            if self._rate_marks and self._t_last is not None:
                t_then, n_then = self._rate_marks[0]
                span = self._t_last - t_then
                if span > 0:
                    rate = (self._samples - n_then - 1) / span
            device_time = 0.0 if self._t_first is None else self._t_last - self._t_first
            return SessionStats(
                state=self.state,
                samples=self._samples,
                delivered_rate=rate,
                missing=self._missing,
                gap_events=self._gap_events,
                saturated=self._saturated,
                last_error=self.last_error,
                device_time=device_time,
            )

    # ------------------------------------------------------------------ the pump
    def _pump(self) -> None:
        try:
            while not self._stop.is_set():
                with self._device_lock:
                    blocks = self.driver.read(timeout=0.1)
                for block in blocks:
                    if not self._wait_for_room(block.n):
                        return
                    self._take(block)
                if self.driver.at_end and not blocks:
                    self._finish(State.ENDED, None)
                    return
        except AccelrigError as exc:
            # The device went away (unplugged, link lost): say so, keep the data.
            self.interruption = exc
            self._finish(State.DISCONNECTED, str(exc))
        except Exception as exc:  # a bug in a driver: report it rather than die silently
            traceback.print_exc()
            self._finish(State.FAILED, f"{type(exc).__name__}: {exc}")

    def _wait_for_room(self, n: int) -> bool:
        ring = self.ring
        with self._space:
            while self._lossless and not self._stop.is_set():
                slowest = min(r.cursor for r in self._lossless)
                if ring.head + n - slowest <= ring.capacity:
                    return True
                self._space.wait(0.05)
            return not self._stop.is_set()

    def _take(self, block: Block) -> None:
        self.ring.write(block)
        clipped = int(np.count_nonzero(saturated(block.counts).any(axis=1)))
        with self._lock:
            if block.gap_before:
                self._gap_events += 1
                self._missing += max(int(block.gap_before), 0)
            if block.n:
                if self._t_first is None:
                    self._t_first = float(block.t[0])
                self._rate_marks.append((float(block.t[0]), self._samples))
                self._t_last = float(block.t[-1])
                while len(self._rate_marks) > 1 and self._t_last - self._rate_marks[1][0] >= self.RATE_WINDOW:
                    self._rate_marks.popleft()
            self._samples += block.n
            self._saturated += clipped

    def _finish(self, state: State, error: str | None) -> None:
        with self._lock:
            self.state = state
            self.last_error = error
        if state == State.ENDED:
            # A finite source that delivered everything is still connected (an emulated
            # chip can still be flashed); stop() releases it.
            return
        with self._device_lock:
            try:
                self.driver.close()
            except AccelrigError:
                pass
