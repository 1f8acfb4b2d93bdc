"""A simulated firmware that speaks the wire protocol (docs/wire-protocol.md).

``SimFirmware`` is the device: it answers commands and, while streaming,
turns a simulated rig + SensorModel into DATA frame bodies for every
``samples_per_frame`` samples its clock has taken.  It keeps a calibration
record store that checks the record's CRC, as a real firmware must.

Two transports put it behind the real driver code:

* ``PtyFirmware`` serves it on a pseudo-terminal (pty.openpty), so the serial
  driver talks to a real tty through pyserial.  ``pace="realtime"`` follows
  the wall clock (demos, ``serial-sim://``); ``pace="fast"`` runs an emulated
  clock that advances as fast as the reader drains the pty (tests: a minute
  of device time in a second or two, no sleeping).
* ``SimBleClient`` is a fake bleak client (the driver's seam) that delivers
  each body as a notification and can drop, reorder and disconnect.

Injected faults (``LinkFaults``) act where they would act in life: frames
dropped by the device or the link, bytes corrupted or garbage inserted on the
wire, the device stalling (samples taken meanwhile are lost to its FIFO).
"""

from __future__ import annotations

import asyncio
import math
import os
import select
import threading
import time
import tty
from dataclasses import dataclass

import numpy as np

from accelrig.acquisition import protocol as P
from accelrig.errors import DeviceError
from accelrig.sim.device import SimDevice
from accelrig.sim.rigs.base import Rig
from accelrig.sim.sensor import SensorModel, SimClock
from accelrig.units import MEMS_RANGES_G

BOOT_US = 2_500_000  # device timer value when the simulated sensor took sample 0
TIMER_HZ = 1_000_000  # the firmware paces samples with a 1 MHz timer: rates are 1e6 / integer


# PtyFirmware in realtime pace: how late after a frame is full it wakes to send it (so the
# sample that completes it is surely due), and the longest it sleeps while streaming.
FRAME_WAKE_MARGIN = 0.0002
MAX_WAIT = 0.05


def deliverable_rate(requested: float) -> float:
    """Nearest rate a 1 MHz timer can pace (2048 Hz -> 1e6/488 = 2049.18 Hz)."""
    return TIMER_HZ / max(round(TIMER_HZ / requested), 1)


@dataclass
class LinkFaults:
    """Faults to inject.  Probabilities are per frame; times are device seconds.

    drop        a DATA frame is never sent (its sequence number is skipped)
    corrupt     one byte of a serial frame is flipped on the wire
    garbage     1-40 random bytes appear on the wire before a frame
    stall_at / stall_for   the device stops sending; samples taken meanwhile are lost
                (stall_for = inf: it never comes back)
    reorder     (BLE) a notification is delivered after the next one
    disconnect_at  (BLE) device times at which the connection drops
    outage      (BLE) device seconds a disconnect lasts before the device is reachable again
    refuse_connects  (BLE) connection attempts that fail after each disconnect
    cal_fault   "corrupt": the calibration store flips a bit of what it stores
                "refuse": it reports a storage error
    """

    drop: float = 0.0
    corrupt: float = 0.0
    garbage: float = 0.0
    stall_at: float | None = None
    stall_for: float = 0.0
    reorder: float = 0.0
    disconnect_at: tuple[float, ...] = ()
    outage: float = 1.0
    refuse_connects: int = 0
    cal_fault: str | None = None


FIRMWARE_CHIP = "sim-mpu9250"   # the chip the simulated firmware says it has (serial-sim://, ble-sim://)


