"""ble://ADDRESS: an ESP32 (or any BLE peripheral) running accelrig-protocol firmware (bleak).

    ble://AA:BB:CC:DD:EE:FF?rate=2048&range=4

GATT (docs/ble.md): one primary service with a TX characteristic (notify;
each notification is one protocol frame body, DATA or a reply) and an RX
characteristic (write with response; each write is one command body).  The
data payload is the serial DATA frame's body, unencoded.

Options: rate, range, frame, stall, command_timeout as for serial://, and
    reconnect=S    give up reconnecting after S s (default 30; 0: never reconnect)
    backoff=S      first reconnect delay, doubled each failure up to 8 s (default 0.5)

The seam for tests is ``client_factory(address, disconnected_callback)``,
which returns a bleak.BleakClient-shaped object; ble-sim://RIG plugs in the
simulated firmware's fake client (accelrig.sim.firmware.SimBleClient) so the
whole driver runs without a radio.  The notification callback only appends
the bytes to a deque; decoding happens in read().
"""

from __future__ import annotations

import asyncio
import collections
import threading
import time

from accelrig.acquisition import protocol as P
from accelrig.acquisition.firmware_link import FirmwareDriver
from accelrig.errors import DeviceError, require_extra

SERVICE_UUID = "a5ce1000-7c2b-4f0e-9d6a-3b8e5f1c2d40"
TX_UUID = "a5ce1001-7c2b-4f0e-9d6a-3b8e5f1c2d40"   # notify: device -> host frame bodies
RX_UUID = "a5ce1002-7c2b-4f0e-9d6a-3b8e5f1c2d40"   # write: host -> device command bodies
SCAN_SECONDS = 3.0
MAX_BACKOFF = 8.0
REORDER_WINDOW = 8
LOOP_STOP_SECONDS = 5.0  # how long close() waits for the link's event loop thread to end


def _import_bleak():
    return require_extra("bleak", "BLE", "bleak", "ble")


def _bleak_client_factory(address, disconnected_callback):
    bleak = _import_bleak()
    return bleak.BleakClient(address, disconnected_callback=disconnected_callback)


def _run_loop(loop: asyncio.AbstractEventLoop) -> None:
    try:
        loop.run_forever()
    finally:
        loop.close()


async def _disconnect_quietly(client) -> None:
    try:
        await client.disconnect()
    except Exception:  # the error that made us drop the link is the one to report
        pass


