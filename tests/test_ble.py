"""The BLE driver at the bleak seam: fake clients that replay, drop, reorder and disconnect."""

import asyncio
import subprocess
import sys
import threading
import time
import types

import numpy as np
import pytest

from accelrig.acquisition import protocol as P
from accelrig.acquisition.driver import driver_for
from accelrig.acquisition.recorder import record
from accelrig.acquisition.url import DeviceURL
from accelrig.errors import DeviceError, MissingExtraError
from accelrig_drivers import ble
from accelrig_drivers.ble import BleDriver
from accelrig_drivers.serial import firmware_from_url


def test_sixty_seconds_at_2048_hz_over_the_fake_client_with_zero_loss():
    with driver_for("ble-sim://still?seed=7&pace=fast&rate=2048") as driver:
        rec = record(driver, seconds=60.0)
        fw, stats, info = driver.firmware, driver.stats, driver.info
    assert info.samples_per_frame == P.SAMPLES_PER_BLE_FRAME == 37
    assert len(rec) == int(np.ceil(60.0 * fw.true_rate))
    assert rec.meta["gaps"] == []
    assert stats.lost_frames == stats.lost_samples == stats.crc_errors == stats.late_frames == 0
    assert info.delivered_rate == pytest.approx(fw.true_rate, rel=1e-6)
    assert np.all(np.diff(rec.t) > 0)
    # the counts are what the firmware sampled
    twin, _ = firmware_from_url(DeviceURL.parse("ble-sim://still?seed=7"), 37)
    twin.handle(P.make_body(P.CONFIGURE, P.LinkConfig(4, 2048, 37).payload()))
    twin.handle(P.make_body(P.START))
    expect = np.concatenate([P.decode_body(b, P.LinkStats()).counts for b in twin.produce(61.0)])[:len(rec)]
    np.testing.assert_array_equal(np.rint(rec.acc / info.scale).astype(np.int16), expect)


def test_drops_reordering_and_disconnects_are_all_explained():
    url = ("ble-sim://still?seed=8&pace=fast&rate=2048&drop=0.01&reorder=0.05"
           "&disconnect_at=10,20&outage=1.5&refuse_connects=2&backoff=0.01")
    with driver_for(url) as driver:
        driver.firmware.fate_log = {}
        rec = record(driver, seconds=30.0)
        stats, fw = driver.stats, driver.firmware
        last_seq = driver.sequencer._next_seq - 1
        attempts = list(driver.reconnect_attempts)
    fates = [fw.fate_log[s] for s in range(last_seq + 1)]
    assert stats.reconnects == 2
    assert attempts == [0.01, 0.02, 0.04, 0.01, 0.02, 0.04]  # backoff doubles; two refusals each time
    # reordered frames wait in the window and are never lost; every lost frame has a cause
    assert stats.lost_frames == len(fates) - fates.count("sent")
    assert stats.late_frames == 0 and stats.duplicate_frames == 0
    missing = [g["missing"] for g in rec.meta["gaps"]]
    assert sum(missing) == stats.lost_samples
    assert sum(missing) == 37 * stats.lost_frames + fw.unsent_samples
    outages = [m for m in missing if m > 37 * 3]
    assert len(outages) == 2 and all(1.5 * fw.true_rate <= m <= 1.7 * fw.true_rate for m in outages)
    assert len(rec) + sum(missing) == pytest.approx(30.0 * fw.true_rate, abs=37)
    assert np.all(np.diff(rec.t) > 0)


class ScriptedClient:
    """bleak-shaped: answers commands from a firmware, then replays a fixed notification script."""

    def __init__(self, address, disconnected_callback, script, firmware):
        self.address, self.script, self.firmware = address, script, firmware
        self.disconnected_callback = disconnected_callback
        self.is_connected = False
        self.callback = None

    async def connect(self):
        self.is_connected = True

    async def disconnect(self):
        self.is_connected = False

    async def start_notify(self, char, callback):
        assert char == ble.TX_UUID
        self.callback = callback

    async def write_gatt_char(self, char, data, response=True):
        assert char == ble.RX_UUID and response
        body = bytes(data)
        for reply in self.firmware.handle(body):
            self.callback(object(), bytearray(reply))
        if body[1] == P.START:
            for note in self.script:
                self.callback(object(), bytearray(note))