class SimFirmware:
    """The device side of the protocol, on a simulated rig and sensor."""

    def __init__(
        self,
        rig: Rig,
        sensor: SensorModel,
        rate_error: float = 0.004,
        jitter: float = 20e-6,
        seed: int = 0,
        serial_number: str = "SIM-0001",
        chip: str = FIRMWARE_CHIP,
        max_samples_per_frame: int = P.SAMPLES_PER_BLE_FRAME,
        faults: LinkFaults | None = None,
    ):
        self.rig = rig
        self.sensor = sensor
        self.rate_error = rate_error
        self.jitter = jitter
        self.seed = seed
        self.faults = faults or LinkFaults()
        self.identity = P.Identity(chip, serial_number, "accelrig-sim 1.0", P.CAPABILITY_CAL_STORE,
                                   max_samples_per_frame)
        self.rng = np.random.default_rng(np.random.SeedSequence(seed).spawn(4)[3])
        self.config = P.LinkConfig(int(sensor.range_g), deliverable_rate(200.0), min(32, max_samples_per_frame))
        self.streaming = False
        self.seq = 0
        self.numbered_until = 0   # device counter after the last numbered frame's samples (sent or not)
        self.record: bytes | None = None
        self.sent_frames = 0
        self.dropped_frames = 0
        self.stalled_samples = 0
        self.damaged_frames = 0   # corrupted or garbled on the wire (serial)
        self.unsent_samples = 0   # taken while the link was down (disconnects)
        self.link_lost = False
        # seq -> "sent" / "dropped" / "damaged" when a test asks for it (None: not kept)
        self.fate_log: dict[int, str] | None = None
        self._lock = threading.Lock()
        self._make_device()

    def _make_device(self) -> None:
        clock = SimClock(self.config.rate, self.rate_error, self.jitter)
        self.device = SimDevice(self.rig, self.sensor, clock, seed=self.seed, block_size=self.config.samples_per_frame)

    @property
    def true_rate(self) -> float:
        return self.device.clock.true_rate

    @property
    def finished(self) -> bool:
        """Every sample the rig's script holds has been taken (a rig without an end never finishes)."""
        return self.device.exhausted

    def truth(self) -> dict:
        return self.device.truth()

    # ------------------------------------------------------------ commands

    def handle(self, body: bytes) -> list[bytes]:
        """One command body from the host -> the reply bodies."""
        with self._lock:
            return self._handle(body)

    def _ack(self, frame_type: int, status: int) -> bytes:
        return P.make_body(P.ACK, P.ACK_PAYLOAD.pack(frame_type, status))

    def _handle(self, body: bytes) -> list[bytes]:
        stats = P.LinkStats()
        frame = P.decode_body(body, stats)
        if frame is None:
            return [self._ack(body[1] if len(body) > 1 else 0, P.STATUS_BAD_FRAME)]
        kind = frame.type
        if kind == P.GET_IDENTITY:
            return [P.make_body(P.IDENTITY, self.identity.payload())]
        if kind == P.CONFIGURE:
            try:
                want = P.LinkConfig.from_payload(frame.payload)
            except DeviceError:
                return [self._ack(kind, P.STATUS_BAD_FRAME)]
            frame_ok = 1 <= want.samples_per_frame <= self.identity.max_samples_per_frame
            if want.range_g not in MEMS_RANGES_G or not frame_ok or not 1.0 <= want.rate <= 10000.0 or self.streaming:
                return [self._ack(kind, P.STATUS_BAD_VALUE)]
            self.sensor.range_g = float(want.range_g)
            self.config = P.LinkConfig(want.range_g, deliverable_rate(want.rate), want.samples_per_frame)
            self._make_device()
            return [P.make_body(P.CONFIG, self.config.payload())]
        if kind == P.START:
            self.streaming = True
            self.link_lost = False
            return [self._ack(kind, P.STATUS_OK)]
        if kind == P.STOP:
            self.streaming = False
            return [self._ack(kind, P.STATUS_OK)]
        if kind == P.CAL_WRITE:
            raw = frame.payload
            if len(raw) != P.CAL_RECORD_SIZE or P.crc16(raw[:-2]) != int.from_bytes(raw[-2:], "big"):
                return [self._ack(kind, P.STATUS_BAD_FRAME)]
            if self.faults.cal_fault == "refuse":
                return [self._ack(kind, P.STATUS_STORAGE_ERROR)]
            stored = bytearray(raw)
            if self.faults.cal_fault == "corrupt":
                stored[10] ^= 0x04  # a flash cell that did not take the write
            self.record = bytes(stored)
            return [self._ack(kind, P.STATUS_OK)]
        if kind == P.CAL_READ:
            if self.record is None:
                return [P.make_body(P.CAL_RECORD, bytes((P.RECORD_EMPTY,)))]
            return [P.make_body(P.CAL_RECORD, bytes((P.RECORD_PRESENT,)) + self.record)]
        return [self._ack(kind, P.STATUS_UNSUPPORTED)]

    # ------------------------------------------------------------ data

    def produce(self, device_time: float) -> list[bytes]:
        """DATA bodies for every full frame of samples taken up to ``device_time`` (s)."""
        with self._lock:
            d = self.device
            due = int(math.floor(device_time * d.clock.true_rate))
            if not self.streaming:
                if due > d.counter:  # the sensor keeps sampling; nobody listens
                    if self.link_lost:  # not stopped by the host: a gap in its stream
                        self.unsent_samples += due - d.counter
                    d.counter = due
                return []
            faults = self.faults
            if faults.stall_at is not None:
                stall_start = int(faults.stall_at * d.clock.true_rate)
                stall_end = (math.inf if math.isinf(faults.stall_for)
                             else int((faults.stall_at + faults.stall_for) * d.clock.true_rate))
                if d.counter + self.config.samples_per_frame > stall_start and d.counter < stall_end:
                    # the FIFO overflows while stalled: those samples are gone
                    lost_to = min(due, stall_end)
                    if lost_to > d.counter:
                        self.stalled_samples += lost_to - d.counter
                        d.counter = lost_to
                    if d.counter < stall_end:
                        return []
            n = self.config.samples_per_frame
            bodies = []
            # the script's last frame may be short; after it the device has nothing more to send
            while d.counter + n <= due and not d.exhausted:
                block = d.next_block(n, 0.0)
                seq, self.seq = self.seq, (self.seq + 1) % (1 << 32)
                self.numbered_until = block.counter + block.n
                if faults.drop and self.rng.random() < faults.drop:
                    self.dropped_frames += 1
                    if self.fate_log is not None:
                        self.fate_log[seq] = "dropped"
                    continue
                if self.fate_log is not None:
                    self.fate_log[seq] = "sent"
                # the device timer counts from boot, which was a while before sampling began
                time_us = BOOT_US + int(round(block.t[0] * 1e6))
                bodies.append(P.make_body(P.DATA, P.data_payload(seq, block.counter, time_us, block.counts)))
                self.sent_frames += 1
            return bodies

    def seconds_to_next_frame(self, device_time: float) -> float:
        """Device seconds from ``device_time`` until the next DATA frame is full (inf when not streaming)."""
        with self._lock:
            if not self.streaming:
                return math.inf
            d = self.device
            return (d.counter + self.config.samples_per_frame) / d.clock.true_rate - device_time

    def wire_bytes(self, body: bytes) -> bytes:
        """A body as it leaves on the serial wire, with the injected wire faults."""
        frame = bytearray(P.cobs_encode(body) + b"\x00")
        faults = self.faults
        damaged = False
        if faults.corrupt and self.rng.random() < faults.corrupt:
            pos = int(self.rng.integers(0, len(frame) - 1))
            frame[pos] ^= 1 << int(self.rng.integers(0, 8))
            damaged = True
        if faults.garbage and self.rng.random() < faults.garbage:
            junk = self.rng.integers(0, 256, int(self.rng.integers(1, 41)), dtype=np.uint8).tobytes()
            frame[:0] = junk
            damaged |= junk[-1] != 0  # junk ending in a delimiter leaves the frame intact
        if damaged:
            self.damaged_frames += 1
            if self.fate_log is not None and body[1] == P.DATA:
                self.fate_log[int.from_bytes(body[2:6], "little")] = "damaged"
        return bytes(frame)


