"""The threaded acquisition Session: rate, drops, disconnects, lossless readers, captures."""

import threading
import time

import numpy as np
import pytest

from accelrig.acquisition.driver import DeviceInfo, Driver
from accelrig.acquisition.recorder import Recorder
from accelrig.acquisition.session import Session, State
from accelrig.acquisition.url import DeviceURL
from accelrig.errors import DeviceError


def _drain(session, reader, recorder, timeout=60.0):
    """Read everything a reader (and a recorder beside it) gets until the pump stops; returns the concatenated counts."""
    parts = []
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        chunk = reader.read()
        recorder.poll()
        session.notify_read()
        if chunk.n:
            parts.append(chunk.counts)
        elif not session.running:
            chunk = reader.read()
            recorder.poll()
            if chunk.n:
                parts.append(chunk.counts)
            break
        else:
            time.sleep(0.005)
    return np.concatenate(parts) if parts else np.zeros((0, 3), np.int16)


def test_finite_fast_source_reaches_a_lossless_reader_whole():
    # 20 s at 200 Hz = ~4000 samples through a ring of 4096 -- a fast source
    # would overrun a plain reader; a lossless one gets every sample.
    session = Session("sim://still?seed=2&pace=fast&seconds=40", buffer_seconds=1.0)
    info = session.open()
    assert info.chip == "sim"
    reader = session.reader(lossless=True)
    recorder = Recorder.attach(session)
    session.start()
    counts = _drain(session, reader, recorder)
    assert session.wait(5)
    stats = session.stats()
    assert stats.state == State.ENDED
    assert stats.last_error is None
    assert reader.lost_total == 0
    assert counts.shape[0] == stats.samples == recorder.samples
    assert stats.samples == int(np.floor(40 * 200 * 1.004)) or abs(stats.samples - 40 * 200 * 1.004) < 50
    rec = recorder.recording()
    assert len(rec) == stats.samples
    np.testing.assert_allclose(rec.acc, counts * info.scale)
    # the device's true rate is +0.4 % (the sim's default rate error)
    assert stats.delivered_rate == pytest.approx(200 * 1.004, rel=2e-3)
    # a finite source that ended is still connected (it can be flashed) until stop()
    assert session.driver.device is not None
    session.stop()
    assert session.driver.device is None


def test_drops_are_counted_and_rate_reflects_them():
    session = Session("sim://still?seed=3&pace=fast&seconds=30&drop=0.2&block=50", buffer_seconds=60)
    session.open()
    recorder = Recorder.attach(session)
    session.start()
    assert session.wait(10)
    recorder.poll()
    stats = session.stats()
    assert stats.gap_events > 0
    # whole 50-sample blocks are lost (the script's last one is short); consecutive losses arrive as one gap
    total = int(np.floor(30 * 200 * 1.004))
    assert stats.missing % 50 in (0, total % 50) and stats.missing >= 50 * (stats.gap_events - 1)
    # blocks lost at the very end too: an empty block carries their gap, as no later block can
    assert stats.samples + stats.missing == total
    assert stats.delivered_rate < 0.95 * 200  # a fifth of the blocks never arrived
    rec = recorder.recording()
    assert sum(g["missing"] for g in rec.meta["gaps"]) == stats.missing


def test_disconnect_is_reported_and_captured_data_kept():
    session = Session("sim://still?seed=4&pace=fast&disconnect_after=3")
    session.open()
    recorder = Recorder.attach(session)
    session.start()
    assert session.wait(10)
    recorder.poll()
    stats = session.stats()
    assert stats.state == State.DISCONNECTED
    assert "disconnected" in stats.last_error
    assert session.interrupted == stats.last_error
    rec = recorder.recording()
    assert rec.duration == pytest.approx(3.0, abs=1.5)
    assert rec.meta["interrupted"] == stats.last_error
    assert "truth" in rec.meta
    assert session.driver.device is None  # a vanished device is released


def test_saturation_is_counted():
    # a 2 g sensor standing on a 3 g shaker would clip; the still rig at 2 g range does not
    session = Session("sim://still?seed=5&pace=fast&seconds=2")
    session.start()
    session.wait(5)
    assert session.stats().saturated == 0
    # A sensor lying with z up reads ~1 g; with range=2 and 'noise' huge it clips often.
    noisy = Session("sim://still?seed=5&pace=fast&seconds=2&noise=30")
    noisy.start()
    noisy.wait(5)
    assert noisy.stats().saturated > 0


def test_open_errors_reach_the_caller_as_one_line():
    session = Session("sim://no-such-rig")
    with pytest.raises(DeviceError, match="unknown simulated rig"):
        session.open()
    with pytest.raises(DeviceError, match="not open"):
        session.reader()


def test_stop_ends_a_realtime_session_promptly():
    session = Session("sim://still?seed=6")
    started = time.monotonic()
    session.start()
    # streaming (waited for, not a fixed 0.3 s a loaded machine can outlast before the pump runs)
    deadline = started + 30
    while session.stats().samples <= 20:
        assert time.monotonic() < deadline, "the session delivered nothing"
        time.sleep(0.01)
    assert session.running
    t0 = time.monotonic()
    session.stop()
    assert time.monotonic() - t0 < 1.0
    assert session.stats().state == State.STOPPED
    # at its own pace: no more samples than 200 Hz gives over the time it ran (a fast-paced source gives thousands)
    assert session.stats().samples < 200 * (time.monotonic() - started) + 50


class SlowReadDriver(Driver):
    """A driver whose read() outlasts the stop() timeout; it records whether close() ran mid-read."""

    scheme = "slow-read"
    description = "test double"

    def __init__(self, read_seconds=0.5, open_error=None):
        super().__init__(DeviceURL.parse("slow-read://x"))
        self.read_seconds = read_seconds
        self.open_error = open_error
        self.reading = threading.Event()
        self.in_read = False
        self.closed_during_read = False
        self.closes = 0

    def open(self):
        if self.open_error is not None:
            raise self.open_error
        return DeviceInfo(driver="slow-read", url="slow-read://x", chip="test", identity="x",
                          range_g=4.0, scale=1e-3, requested_rate=100.0, nominal_rate=100.0)

    def read(self, timeout=0.1):
        self.in_read = True
        self.reading.set()
        time.sleep(self.read_seconds)
        self.in_read = False
        return []

    def close(self):
        self.closes += 1
        self.closed_during_read |= self.in_read


def test_stop_whose_join_times_out_waits_for_the_read_before_closing():
    driver = SlowReadDriver(read_seconds=0.5)
    session = Session(driver=driver)
    session.start()
    assert driver.reading.wait(2)
    session.stop(timeout=0.05)
    assert driver.closes == 1 and not driver.closed_during_read
    assert "did not stop within 0.05 s" in session.stats().last_error
    assert session._thread is not None  # kept, so it can still be joined
    assert session.wait(2)


@pytest.mark.parametrize("error", [RuntimeError("driver bug"), KeyboardInterrupt()])
def test_open_that_fails_any_way_releases_the_driver(error):
    driver = SlowReadDriver(open_error=error)
    session = Session(driver=driver)
    with pytest.raises(type(error)):
        session.open()
    assert driver.closes == 1
    assert session.state == State.CLOSED


def test_open_and_start_releases_the_device_when_preparing_it_fails():
    prepared = []

    def refuse(driver):
        prepared.append(driver)
        raise DeviceError("refused")

    with pytest.raises(DeviceError, match="refused"):
        Session.open_and_start("sim://still?seed=1", record=True, prepare=refuse)
    assert prepared[0].device is None  # stopped: the device was released