def scripted_driver(script, **options):
    firmware, _ = firmware_from_url(DeviceURL.parse("ble-sim://still?seed=1"), 37)
    query = "&".join(f"{k}={v}" for k, v in {"rate": 100, "frame": 10, **options}.items())
    return BleDriver(DeviceURL.parse(f"ble://AA:BB:CC:DD:EE:FF?{query}"),
                     client_factory=lambda addr, cb: ScriptedClient(addr, cb, script, firmware))


def body(seq, n=10):
    counts = np.full((n, 3), seq, dtype=np.int16)
    return P.make_body(P.DATA, P.data_payload(seq, 1000 + 10 * seq, 5_000_000 + seq * 100_000, counts))


def test_scripted_notifications_reordered_late_duplicate_and_truncated():
    order = [0, 1, 3, 2, 4, 5, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16, 17, 6, 18, 18]
    script = [body(s) for s in order]
    script.insert(5, body(99)[:20])  # cut to MTU 23 - 3: fails its length / CRC check
    with scripted_driver(script) as driver:
        blocks = []
        deadline = time.monotonic() + 5
        while sum(b.n for b in blocks) < 180 and time.monotonic() < deadline:
            blocks += driver.read(0.2)
        stats = driver.stats
    counts = np.concatenate([b.counts for b in blocks])[:, 0]
    delivered = [int(v) for v in counts[::10]]
    assert delivered == [0, 1, 2, 3, 4, 5] + list(range(7, 19))
    assert stats.late_frames == 1 and stats.lost_frames == 0 and stats.duplicate_frames == 1
    assert stats.crc_errors + stats.length_errors == 1
    assert [b.gap_before for b in blocks if b.gap_before] == [10]


def test_notification_callback_only_hands_bytes_over():
    driver = scripted_driver([])
    driver._on_notify(None, bytearray(body(0)))
    assert list(driver._inbox) == [body(0)] and driver.stats.frames == 0


def test_device_that_does_not_come_back_is_a_clear_error():
    url = "ble-sim://still?pace=fast&disconnect_at=1&refuse_connects=1000&reconnect=0.3&backoff=0.05"
    with driver_for(url) as driver:
        with pytest.raises(DeviceError, match="did not come back within 0.3 s"):
            record(driver, seconds=10.0)


def test_missing_bleak_is_one_clear_error(monkeypatch):
    monkeypatch.setitem(sys.modules, "bleak", None)
    with pytest.raises(MissingExtraError, match=r"pip install 'accelrig\[ble\]'"):
        BleDriver.discover()
    with pytest.raises(MissingExtraError):
        driver_for("ble://AA:BB:CC:DD:EE:FF").open()


def fake_bleak(discover):
    module = types.ModuleType("bleak")
    module.BleakScanner = types.SimpleNamespace(discover=discover)
    return module


def test_scan_failure_and_hang_are_reported_not_raised_raw(monkeypatch):
    async def broken(**kwargs):
        raise FileNotFoundError("[Errno 2] No such file or directory: '/run/dbus/system_bus_socket'")

    monkeypatch.setitem(sys.modules, "bleak", fake_bleak(broken))
    with pytest.raises(DeviceError, match="BLE not searched: no Bluetooth service on this machine"):
        BleDriver.discover()

    async def hangs(**kwargs):
        await asyncio.sleep(100)

    monkeypatch.setitem(sys.modules, "bleak", fake_bleak(hangs))
    monkeypatch.setattr(ble, "SCAN_SECONDS", 0.1)
    start = time.monotonic()
    with pytest.raises(DeviceError, match="BLE scan"):
        BleDriver.discover()
    assert time.monotonic() - start < 3

    async def finds(timeout, service_uuids):
        assert service_uuids == [ble.SERVICE_UUID] and timeout == 0.1
        return [types.SimpleNamespace(address="AA:BB:CC:DD:EE:01", name="accelrig-esp32")]

    monkeypatch.setitem(sys.modules, "bleak", fake_bleak(finds))
    assert BleDriver.discover() == ["ble://AA:BB:CC:DD:EE:01  (accelrig-esp32)"]