class PtyFirmware:
    """Serve a SimFirmware on a pseudo-terminal; ``port`` is the tty path for pyserial."""

    def __init__(self, firmware: SimFirmware, pace: str = "realtime", step: float = 0.02):
        if pace not in ("realtime", "fast"):
            raise ValueError(pace)
        self.firmware = firmware
        self.pace = pace
        self.step = step
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)  # no echo, no line editing: a byte pipe like a UART
        os.set_blocking(self.master, False)
        self.port = os.ttyname(self.slave)
        self.device_time = 0.0
        # True once the firmware's last sample is on the wire (the rig's script ended)
        self.sent_all = False
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="sim-firmware-pty", daemon=True)
        self._parser = P.FrameParser()
        self.error: BaseException | None = None

    def start(self) -> PtyFirmware:
        self._thread.start()
        return self

    def __enter__(self) -> PtyFirmware:
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()

    def stop(self, timeout: float = 5.0) -> None:
        """Stop serving and close the pty; safe to call more than once."""
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout)
        if self._thread.is_alive():
            # Still inside select/os.write on the master: closing now would let its fd
            # number be reused by another file under it.  _run closes both when it ends.
            return
        self._close_pty()

    def _close_pty(self) -> None:
        # -1 marks a closed fd, so a second call never closes a number reused since
        for name in ("master", "slave"):
            fd = getattr(self, name)
            if fd < 0:
                continue
            setattr(self, name, -1)
            try:
                os.close(fd)
            except OSError:
                pass

    def _write(self, data: bytes) -> bool:
        view = memoryview(data)
        while view:
            if self._stop.is_set():
                return False
            _, writable, _ = select.select([], [self.master], [], 0.05)
            if not writable:
                self._serve_commands(0)
                continue
            try:
                n = os.write(self.master, view)
            except BlockingIOError:
                continue
            view = view[n:]
        return True

    def _serve_commands(self, timeout: float) -> None:
        readable, _, _ = select.select([self.master], [], [], timeout)
        if not readable:
            return
        try:
            data = os.read(self.master, 4096)
        except (BlockingIOError, OSError):
            return
        for frame in self._parser.feed(data):
            if isinstance(frame, P.Frame):
                for reply in self.firmware.handle(P.make_body(frame.type, frame.payload)):
                    self._write_reply(P.cobs_encode(reply) + b"\x00")
        # a corrupted command is simply not answered, as a UART would lose it: the host retries

    def _write_reply(self, frame: bytes) -> None:
        view = memoryview(frame)
        while view and not self._stop.is_set():
            try:
                view = view[os.write(self.master, view):]
            except BlockingIOError:
                select.select([], [self.master], [], 0.05)

    def _run(self) -> None:
        t0 = time.monotonic()
        fw = self.firmware
        try:
            while not self._stop.is_set():
                if self.pace == "realtime":
                    # Wake when the next frame is full, as the firmware sends it (a command
                    # wakes the select at once); idle, every 5 ms, so the samples taken
                    # before a START are skipped to within 5 ms of it.
                    wait = fw.seconds_to_next_frame(time.monotonic() - t0) + FRAME_WAKE_MARGIN
                    self._serve_commands(min(max(wait, 0.0), 0.005 if math.isinf(wait) else MAX_WAIT))
                    self.device_time = time.monotonic() - t0
                else:
                    self._serve_commands(0.0 if fw.streaming else 0.01)
                    if fw.streaming:
                        self.device_time += self.step
                out = b"".join(fw.wire_bytes(body) for body in fw.produce(self.device_time))
                if out and not self._write(out):
                    return
                if fw.finished:
                    self.sent_all = True
        except BaseException as exc:  # surfaced to tests; the host sees a stalled device
            self.error = exc
        finally:
            if self._stop.is_set():  # stop() may have given up waiting for this thread
                self._close_pty()


