"""serial://PORT: a device running accelrig-protocol firmware on a serial port (pyserial).

    serial:///dev/ttyUSB0?baud=921600&rate=2048&range=4

Options:
    baud=N          line rate (default 921600); refused when too slow for the rate
    rate=HZ         requested sample rate (default 2048); the device reports what it delivers
    range=G         full scale +-G: 2, 4 (default), 8, 16
    frame=N         samples per DATA frame (default 64, at most what the device allows)
    stall=S         seconds without data before the device counts as stalled (default 2; under the
                    daemon, its stall_seconds)
While streaming, the port is read at most every 50 ms (sooner when more than 1 KB
would wait in its buffer), so a wake-up takes several frames.
    command_timeout=S   wait for a reply before retrying a command (default 0.5)

serial-sim://RIG: the same driver talking through a pseudo-terminal to the
simulated firmware (accelrig.sim.firmware) on a simulated rig, no hardware.
It takes the serial options above, the sim:// sensor and rig options (seed,
rate_error, jitter, noise, truth, and the rig's), and:
    pace=realtime|fast   wall clock (default) or an emulated clock as fast as read
    drop=P corrupt=P garbage=P   per-frame fault probabilities
    stall_at=S stall_for=S       the device stalls (stall_for=inf: for good)
    cal_fault=corrupt|refuse     the calibration store misbehaves
"""

from __future__ import annotations

import math
import time

import numpy as np

from accelrig.acquisition import protocol as P
from accelrig.acquisition.block import Block
from accelrig.acquisition.firmware_link import FirmwareDriver
from accelrig.acquisition.url import DeviceURL
from accelrig.errors import DeviceError, require_extra

DEFAULT_BAUD = 921600
SERIAL_FRAME_SAMPLES = 64
# bits per byte on a UART (start + 8 data + stop) and the COBS overhead bound
_BITS_PER_BYTE = 10
# While streaming, reads are at least READ_EVERY s apart, so a wake-up handles what a few
# frames brought rather than one frame (64 samples every 31 ms at 2048 Hz) -- but never
# more than READ_AHEAD_BYTES wait in the port's buffer (the kernel's tty buffer is 4 KB).
READ_EVERY = 0.05
READ_AHEAD_BYTES = 1024


def _import_serial():
    return require_extra("serial", "serial", "pyserial", "serial")


class SerialDriver(FirmwareDriver):
    scheme = "serial"
    description = "accelrig-protocol firmware on a serial port (USB-UART, USB-CDC)"
    extra = "serial"
    link_name = "serial port"

    def __init__(self, url):
        super().__init__(url)
        self._port = None
        self.parser = P.FrameParser(self.stats)
        self._read_every = READ_EVERY
        self._last_read = 0.0

    @classmethod
    def discover(cls) -> list[str]:
        _import_serial()
        from serial.tools import list_ports

        return [f"serial://{p.device}" + (f"  ({p.description})" if p.description and p.description != "n/a" else "")
                for p in sorted(list_ports.comports(), key=lambda p: p.device)]

    def _link_options(self) -> set[str]:
        return super()._link_options() | {"baud"}

    def _default_frame_samples(self) -> int:
        return SERIAL_FRAME_SAMPLES

    def _transport_open(self) -> str:
        serial = _import_serial()
        port = self.url.target
        if not port:
            raise DeviceError("serial:// needs a port", "e.g. serial:///dev/ttyUSB0 or serial://COM3")
        self.baud = self.url.get_int("baud", DEFAULT_BAUD)
        if self.baud <= 0:
            raise DeviceError(f"baud={self.baud} in {self.url.raw!r} must be positive")
        try:
            self._port = serial.Serial(port, baudrate=self.baud, timeout=0, exclusive=True)
        except (serial.SerialException, OSError, ValueError) as exc:
            raise DeviceError(f"cannot open serial port {port}: {exc}",
                              "check the name and permissions; 'accelrig devices' lists the ports") from None
        self._port.reset_input_buffer()
        return f"{port} at {self.baud} baud"

    @staticmethod
    def _bytes_per_second(config: P.LinkConfig) -> float:
        """Bytes a stream takes on the wire at most."""
        n = config.samples_per_frame
        # worst-case COBS adds one byte per 254, plus code byte and delimiter
        frame_bytes = P.DATA_HEADER_SIZE + P.SAMPLE_SIZE * n + P.CRC_SIZE + 2 + (P.DATA_HEADER_SIZE + 6 * n) // 254
        return config.rate / n * frame_bytes

    def open(self):
        info = super().open()
        self._read_every = min(READ_EVERY, READ_AHEAD_BYTES / self._bytes_per_second(self.config))
        return info

    def read(self, timeout: float = 0.1):
        if self.streaming and timeout > self._read_every:
            wait = self._last_read + self._read_every - time.monotonic()
            if wait > 0:
                time.sleep(wait)
            # one timeout for every paced read: pyserial reconfigures the tty when it changes
            timeout -= self._read_every
        blocks = super().read(timeout)
        self._last_read = time.monotonic()
        return blocks

    def _check_bandwidth(self, config: P.LinkConfig) -> None:
        n = config.samples_per_frame
        need = self._bytes_per_second(config) * _BITS_PER_BYTE
        if need > 0.9 * self.baud:
            raise DeviceError(
                f"{config.rate:g} Hz in frames of {n} needs {need:,.0f} baud; baud={self.baud} is too slow",
                "use baud=921600 (or 460800), a lower rate, or a USB-CDC device",
            )

    def _send(self, body: bytes) -> None:
        try:
            self._port.write(P.cobs_encode(body) + b"\x00")
        except Exception as exc:
            raise DeviceError(f"writing to {self.url.target} failed: {exc}", "is the device still connected?") from None

    def _receive(self, timeout: float) -> list:
        port = self._port
        try:
            if port.timeout != timeout:  # pyserial reconfigures the tty on every change
                port.timeout = timeout
            data = port.read(max(port.in_waiting, 1))
            if data:
                waiting = port.in_waiting
                if waiting:
                    data += port.read(waiting)
        except Exception as exc:  # pyserial raises SerialException / OSError when the device goes
            raise DeviceError(f"reading {self.url.target} failed: {exc}", "is the device still connected?") from None
        return self.parser.feed(data) if data else []

    def _transport_close(self) -> None:
        if self._port is not None:
            try:
                self._port.close()
            finally:
                self._port = None