def test_devices_command_lists_links_and_never_hangs(cli):
    # the real command ends (a hang runs into the timeout) and lists every link
    r = subprocess.run([sys.executable, "-m", "accelrig", "devices"], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert "Traceback" not in r.stdout + r.stderr
    for scheme in ("serial://", "ble://", "serial-sim://still", "ble-sim://still"):
        assert scheme in r.stdout
    # and quickly: the searches timed in this process, without a new interpreter's start-up (its imports alone
    # took 12 s of wall time on a loaded 2-core machine, and the whole command 16-24 s)
    start = time.monotonic()
    assert cli("devices").returncode == 0
    assert time.monotonic() - start < 15


class NotifyRefusingClient(ScriptedClient):
    """Connects, then refuses to subscribe (as bleak does when the TX characteristic is missing)."""

    async def start_notify(self, char, callback):
        raise OSError("characteristic not found")


def clients_driver(kinds, **options):
    """A BleDriver whose factory hands out one client of each kind in turn; returns (driver, clients)."""
    firmware, _ = firmware_from_url(DeviceURL.parse("ble-sim://still?seed=1"), 37)
    query = "&".join(f"{k}={v}" for k, v in {"rate": 100, "frame": 10, **options}.items())
    kinds = iter(kinds)
    made = []

    def factory(addr, cb):
        made.append(next(kinds)(addr, cb, [], firmware))
        return made[-1]

    return BleDriver(DeviceURL.parse(f"ble://AA:BB:CC:DD:EE:FF?{query}"), client_factory=factory), made


def test_connect_whose_subscription_fails_disconnects_the_client():
    driver, made = clients_driver([NotifyRefusingClient])
    with pytest.raises(DeviceError, match="characteristic not found"):
        driver.open()
    assert len(made) == 1 and not made[0].is_connected
    assert driver.reconnect_attempts == []  # dropping it on purpose is not a link loss
    assert driver._loop is None


def test_reconnect_whose_subscription_fails_disconnects_that_client_and_retries():
    driver, made = clients_driver([ScriptedClient, NotifyRefusingClient, ScriptedClient], backoff=0.01)
    with driver:
        first = made[0]
        first.disconnected_callback(first)  # the link drops
        deadline = time.monotonic() + 30
        while driver.stats.reconnects < 1 and time.monotonic() < deadline:
            time.sleep(0.01)
        assert driver.stats.reconnects == 1
        assert driver.reconnect_attempts == [0.01, 0.02]
        assert not made[1].is_connected
        assert driver.client is made[2] and made[2].is_connected


def test_close_does_not_close_an_event_loop_that_is_still_running(monkeypatch):
    monkeypatch.setattr(ble, "LOOP_STOP_SECONDS", 0.05)
    driver = scripted_driver([])
    driver.open()
    loop, thread = driver._loop, driver._thread
    # a callback (a stuck bleak call) that outlasts the join: stuck until the test lets it go (a fixed 0.5 s could
    # end before the join on a loaded machine, and the thread was no longer alive to be checked)
    stuck, release = threading.Event(), threading.Event()
    loop.call_soon_threadsafe(lambda: (stuck.set(), release.wait(60)))
    assert stuck.wait(60)
    driver._stop_loop()  # used to raise RuntimeError: Cannot close a running event loop
    try:
        assert thread.is_alive() and not loop.is_closed() and driver._loop is None
    finally:
        release.set()
    thread.join(60)
    assert loop.is_closed()  # the thread closed it when it ended
