"""The host side of the wire protocol, shared by the serial and BLE drivers.

A subclass supplies the transport (``_transport_open``, ``_send``,
``_receive``, ``_transport_close``); this class does the session: identity,
configuration, start, data frames -> Blocks with measured gaps and estimated
sample times, stall detection, and flashing the calibration record.
"""

from __future__ import annotations

import abc
import time

import numpy as np

from accelrig.acquisition import protocol as P
from accelrig.acquisition.block import Block
from accelrig.acquisition.driver import DeviceInfo, Driver
from accelrig.acquisition.flash import FlashPlan, FlashReport, FlashWrite
from accelrig.acquisition.timebase import StreamClock
from accelrig.errors import DeviceError, DeviceStalled
from accelrig.result import Correction
from accelrig.units import scale_for_range

# URL options every firmware device understands
LINK_OPTIONS = {"rate", "range", "frame", "stall", "command_timeout"}


class FirmwareDriver(Driver):
    """A device running accelrig-protocol firmware, over some transport."""

    reorder_window = 0          # frames that may wait for a late predecessor
    link_name = "link"

    def __init__(self, url):
        super().__init__(url)
        self.stats = P.LinkStats()
        self.sequencer = P.DataSequencer(self.stats, self.reorder_window)
        self.identity: P.Identity | None = None
        self.config: P.LinkConfig | None = None
        self.clock: StreamClock | None = None
        self.streaming = False
        self._opened = False
        self._block_seq = 0
        self._last_data = 0.0
        self._flush_requested = False
        self._pending_data: list[P.DataFrame] = []  # data that arrived while waiting for a reply

    # -------------------------------------------------------- transport (subclass)

    @abc.abstractmethod
    def _transport_open(self) -> str:
        """Connect; return a human description of the link (port, address)."""

    @abc.abstractmethod
    def _send(self, body: bytes) -> None:
        """Send one frame body (the transport adds its own framing)."""

    @abc.abstractmethod
    def _receive(self, timeout: float) -> list:
        """Frames (P.Frame / P.DataFrame) that arrived, waiting at most ``timeout`` s."""

    @abc.abstractmethod
    def _transport_close(self) -> None:
        """Disconnect; safe to call once after a successful _transport_open."""

    def _link_extra(self) -> dict:
        return {}

    # -------------------------------------------------------- session

    def _link_options(self) -> set[str]:
        return set(LINK_OPTIONS)

    def known_options(self) -> set[str]:
        return self._link_options()

    def open(self) -> DeviceInfo:
        url = self.url
        url.check_known(self._link_options())
        rate = url.get_rate(2048.0)
        range_g = int(url.get_range_g(4.0))  # the wire carries it as a byte
        self.stall_timeout = url.get_float("stall", 2.0, low=0.0, low_open=True, high=3600.0, unit="s")
        self.command_timeout = url.get_float("command_timeout", 0.5, low=0.0, low_open=True, high=60.0, unit="s")
        link = self._transport_open()
        self._opened = True
        try:
            # A device left streaming by an earlier session is stopped first.
            self._command(P.STOP, b"", P.ACK)
            self.identity = P.Identity.from_payload(self._command(P.GET_IDENTITY, b"", P.IDENTITY).payload)
            max_n = self.identity.max_samples_per_frame or P.SAMPLES_PER_BLE_FRAME
            frame_n = url.get_int("frame", min(max_n, self._default_frame_samples()))
            if not 1 <= frame_n <= max_n:
                raise DeviceError(f"frame={frame_n} samples in {url.raw!r}: this device sends 1 .. {max_n} per frame")
            requested = P.LinkConfig(range_g, rate, frame_n)
            reply = self._command(P.CONFIGURE, requested.payload(), (P.CONFIG, P.ACK))
            if reply.type == P.ACK:
                raise DeviceError(f"the device refused the configuration {requested} "
                                  f"({self._ack_status(reply)})", "try another rate or range")
            self.config = P.LinkConfig.from_payload(reply.payload)
            if self.config.range_g != range_g:
                raise DeviceError(f"asked for +-{range_g} g, the device reports +-{self.config.range_g} g")
            self._check_bandwidth(self.config)
        except Exception:
            self.close()
            raise
        self.clock = StreamClock(self.config.rate)
        self.info = DeviceInfo(
            driver=self.scheme, url=url.raw, chip=self.identity.chip, identity=self.identity.serial,
            range_g=float(self.config.range_g), scale=scale_for_range(self.config.range_g),
            requested_rate=rate, nominal_rate=self.config.rate,
            firmware=self.identity.firmware, samples_per_frame=self.config.samples_per_frame,
            calibration_store=bool(self.identity.capabilities & P.CAPABILITY_CAL_STORE), link_stats=self.stats,
            extra={"link": link, **self._link_extra()},
        )
        return self.info

    def _default_frame_samples(self) -> int:
        return P.SAMPLES_PER_BLE_FRAME

    def _check_bandwidth(self, config: P.LinkConfig) -> None:
        """Transports with a bit rate refuse configurations they cannot carry."""

    def close(self) -> None:
        if not self._opened:
            return
        self._opened = False
        try:
            if self.streaming:
                self._send(P.make_body(P.STOP))
        except Exception:  # closing a link that is already gone must not mask the first error
            pass
        self.streaming = False
        self._transport_close()

    @staticmethod
    def _ack_status(frame: P.Frame) -> str:
        acked, status = P.ACK_PAYLOAD.unpack(frame.payload)
        return f"{P.FRAME_NAMES.get(acked, hex(acked))}: {P.STATUS_NAMES.get(status, status)}"

    def _command(self, frame_type: int, payload: bytes, expect, retries: int = 3) -> P.Frame:
        """Send a command and wait for its reply, retrying when a frame is lost on the link."""
        expect = (expect,) if isinstance(expect, int) else tuple(expect)
        body = P.make_body(frame_type, payload)
        name = P.FRAME_NAMES[frame_type]
        for _ in range(retries):
            self._send(body)
            deadline = time.monotonic() + self.command_timeout
            while time.monotonic() < deadline:
                for frame in self._take(deadline - time.monotonic()):
                    if frame.type not in expect:
                        continue
                    if frame.type == P.ACK:
                        acked, status = P.ACK_PAYLOAD.unpack(frame.payload)
                        if acked != frame_type:
                            continue  # a late reply to an earlier command
                        if expect == (P.ACK,) and status != P.STATUS_OK:
                            raise DeviceError(f"the device refused {name}: {P.STATUS_NAMES.get(status, status)}")
                    return frame
        raise DeviceError(
            f"no reply to {name} from {self.url.raw} after {retries} tries",
            f"is the device running accelrig protocol v{P.PROTOCOL_VERSION} firmware on this {self.link_name}?",
        )

    def _take(self, timeout: float) -> list[P.Frame]:
        """Non-data frames; data frames that arrive meanwhile go to the stream when streaming."""
        out = []
        for frame in self._receive(max(timeout, 0.0)):
            if isinstance(frame, P.DataFrame):
                if self.streaming:
                    self._pending_data.append(frame)
            else:
                out.append(frame)
        return out

    def _start(self) -> None:
        self._pending_data = []
        self.streaming = True  # before the command: data may arrive right behind the ACK
        try:
            self._command(P.START, b"", P.ACK)
        except Exception:
            self.streaming = False
            raise
        self._last_data = time.monotonic()

    def read(self, timeout: float = 0.1) -> list[Block]:
        if not self._opened:
            raise DeviceError(f"{self.url.raw} is not open")
        if not self.streaming:
            self._start()
        frames = self._pending_data + self._receive(timeout)
        self._pending_data = []
        return self._blocks(frames, time.monotonic())

    def _blocks(self, frames: list, host_time: float) -> list[Block]:
        placed = []
        if self._flush_requested:  # the transport says nothing more will come for what is awaited
            self._flush_requested = False
            placed += self.sequencer.flush()
        arrived = False
        for frame in frames:
            if isinstance(frame, P.DataFrame):
                arrived = True
                placed += self.sequencer.push(frame)
        if arrived:   # held for a predecessor or not, data came: the device is not stalled
            self._last_data = time.monotonic()
        if not placed:
            if time.monotonic() - self._last_data > self.stall_timeout:
                raise DeviceStalled(
                    f"{self.url.raw} sent no data for {self.stall_timeout:g} s: the device stalled "
                    f"(link so far: {self.stats.frames} frames, {self.stats.crc_errors} CRC errors, "
                    f"{self.stats.lost_frames} lost frames)",
                    "check the device and the link; stall=SECONDS in the URL changes the limit",
                    seconds=self.stall_timeout,
                )
            return []
        self._last_data = time.monotonic()
        return self._assemble(placed, host_time)

    def _assemble(self, placed, host_time: float) -> list[Block]:
        """Consecutive frames with no gap between them become one Block."""
        clock = self.clock
        blocks = []
        run: list = []

        def emit():
            if not run:
                return
            first_counter, gap = run[0][1], run[0][2]
            counts = np.concatenate([f.counts for f, _, _ in run]) if len(run) > 1 else run[0][0].counts
            t = clock.times(first_counter, counts.shape[0])
            blocks.append(Block(self._block_seq, first_counter, host_time, counts, self.info.scale, t, gap))
            self._block_seq += 1

        for frame, first, gap in placed:
            if gap != 0:
                emit()   # before a restart forgets the old counter
                run = []
            if gap == -1:
                clock.restart()
            clock.observe(first, frame.counts.shape[0], frame.device_time_us * 1e-6, host_time)
            run.append((frame, first, gap))
        emit()
        self.info.delivered_rate = clock.delivered_rate
        self.info.clock_alignment = clock.alignment
        return blocks

    # -------------------------------------------------------- flashing

    def _read_record(self) -> P.CalibrationRecord | None:
        reply = self._command(P.CAL_READ, b"", (P.CAL_RECORD, P.ACK))
        if reply.type == P.ACK:
            raise DeviceError(f"the device cannot read its calibration record ({self._ack_status(reply)})")
        if not reply.payload or reply.payload[0] == P.RECORD_EMPTY:
            return None
        return P.CalibrationRecord.from_bytes(reply.payload[1:])

    def plan_flash(self, correction: Correction, profile_id: bytes) -> FlashPlan:
        if self.info is None:
            raise DeviceError("plan_flash needs an opened device")
        if self.streaming:
            raise DeviceError("cannot flash while streaming", "flash from a freshly opened device")
        if not self.info.calibration_store:
            raise DeviceError(f"{self.identity.chip} firmware {self.identity.firmware!r} has no calibration store",
                              "keep the profile on the host and apply it to the stream instead")
        current = self._read_record()
        new = P.CalibrationRecord.from_correction(correction, self.config.range_g, profile_id, int(time.time())
                                                  ).as_float32()
        writes = []
        axes = "xyz"
        for i in range(3):
            writes.append(FlashWrite(
                f"record: matrix row {axes[i]}",
                None if current is None else _fmt(current.matrix[i]), _fmt(new.matrix[i]),
                f"calibrated {axes[i]} = C[{axes[i]}] . (raw - b), dimensionless"))
        writes.append(FlashWrite("record: bias b", None if current is None else _fmt(current.bias), _fmt(new.bias),
                                 "subtracted from raw = counts x nominal scale, m/s^2"))
        writes.append(FlashWrite("record: bias uncertainty", None if current is None else _fmt(current.bias_uncertainty),
                                 _fmt(new.bias_uncertainty), "standard uncertainty (k=1), m/s^2"))
        writes.append(FlashWrite("record: matrix uncertainty (max)",
                                 None if current is None else f"{float(np.max(current.matrix_uncertainty)):.3g}",
                                 f"{float(np.max(new.matrix_uncertainty)):.3g}", "largest standard uncertainty of C, k=1"))
        writes.append(FlashWrite("record: range / profile id",
                                 None if current is None else f"+-{current.range_g} g / {current.profile_id.hex()}",
                                 f"+-{new.range_g} g / {new.profile_id.hex()}", "which profile the device holds"))
        residual = {
            "float32 rounding of matrix (max abs)": float(np.max(np.abs(new.matrix - correction.matrix))),
            "float32 rounding of bias, m/s^2 (max abs)": float(np.max(np.abs(new.bias - correction.bias))),
        }
        notes = [
            f"the full correction (C, b and their uncertainties) is written as one {P.CAL_RECORD_SIZE}-byte "
            "record with a CRC-16, then read back and compared byte for byte",
            "data frames stay raw counts: whoever reads the device applies the record (or the profile)",
        ]
        if current is None:
            notes.append("the device holds no calibration record yet")
        return FlashPlan(device=f"{self.url.raw} ({self.identity.serial})", writes=writes, residual=residual,
                         notes=notes, payload=new.to_bytes())

    def flash(self, plan: FlashPlan) -> FlashReport:
        record_bytes = plan.payload
        if not isinstance(record_bytes, bytes) or len(record_bytes) != P.CAL_RECORD_SIZE:
            raise DeviceError("this flash plan was not made by a firmware driver's plan_flash")
        intended = P.CalibrationRecord.from_bytes(record_bytes)
        self._command(P.CAL_WRITE, record_bytes, P.ACK)
        reply = self._command(P.CAL_READ, b"", (P.CAL_RECORD, P.ACK))
        notes = []
        readback = []
        if reply.type != P.CAL_RECORD or not reply.payload or reply.payload[0] != P.RECORD_PRESENT:
            verified = False
            notes.append("the device reports no calibration record after the write")
        else:
            raw = reply.payload[1:]
            verified = raw == record_bytes
            try:
                back = P.CalibrationRecord.from_bytes(raw)
            except DeviceError as exc:
                notes.append(f"read back: {exc}")
                back = None
            if back is not None:
                readback = [
                    FlashWrite(f"record: matrix row {axis}", _fmt(back.matrix[i]), _fmt(intended.matrix[i]),
                               "same" if np.array_equal(back.matrix[i], intended.matrix[i]) else "DIFFERS")
                    for i, axis in enumerate("xyz")
                ] + [
                    FlashWrite("record: bias b", _fmt(back.bias), _fmt(intended.bias),
                               "same" if np.array_equal(back.bias, intended.bias) else "DIFFERS"),
                    FlashWrite("record: CRC-16", f"0x{int.from_bytes(raw[-2:], 'big'):04X}",
                               f"0x{int.from_bytes(record_bytes[-2:], 'big'):04X}", "stored vs computed"),
                ]
            if not verified:
                diff = sum(a != b for a, b in zip(raw, record_bytes, strict=True)) + abs(len(raw) - len(record_bytes))
                notes.append(f"read back differs from what was written in {diff} byte(s)")
        return FlashReport(device=plan.device, verified=verified, readback=readback, residual=plan.residual,
                           notes=notes)


def _fmt(values) -> str:
    """float32 values in full (9 significant digits round-trip a float32)."""
    return "[" + ", ".join(f"{v:.9g}" for v in np.asarray(values, dtype=float).ravel()) + "]"