class BleDriver(FirmwareDriver):
    scheme = "ble"
    description = "accelrig-protocol firmware over Bluetooth LE (ESP32)"
    extra = "ble"
    link_name = "BLE link"
    reorder_window = REORDER_WINDOW

    def __init__(self, url, client_factory=None):
        super().__init__(url)
        self.client_factory = client_factory or _bleak_client_factory
        self.client = None
        self._inbox: collections.deque[bytes] = collections.deque()
        self._arrived = threading.Event()
        self._loop: asyncio.AbstractEventLoop | None = None
        self._thread: threading.Thread | None = None
        self._failure: DeviceError | None = None
        self._reconnected = False
        self._closing = False
        self.reconnect_attempts: list[float] = []  # delay before each attempt, s

    # ------------------------------------------------------------ discovery

    @classmethod
    def discover(cls) -> list[str]:
        """Scan ~3 s for devices advertising the accelrig service; never hangs."""
        bleak = _import_bleak()
        result: dict = {}

        def scan():
            async def run():
                return await bleak.BleakScanner.discover(timeout=SCAN_SECONDS, service_uuids=[SERVICE_UUID])

            try:
                result["devices"] = asyncio.run(asyncio.wait_for(run(), SCAN_SECONDS + 2))
            except BaseException as exc:  # no adapter, no D-Bus, permissions: all mean "cannot scan"
                result["error"] = exc

        worker = threading.Thread(target=scan, name="ble-scan", daemon=True)
        worker.start()
        worker.join(SCAN_SECONDS + 3)
        if worker.is_alive():
            raise DeviceError("BLE scan did not finish", "is a Bluetooth adapter present and powered?")
        if "error" in result:
            exc = result["error"]
            if isinstance(exc, FileNotFoundError):   # bleak on Linux: no D-Bus system bus socket to talk to BlueZ
                raise DeviceError("BLE not searched: no Bluetooth service on this machine (no D-Bus system bus)",
                                  "BLE devices need BlueZ running and an adapter")
            text = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
            raise DeviceError(f"BLE scan failed: {text}", "is a Bluetooth adapter present and powered?")
        return [f"ble://{d.address}" + (f"  ({d.name})" if d.name else "") for d in result.get("devices", [])]

    # ------------------------------------------------------------ transport

    def _link_options(self) -> set[str]:
        return super()._link_options() | {"reconnect", "backoff"}

    def _transport_open(self) -> str:
        address = self.url.target
        if not address:
            raise DeviceError("ble:// needs a device address", "e.g. ble://AA:BB:CC:DD:EE:FF; 'accelrig devices' scans")
        self.reconnect_limit = self.url.get_float("reconnect", 30.0, low=0.0, high=86400.0, unit="s")
        self.backoff = self.url.get_float("backoff", 0.5, low=0.0, low_open=True, high=600.0, unit="s")
        if self.backoff <= 0:
            raise DeviceError(f"backoff={self.backoff} in {self.url.raw!r} must be positive")
        self._loop = asyncio.new_event_loop()
        self._thread = threading.Thread(target=_run_loop, args=(self._loop,), name="ble-link", daemon=True)
        self._thread.start()
        try:
            self._call(self._connect(), timeout=20.0)
        except DeviceError:
            self._stop_loop()
            raise
        return f"BLE {address}"

    def _call(self, coro, timeout: float):
        future = asyncio.run_coroutine_threadsafe(coro, self._loop)
        try:
            return future.result(timeout)
        except DeviceError:
            raise
        except Exception as exc:
            future.cancel()
            text = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
            raise DeviceError(f"BLE {self.url.target}: {text}",
                              "is a Bluetooth adapter present, and the device powered, in range "
                              "and not connected to another central?") from None

    def _on_notify(self, _characteristic, data: bytearray) -> None:
        # Runs in bleak's callback context: hand the bytes over and nothing else.
        self._inbox.append(bytes(data))
        self._arrived.set()

    def _on_disconnect(self, client) -> None:
        # Only the link in use reconnects: a client dropped on purpose (a failed
        # connect, a late callback from the previous link) must not start another loop.
        if self._closing or client is not self.client:
            return
        self._loop.call_soon_threadsafe(lambda: self._loop.create_task(self._reconnect()))

    async def _connect(self) -> None:
        client = self.client_factory(self.url.target, self._on_disconnect)
        await client.connect()
        try:
            await client.start_notify(TX_UUID, self._on_notify)
        except BaseException:
            await _disconnect_quietly(client)  # connected but unusable: do not leave it connected
            raise
        self.client = client

    async def _reconnect(self) -> None:
        """Reconnect with exponential backoff; the stream resumes with the gap the counter shows."""
        self.client = None
        deadline = time.monotonic() + self.reconnect_limit
        delay = self.backoff
        last_error = "disconnected"
        while not self._closing and time.monotonic() + delay <= deadline:
            self.reconnect_attempts.append(delay)
            await asyncio.sleep(delay)
            try:
                await self._connect()
                self._reconnected = True
                if self.streaming:
                    await self.client.write_gatt_char(RX_UUID, P.make_body(P.START), response=True)
                self.stats.reconnects += 1
                self._arrived.set()
                return
            except Exception as exc:  # bleak raises BleakError, TimeoutError, OSError ...
                last_error = str(exc) or type(exc).__name__
                # connected but START failed: drop that link before the next attempt
                client, self.client = self.client, None
                if client is not None:
                    await _disconnect_quietly(client)
                delay = min(delay * 2, MAX_BACKOFF)
        self._failure = DeviceError(
            f"BLE {self.url.target} disconnected and did not come back within {self.reconnect_limit:g} s "
            f"({self.stats.reconnects} earlier reconnects; last error: {last_error})",
            "bring the device back in range and power, then start again",
        )
        self._arrived.set()

    def _send(self, body: bytes) -> None:
        if self._failure is not None:
            raise self._failure
        client = self.client
        if client is None:
            raise DeviceError(f"BLE {self.url.target} is reconnecting", "try again in a moment")
        self._call(client.write_gatt_char(RX_UUID, body, response=True), timeout=5.0)

    def _receive(self, timeout: float) -> list:
        if not self._inbox:
            self._arrived.wait(timeout)
        self._arrived.clear()
        if self._failure is not None:
            raise self._failure
        frames = []
        if self._reconnected:
            # whatever was still awaited from before the disconnect is lost for good
            self._reconnected = False
            self._flush_requested = True
        inbox = self._inbox
        while inbox:
            body = inbox.popleft()
            self.stats.bytes_in += len(body)
            frame = P.decode_body(body, self.stats)
            if frame is not None:
                frames.append(frame)
        return frames

    def _blocks(self, frames, host_time):
        if self.client is None and self._failure is None:
            self._last_data = time.monotonic()  # a reconnect in progress is not a stall
        return super()._blocks(frames, host_time)

    def _link_extra(self) -> dict:
        return {"service_uuid": SERVICE_UUID}

    def _stop_loop(self) -> None:
        if self._loop is not None:
            self._loop.call_soon_threadsafe(self._loop.stop)
            # The thread closes its loop when run_forever() returns; closing it from here
            # while a slow callback still runs would raise "Cannot close a running event loop".
            self._thread.join(timeout=LOOP_STOP_SECONDS)
            self._loop = None

    def _transport_close(self) -> None:
        self._closing = True
        try:
            if self.client is not None and self._loop is not None:
                try:
                    self._call(self.client.disconnect(), timeout=5.0)
                except DeviceError:
                    pass
        finally:
            self.client = None
            self._stop_loop()