# ------------------------------------------------------------------ simulated firmware

SIM_FAULT_OPTIONS = {"drop", "corrupt", "garbage", "stall_at", "stall_for", "cal_fault"}


def _shared_sim_options(url: DeviceURL) -> set[str]:
    """The sim:// options a *-sim:// URL passes to the simulated device (its rig named by the target)."""
    from accelrig.sim.rigs import RIGS
    from accelrig_drivers.sim import SENSOR_OPTIONS

    rig_cls = RIGS.get(url.target)
    if rig_cls is None:
        raise DeviceError(f"unknown simulated rig {url.target!r} in {url.raw!r}",
                          f"available: {', '.join(sorted(RIGS))}")
    # options that mean the same as for sim:// go to its parser; rate and range the host asks for
    return (set(SENSOR_OPTIONS) - {"pace", "block", "drop", "disconnect_after", "rate", "range"}) | set(rig_cls.options)


# after the simulated firmware's last frame, how long a host waits for frames lost on the way
# (dropped or damaged) before it counts them lost and the stream as ended: well inside the 2 s stall limit
SIM_END_SETTLE = 0.5


def sim_stream_read(driver: FirmwareDriver, sent_all: bool) -> bool:
    """Whether a *-sim driver has read everything its simulated firmware will ever send.

    The bytes of the last frames can still be in the pty or the notification queue when the
    firmware is done, so the frame sequence numbers decide: the host has seen (or counted as
    lost) every frame the firmware numbered.  Last frames lost on the way are never seen:
    ``sim_lost_tail`` counts them.
    """
    if not sent_all or driver._pending_data:
        return False
    return driver.sequencer.next_seq == driver.firmware.seq


def sim_lost_tail(driver: FirmwareDriver, sent_all: bool) -> list[Block]:
    """The blocks that end a *-sim stream whose last frames were lost on the way (none otherwise).

    No later frame shows such a loss, so the simulated firmware says where it stopped: once it has
    sent all and the link has been quiet for SIM_END_SETTLE, frames still held for a predecessor are
    released, and those never received are counted lost, their samples a gap after the last sample
    (an empty block carrying it): the stream ends with its loss counted, never silently short.
    """
    if not sent_all or driver._pending_data or sim_stream_read(driver, sent_all):
        return []
    if time.monotonic() - driver._last_data <= SIM_END_SETTLE:
        return []
    now = time.monotonic()
    blocks = driver._assemble(placed, now) if (placed := driver.sequencer.flush()) else []
    firmware = driver.firmware
    missing = driver.sequencer.lose_tail(firmware.seq, firmware.numbered_until)
    if missing:
        blocks.append(Block(driver._block_seq, driver.sequencer.next_counter, now, np.empty((0, 3), np.int16),
                            driver.info.scale, np.empty(0), missing))
        driver._block_seq += 1
    if blocks:   # a stream of which nothing ever arrived has nothing to end: it stalls, as it should
        driver._last_data = now
    return blocks