class SimBleClient:
    """A fake bleak.BleakClient in front of a SimFirmware: the BLE driver's test seam.

    Each DATA/reply body becomes one notification on the TX characteristic.
    Faults: ``reorder`` swaps a notification with the next, ``disconnect_at``
    drops the connection at those device times, ``refuse_connects`` makes the
    next attempts fail, ``outage`` is how much device time passes before the
    device is reachable again.  ``pace`` as for PtyFirmware.
    """

    def __init__(self, firmware: SimFirmware, address: str, disconnected_callback=None,
                 pace: str = "realtime", step: float = 0.1, shared: dict | None = None):
        self.firmware = firmware
        self.address = address
        self._disconnected_callback = disconnected_callback
        self.pace = pace
        self.step = step
        # state that outlives one client object (one BLE device, several connections)
        self.shared = shared if shared is not None else {"device_time": 0.0, "t0": time.monotonic(),
                                                         "disconnects": list(firmware.faults.disconnect_at),
                                                         "refusals_left": 0, "connects": 0}
        self.is_connected = False
        self.mtu_size = 23  # what BlueZ reports through bleak, whatever was negotiated
        self._callback = None
        self._task: asyncio.Task | None = None
        self._held: bytes | None = None

    async def connect(self, **kwargs) -> bool:
        await asyncio.sleep(0)
        if self.shared["refusals_left"] > 0:
            self.shared["refusals_left"] -= 1
            raise OSError(f"simulated BLE device {self.address} not reachable")
        self.shared["connects"] += 1
        self.is_connected = True
        return True

    async def disconnect(self) -> bool:
        self._stop_task()
        self.is_connected = False
        return True

    async def start_notify(self, char, callback, **kwargs) -> None:
        self._callback = callback
        self._task = asyncio.get_running_loop().create_task(self._produce())

    async def stop_notify(self, char) -> None:
        self._stop_task()

    async def write_gatt_char(self, char, data, response: bool = True) -> None:
        if not self.is_connected:
            raise OSError("not connected")
        # samples taken while nobody listened are discarded before a START takes effect
        self.firmware.produce(self._now())
        for reply in self.firmware.handle(bytes(data)):
            self._notify(reply)

    def _stop_task(self) -> None:
        if self._task is not None:
            self._task.cancel()
            self._task = None

    def _notify(self, body: bytes) -> None:
        if self._callback is not None:
            self._callback(None, bytearray(body))

    def _now(self) -> float:
        if self.pace == "realtime":
            return time.monotonic() - self.shared["t0"]
        return self.shared["device_time"]

    async def _produce(self) -> None:
        fw = self.firmware
        faults = fw.faults
        while self.is_connected:
            if self.pace == "realtime":
                await asyncio.sleep(0.005)
            else:
                await asyncio.sleep(0.0005)
                if fw.streaming:
                    self.shared["device_time"] += self.step
            now = self._now()
            pending = self.shared["disconnects"]
            if pending and now >= pending[0]:
                pending.pop(0)
                await self._drop_connection(now)
                return
            for body in fw.produce(now):
                if self._held is not None:
                    self._notify(body)
                    self._notify(self._held)
                    self._held = None
                elif faults.reorder and fw.rng.random() < faults.reorder:
                    self._held = body
                else:
                    self._notify(body)
            if fw.finished:
                if self._held is not None:  # the last frame held back has no successor to swap with
                    self._notify(self._held)
                    self._held = None
                self.shared["sent_all"] = True

    async def _drop_connection(self, now: float) -> None:
        fw = self.firmware
        self.is_connected = False
        if self._held is not None and fw.fate_log is not None:
            fw.fate_log[int.from_bytes(self._held[2:6], "little")] = "in flight at disconnect"
        self._held = None  # in flight when the link died
        with fw._lock:
            fw.streaming = False  # the firmware stops streaming when the central goes away
            fw.link_lost = True
        self.shared["refusals_left"] = fw.faults.refuse_connects
        if self.pace == "fast":
            self.shared["device_time"] = now + fw.faults.outage
        if self._disconnected_callback is not None:
            self._disconnected_callback(self)