BLE_SIM_FAULTS = frozenset({"reorder", "disconnect_at", "outage", "refuse_connects"})


class BleSimDriver(BleDriver):
    scheme = "ble-sim"
    description = "the BLE driver on a fake bleak client to simulated firmware (no radio; demos and tests)"
    extra = None  # needs no bleak: the fake client stands where bleak would

    def __init__(self, url, client_factory=None):
        super().__init__(url, client_factory)
        self.firmware = None

    @classmethod
    def discover(cls) -> list[str]:
        from accelrig.sim.rigs import RIGS

        return [f"ble-sim://{name}" for name in sorted(RIGS)]

    def chip_named(self) -> str:
        from accelrig.sim.firmware import FIRMWARE_CHIP

        return FIRMWARE_CHIP

    def open(self):
        from accelrig.sim.firmware import SimBleClient
        from accelrig_drivers.serial import firmware_from_url

        self.firmware, _ = firmware_from_url(self.url, P.SAMPLES_PER_BLE_FRAME, BLE_SIM_FAULTS)
        faults = self.firmware.faults
        faults.reorder = self.url.get_float("reorder", 0.0, low=0.0, high=1.0)
        text = self.url.get_str("disconnect_at", "")
        try:
            faults.disconnect_at = tuple(sorted(float(v) for v in text.split(",") if v.strip()))
        except ValueError:
            raise DeviceError(f"disconnect_at={text!r} in {self.url.raw!r} is not a list of seconds") from None
        faults.outage = self.url.get_float("outage", 1.0, low=0.0, high=3600.0, unit="s")
        faults.refuse_connects = self.url.get_int("refuse_connects", 0, low=0, high=1000)
        pace = self.url.get_choice("pace", ("realtime", "fast"), "realtime")
        shared = None  # one simulated device behind every client object the driver creates

        def factory(address, disconnected_callback):
            nonlocal shared
            client = SimBleClient(self.firmware, address, disconnected_callback, pace=pace, shared=shared)
            shared = client.shared
            return client

        if self.client_factory is _bleak_client_factory:
            self.client_factory = factory
        info = super().open()
        info.truth = self.firmware.truth()
        return info

    @property
    def at_end(self) -> bool:
        # a scripted rig ends: once its last notification has been read, the recording is complete
        from accelrig_drivers.serial import sim_stream_read

        client = self.client
        return client is not None and not self._inbox and sim_stream_read(self, client.shared.get("sent_all", False))

    def read(self, timeout: float = 0.1):
        from accelrig_drivers.serial import sim_lost_tail

        blocks = super().read(timeout)
        client = self.client
        if not blocks and client is not None and not self._inbox:
            blocks = sim_lost_tail(self, client.shared.get("sent_all", False))
        return blocks

    def _link_options(self) -> set[str]:
        from accelrig_drivers.serial import sim_firmware_options

        return super()._link_options() | sim_firmware_options(self.url, BLE_SIM_FAULTS)