def sim_firmware_options(url: DeviceURL, extra_faults: set[str] = frozenset()) -> set[str]:
    """The options of a *-sim:// URL besides the link's (``firmware_from_url`` takes them)."""
    return _shared_sim_options(url) | SIM_FAULT_OPTIONS | set(extra_faults) | {"pace"}


def firmware_from_url(url: DeviceURL, max_samples_per_frame: int, extra_faults: set[str] = frozenset()):
    """Build (SimFirmware, own options) from a *-sim:// URL, reusing the sim:// option parser."""
    from accelrig.sim.firmware import LinkFaults, SimFirmware
    from accelrig_drivers.sim import build_device

    shared = _shared_sim_options(url)
    sim_url = DeviceURL(url.raw, "sim", url.target, {k: v for k, v in url.params.items() if k in shared})
    device, _ = build_device(sim_url)
    faults = LinkFaults(
        drop=url.get_float("drop", 0.0, low=0.0, high=0.99), corrupt=url.get_float("corrupt", 0.0, low=0.0, high=0.99),
        garbage=url.get_float("garbage", 0.0, low=0.0, high=0.99), stall_at=url.get_float("stall_at", low=0.0, unit="s"),
        # stall_for=inf: the device never speaks again (the one option where infinity means something)
        stall_for=math.inf if url.get_str("stall_for") == "inf" else url.get_float("stall_for", 0.0, low=0.0, unit="s"),
        cal_fault=url.get_choice("cal_fault", ("none", "corrupt", "refuse"), "none"),
    )
    if faults.cal_fault == "none":
        faults.cal_fault = None
    firmware = SimFirmware(
        device.rig, device.sensor, rate_error=device.clock.rate_error, jitter=device.clock.jitter,
        seed=int(np.random.SeedSequence(device.seed).generate_state(1)[0]),
        serial_number=f"SIM-{device.seed}", max_samples_per_frame=max_samples_per_frame,
        faults=faults,
    )
    return firmware, sim_firmware_options(url, extra_faults)


class SerialSimDriver(SerialDriver):
    scheme = "serial-sim"
    description = "the serial driver on a pty to simulated firmware (no hardware; demos and tests)"
    extra = "serial"

    def __init__(self, url):
        super().__init__(url)
        self.firmware = None
        self.server = None

    @classmethod
    def discover(cls) -> list[str]:
        from accelrig.sim.rigs import RIGS

        return [f"serial-sim://{name}" for name in sorted(RIGS)]

    def chip_named(self) -> str:
        from accelrig.sim.firmware import FIRMWARE_CHIP

        return FIRMWARE_CHIP

    def open(self):
        self.firmware, _ = firmware_from_url(self.url, 255)
        info = super().open()
        info.truth = self.firmware.truth()
        if self.server.pace == "fast":
            self._read_every = 0.0   # the emulated clock advances as fast as the host drains the pty
        return info

    def _link_options(self) -> set[str]:
        return super()._link_options() | sim_firmware_options(self.url)

    @property
    def at_end(self) -> bool:
        # a scripted rig (static, slider-crank, ...) ends: once its last frame has been read,
        # the recording is complete, not a stalled device
        return self.server is not None and sim_stream_read(self, self.server.sent_all)

    def read(self, timeout: float = 0.1) -> list[Block]:
        blocks = super().read(timeout)
        if not blocks and self.server is not None:
            blocks = sim_lost_tail(self, self.server.sent_all)
        return blocks

    def _transport_open(self) -> str:
        from accelrig.sim.firmware import PtyFirmware

        pace = self.url.get_choice("pace", ("realtime", "fast"), "realtime")
        self.server = PtyFirmware(self.firmware, pace=pace).start()
        self.url = DeviceURL(self.url.raw, self.url.scheme, self.server.port, self.url.params)
        try:
            return super()._transport_open() + f" (simulated firmware, pace={pace})"
        except Exception:
            self.server.stop()
            raise

    def _transport_close(self) -> None:
        try:
            super()._transport_close()
        finally:
            if self.server is not None:
                self.server.stop()
                self.server = None
