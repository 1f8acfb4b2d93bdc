"""The accelrig wire protocol spoken by serial and BLE firmware (docs/wire-protocol.md).

A frame *body* is

    version u8 | type u8 | payload ... | crc16 (big-endian)

where crc16 is CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF, no reflection,
``binascii.crc_hqx(data, 0xFFFF)``) over version, type and payload.  All
multi-byte payload fields are little-endian (what an ESP32 or an ARM MCU has
in memory).

* On serial the body is COBS-encoded and followed by one 0x00 delimiter, so a
  receiver that starts mid-stream or meets garbage resynchronises at the next
  0x00 (COBS guarantees that no 0x00 occurs inside an encoded frame).
* On BLE each notification carries exactly one body, unencoded (the
  notification already delimits it); the CRC still catches truncation by a
  too small MTU.

The host counts everything that goes wrong (CRC errors, broken COBS,
oversized frames, unknown versions, lost / late / duplicate data frames by
sequence number) and turns sample-counter jumps into gaps.  Nothing is
repaired silently.
"""

from __future__ import annotations

import binascii
import re
import struct
from dataclasses import dataclass

import numpy as np

from accelrig.errors import DeviceError

PROTOCOL_VERSION = 1

# Host -> device
GET_IDENTITY = 0x01
CONFIGURE = 0x02
START = 0x03
STOP = 0x04
CAL_WRITE = 0x05
CAL_READ = 0x06
# Device -> host
IDENTITY = 0x81
CONFIG = 0x82
ACK = 0x83
CAL_RECORD = 0x84
DATA = 0x90

FRAME_NAMES = {
    GET_IDENTITY: "GET_IDENTITY", CONFIGURE: "CONFIGURE", START: "START", STOP: "STOP",
    CAL_WRITE: "CAL_WRITE", CAL_READ: "CAL_READ", IDENTITY: "IDENTITY", CONFIG: "CONFIG",
    ACK: "ACK", CAL_RECORD: "CAL_RECORD", DATA: "DATA",
}

# ACK status codes
STATUS_OK = 0
STATUS_BAD_FRAME = 1      # CRC / length error in the command
STATUS_UNSUPPORTED = 2    # frame type or version not implemented
STATUS_BAD_VALUE = 3      # e.g. a range the chip does not have
STATUS_STORAGE_ERROR = 4  # the calibration record could not be stored
STATUS_NAMES = {0: "ok", 1: "bad frame", 2: "unsupported", 3: "bad value", 4: "storage error"}

# CAL_RECORD status
RECORD_PRESENT = 0
RECORD_EMPTY = 1

CAPABILITY_CAL_STORE = 0x0001  # the device keeps a calibration record

# DATA: version, type, seq u32, counter u32 (first sample), device time u64 (us, first sample), n u16
DATA_HEADER = struct.Struct("<BBIIQH")
DATA_HEADER_SIZE = DATA_HEADER.size  # 20
SAMPLE_SIZE = 6                     # 3 x int16 little-endian
CRC_SIZE = 2
BLE_MAX_PAYLOAD = 244               # ATT MTU 247 - 3
SAMPLES_PER_BLE_FRAME = (BLE_MAX_PAYLOAD - DATA_HEADER_SIZE - CRC_SIZE) // SAMPLE_SIZE  # 37
MAX_BODY = 4096                     # anything longer is garbage by definition
_U32 = 1 << 32

CONFIG_PAYLOAD = struct.Struct("<BIH")     # range_g, rate in mHz, samples per frame
IDENTITY_HEAD = struct.Struct("<HH")       # capabilities, max samples per frame
ACK_PAYLOAD = struct.Struct("<BB")         # acked type, status


def crc16(data: bytes) -> int:
    """CRC-16/CCITT-FALSE (check value 0x29B1 for b"123456789")."""
    return binascii.crc_hqx(data, 0xFFFF)


# ---------------------------------------------------------------- COBS


def cobs_encode(data: bytes) -> bytes:
    """Consistent Overhead Byte Stuffing: the result contains no 0x00."""
    out = bytearray()
    for segment in bytes(data).split(b"\x00"):
        while len(segment) >= 254:
            out.append(0xFF)
            out += segment[:254]
            segment = segment[254:]
        out.append(len(segment) + 1)
        out += segment
    return bytes(out)


_NOT_ONE = re.compile(b"[^\x01]")


def cobs_decode(data: bytes) -> bytes:
    """Inverse of cobs_encode; raises ValueError on a malformed frame.

    This is the parser's hot loop, so it does not copy block by block: the
    decoded frame is the encoded one with the first code byte removed and
    every later code byte replaced by the zero it stands for (or removed,
    after a full 0xFF block, which implies no zero).  Only the walk along
    the chain of code bytes runs in Python, a few operations per zero byte
    of the frame.
    """
    n = len(data)
    if n == 0:
        return b""
    if b"\x00" in data:
        raise ValueError("zero byte inside a COBS frame")
    out = bytearray(data)
    removed = None
    i = 0
    while True:
        code = data[i]
        if code == 1 and i + 1 < n and data[i + 1] == 1:
            # A run of empty blocks (consecutive zeros in the body, e.g. small or
            # zero samples): each 0x01 is followed by the next code, which
            # stands for a zero.  One regex search replaces the per-block walk.
            m = _NOT_ONE.search(data, i)
            stop = m.start() if m else n
            out[i + 1:stop + 1] = bytes(min(stop + 1, n) - i - 1)
            if stop >= n:
                j = n
                break
            i = stop
            continue
        j = i + code
        if j >= n:
            break
        if code == 0xFF:
            if removed is None:
                removed = []
            removed.append(j)
        else:
            out[j] = 0
        i = j
    if j > n:
        raise ValueError("COBS block runs past the end of the frame")
    if removed:
        for j in reversed(removed):
            del out[j]
    del out[0]
    return bytes(out)


# ---------------------------------------------------------------- bodies


def make_body(frame_type: int, payload: bytes = b"", version: int = PROTOCOL_VERSION) -> bytes:
    head = bytes((version, frame_type)) + payload
    return head + crc16(head).to_bytes(2, "big")


def encode_frame(frame_type: int, payload: bytes = b"") -> bytes:
    """A complete serial frame: COBS(body) + 0x00."""
    return cobs_encode(make_body(frame_type, payload)) + b"\x00"


def data_payload(seq: int, counter: int, device_time_us: int, counts: np.ndarray) -> bytes:
    """Payload of a DATA frame (everything after version and type)."""
    counts = np.ascontiguousarray(counts, dtype="<i2")
    n = counts.shape[0]
    return DATA_HEADER.pack(0, 0, seq % _U32, counter % _U32, device_time_us, n)[2:] + counts.tobytes()


@dataclass(slots=True)
class Frame:
    """A non-data frame that passed its CRC."""

    type: int
    payload: bytes


@dataclass(slots=True)
class DataFrame:
    """One DATA frame: ``counts`` (n, 3) int16, first sample's counter and device time."""

    seq: int
    counter: int
    device_time_us: int
    counts: np.ndarray


@dataclass
class LinkStats:
    """Everything the link got wrong, counted.  Shown by drivers in DeviceInfo.link_stats."""

    bytes_in: int = 0
    frames: int = 0
    data_frames: int = 0
    samples: int = 0
    crc_errors: int = 0
    cobs_errors: int = 0
    length_errors: int = 0     # too short, too long, or n disagreeing with the length
    version_errors: int = 0
    discarded_bytes: int = 0   # bytes thrown away while resynchronising
    lost_frames: int = 0       # data frames never received (by sequence number)
    late_frames: int = 0       # arrived after their place was declared lost (dropped, counted)
    duplicate_frames: int = 0
    lost_samples: int = 0      # samples missing by the device counter
    unknown_gaps: int = 0      # gaps of unknown size (device restarted, reconnect with reset)
    restarts: int = 0
    reconnects: int = 0

    def as_dict(self) -> dict:
        return dict(self.__dict__)


def decode_body(body: bytes, stats: LinkStats) -> Frame | DataFrame | None:
    """Check a frame body (CRC, version, length) and decode it; None (and counted) if bad."""
    size = len(body)
    if size < 4:
        stats.length_errors += 1
        return None
    if crc16(body[:-2]) != (body[-2] << 8 | body[-1]):
        stats.crc_errors += 1
        return None
    if body[0] != PROTOCOL_VERSION:
        stats.version_errors += 1
        return None
    stats.frames += 1
    frame_type = body[1]
    if frame_type != DATA:
        return Frame(frame_type, bytes(body[2:-2]))
    if size < DATA_HEADER_SIZE + CRC_SIZE:
        stats.length_errors += 1
        return None
    _, _, seq, counter, time_us, n = DATA_HEADER.unpack_from(body)
    if size != DATA_HEADER_SIZE + SAMPLE_SIZE * n + CRC_SIZE:
        stats.length_errors += 1
        return None
    counts = np.frombuffer(body, dtype="<i2", count=3 * n, offset=DATA_HEADER_SIZE).reshape(n, 3)
    stats.data_frames += 1
    stats.samples += n
    return DataFrame(seq, counter, time_us, counts)


class FrameParser:
    """Streaming parser for the serial byte stream: feed any chunks, get whole frames.

    Resynchronises at every 0x00 delimiter; a frame broken by garbage, a lost
    byte or a flipped bit fails COBS or CRC and is counted, never returned.
    Memory is bounded: a run of bytes with no delimiter longer than a frame
    can be is discarded (and counted).
    """

    def __init__(self, stats: LinkStats | None = None, max_body: int = MAX_BODY):
        self.stats = stats or LinkStats()
        self.max_encoded = max_body + max_body // 254 + 2
        self._tail = b""

    def feed(self, data: bytes) -> list[Frame | DataFrame]:
        stats = self.stats
        stats.bytes_in += len(data)
        if self._tail:
            data = self._tail + data
        parts = data.split(b"\x00")
        tail = parts.pop()
        if len(tail) > self.max_encoded:  # no delimiter for too long: garbage
            stats.discarded_bytes += len(tail)
            stats.length_errors += 1
            tail = b""
        self._tail = tail
        frames = []
        append = frames.append
        for part in parts:
            if not part:
                continue  # consecutive delimiters: a sender may flush with 0x00
            if len(part) > self.max_encoded:
                stats.length_errors += 1
                stats.discarded_bytes += len(part)
                continue
            try:
                body = cobs_decode(part)
            except ValueError:
                stats.cobs_errors += 1
                stats.discarded_bytes += len(part)
                continue
            frame = decode_body(body, stats)
            if frame is None:
                stats.discarded_bytes += len(part)
            else:
                append(frame)
        return frames


def _forward(a: int, b: int) -> int:
    """Signed distance from a to b on a 32-bit wrapping counter."""
    d = (b - a) % _U32
    return d - _U32 if d >= _U32 // 2 else d


class DataSequencer:
    """Orders DATA frames by sequence number and turns counter jumps into counted gaps.

    ``reorder_window`` frames may wait for a missing predecessor (BLE can
    reorder notifications; serial cannot, so it uses 0).  With a window, the
    stream starts at the older of its first two frames, so a frame that
    overtakes the very first one does not start it (one frame's wait, not
    the window's: at low rates a window of frames is seconds).  A frame that
    arrives after its predecessor was declared lost is dropped and counted as
    late: samples are never inserted into the past.  ``push`` returns
    ``[(frame, first_counter, gap_before)]`` in order: ``first_counter`` is
    the device counter of the frame's first sample without 32-bit wrap, and
    ``gap_before`` the samples missing before it by the device counter
    (-1: unknown, because the device restarted and its counter went back).

    The firmware keeps counting across reconnects (the counter is samples
    since boot), so the gap a reconnect leaves is measured, not guessed.
    """

    def __init__(self, stats: LinkStats, reorder_window: int = 0):
        self.stats = stats
        self.window = reorder_window
        self.late_horizon = max(4 * reorder_window, 16)  # further back than this is a restart
        self._pending: dict[int, DataFrame] = {}
        self._next_seq: int | None = None
        self._origin = 0                       # first sequence number of this stream
        self._next_counter: int | None = None  # unwrapped counter expected next
        self._device_next = 0                  # the same as the device's 32-bit counter
        self._skipped: dict[int, None] = {}    # recently declared lost (ordered, bounded)

    @property
    def next_seq(self) -> int | None:
        """The sequence number expected next (None before the first frame)."""
        return self._next_seq

    @property
    def next_counter(self) -> int | None:
        """The unwrapped device counter expected next (None before the first frame is placed)."""
        return self._next_counter

    def push(self, frame: DataFrame) -> list[tuple[DataFrame, int, int]]:
        stats = self.stats
        if self._next_seq is None:   # not started: wait for a frame the first one may have overtaken
            if frame.seq in self._pending:
                stats.duplicate_frames += 1
                return []
            self._pending[frame.seq] = frame
            return self._release()
        ahead = _forward(self._next_seq, frame.seq)
        if ahead < 0:
            if -ahead > self.late_horizon:  # far behind: the device restarted
                stats.restarts += 1
                out = self.flush()
                self._next_seq = None   # a new stream: it starts as the first one did
                self._pending[frame.seq] = frame
                return out + self._release()
            if frame.seq in self._skipped:
                # It was declared lost; now it is late instead (and still dropped).
                del self._skipped[frame.seq]
                stats.late_frames += 1
                stats.lost_frames -= 1
            elif _forward(self._origin, frame.seq) < 0:
                stats.late_frames += 1  # older than the frame the stream began with
            else:
                stats.duplicate_frames += 1
            return []
        if frame.seq in self._pending:
            stats.duplicate_frames += 1
            return []
        self._pending[frame.seq] = frame
        return self._release()

    def flush(self) -> list[tuple[DataFrame, int, int]]:
        """Stop waiting for anything missing (a reconnect, the end of the stream)."""
        out = []
        while self._pending:
            if self._next_seq is None:
                self._start_at_oldest()
            self._skip_to_oldest()
            out += self._release()
        return out

    def lose_tail(self, next_seq: int, device_next: int) -> int:
        """The stream ended: the device numbered its frames up to ``next_seq`` (exclusive) and its
        sample counter reached ``device_next``.  The frames after the last one received never came:
        they are counted lost, and the samples they held are returned (0: nothing is missing, or
        nothing was received to measure from).  Only a device that says where it stopped can tell;
        call ``flush`` first."""
        if self._next_seq is None or self._next_counter is None:
            return 0
        frames = _forward(self._next_seq, next_seq % _U32)
        if frames <= 0:
            return 0
        samples = max(_forward(self._device_next, device_next % _U32), 0)
        self.stats.lost_frames += frames
        self.stats.lost_samples += samples
        self._next_seq = next_seq % _U32
        self._next_counter += samples
        self._device_next = device_next % _U32
        return samples

    def _start_at_oldest(self) -> None:
        first = next(iter(self._pending))   # the first to arrive: the others are near it, either side
        self._next_seq = self._origin = min(self._pending, key=lambda s: _forward(first, s))

    def _skip_to_oldest(self) -> None:
        oldest = min(self._pending, key=lambda s: _forward(self._next_seq, s))
        missing = _forward(self._next_seq, oldest)
        self.stats.lost_frames += missing
        for k in range(max(missing - self.late_horizon, 0), missing):
            self._skipped[(self._next_seq + k) % _U32] = None
        while len(self._skipped) > self.late_horizon:
            del self._skipped[next(iter(self._skipped))]
        self._next_seq = oldest

    def _release(self) -> list[tuple[DataFrame, int, int]]:
        out = []
        while True:
            if self._next_seq is None:
                if len(self._pending) <= min(self.window, 1):
                    return out
                self._start_at_oldest()
            frame = self._pending.pop(self._next_seq, None)
            if frame is None:
                if len(self._pending) > self.window:
                    self._skip_to_oldest()
                    continue
                return out
            self._next_seq = (self._next_seq + 1) % _U32
            out.append(self._place(frame))

    def _place(self, frame: DataFrame) -> tuple[DataFrame, int, int]:
        n = frame.counts.shape[0]
        if self._next_counter is None:
            first, gap = frame.counter, 0
        else:
            jump = _forward(self._device_next, frame.counter)
            if jump >= 0:
                first, gap = self._next_counter + jump, jump
                self.stats.lost_samples += jump
            else:  # the counter went back: the device reset; the gap's size is unknown
                first, gap = self._next_counter, -1
                self.stats.unknown_gaps += 1
        self._next_counter = first + n
        self._device_next = (frame.counter + n) % _U32
        return frame, first, gap


# ---------------------------------------------------------------- other payloads


@dataclass
class Identity:
    chip: str
    serial: str
    firmware: str
    capabilities: int = 0
    max_samples_per_frame: int = 0

    def payload(self) -> bytes:
        out = IDENTITY_HEAD.pack(self.capabilities, self.max_samples_per_frame)
        for text in (self.chip, self.serial, self.firmware):
            raw = text.encode("utf-8")[:255]
            out += bytes((len(raw),)) + raw
        return out

    @classmethod
    def from_payload(cls, payload: bytes) -> Identity:
        try:
            caps, max_n = IDENTITY_HEAD.unpack_from(payload)
            pos = IDENTITY_HEAD.size
            texts = []
            for _ in range(3):
                size = payload[pos]
                texts.append(payload[pos + 1:pos + 1 + size].decode("utf-8"))
                pos += 1 + size
                if pos > len(payload):
                    raise ValueError("truncated")
        except (struct.error, IndexError, ValueError, UnicodeDecodeError) as exc:
            raise DeviceError(f"the device sent a malformed IDENTITY frame ({exc})",
                              "is its firmware speaking accelrig protocol version 1?") from None
        return cls(texts[0], texts[1], texts[2], caps, max_n)


@dataclass
class LinkConfig:
    range_g: int
    rate: float           # Hz
    samples_per_frame: int

    def payload(self) -> bytes:
        return CONFIG_PAYLOAD.pack(self.range_g, int(round(self.rate * 1000)), self.samples_per_frame)

    @classmethod
    def from_payload(cls, payload: bytes) -> LinkConfig:
        if len(payload) != CONFIG_PAYLOAD.size:
            raise DeviceError(f"the device sent a CONFIG frame of {len(payload)} bytes, expected {CONFIG_PAYLOAD.size}")
        range_g, rate_mhz, n = CONFIG_PAYLOAD.unpack(payload)
        return cls(range_g, rate_mhz / 1000.0, n)


# ---------------------------------------------------------------- calibration record

# record_version u8, range_g u8, reserved u16, C[9] f32, b[3] f32 (m/s^2),
# u(C)[9] f32, u(b)[3] f32, profile id 8 bytes, written (unix s) u32, then crc16 (big-endian)
CAL_RECORD_VERSION = 1
_CAL_LAYOUT = struct.Struct("<BBH9f3f9f3f8sI")
CAL_RECORD_SIZE = _CAL_LAYOUT.size + CRC_SIZE


@dataclass
class CalibrationRecord:
    """The full canonical correction as a firmware device stores it (float32)."""

    range_g: int
    matrix: np.ndarray          # (3, 3)
    bias: np.ndarray            # (3,), m/s^2
    matrix_uncertainty: np.ndarray
    bias_uncertainty: np.ndarray
    profile_id: bytes           # 8 bytes: identifies the profile it came from
    written: int                # unix time, s

    def to_bytes(self) -> bytes:
        head = _CAL_LAYOUT.pack(
            CAL_RECORD_VERSION, int(self.range_g), 0,
            *np.asarray(self.matrix, float).ravel(), *np.asarray(self.bias, float).ravel(),
            *np.asarray(self.matrix_uncertainty, float).ravel(), *np.asarray(self.bias_uncertainty, float).ravel(),
            bytes(self.profile_id)[:8].ljust(8, b"\x00"), int(self.written),
        )
        return head + crc16(head).to_bytes(2, "big")

    @classmethod
    def from_bytes(cls, raw: bytes) -> CalibrationRecord:
        if len(raw) != CAL_RECORD_SIZE:
            raise DeviceError(f"calibration record of {len(raw)} bytes, expected {CAL_RECORD_SIZE}")
        if crc16(raw[:-2]) != int.from_bytes(raw[-2:], "big"):
            raise DeviceError("the calibration record stored on the device fails its CRC",
                              "flash the profile again; if it persists the device's storage is faulty")
        v = _CAL_LAYOUT.unpack(raw[:-2])
        if v[0] != CAL_RECORD_VERSION:
            raise DeviceError(f"calibration record version {v[0]} is not supported (expected {CAL_RECORD_VERSION})")
        return cls(
            range_g=v[1], matrix=np.array(v[3:12]).reshape(3, 3), bias=np.array(v[12:15]),
            matrix_uncertainty=np.array(v[15:24]).reshape(3, 3), bias_uncertainty=np.array(v[24:27]),
            profile_id=v[27], written=v[28],
        )

    @classmethod
    def from_correction(cls, correction, range_g: int, profile_id: bytes, written: int) -> CalibrationRecord:
        return cls(int(range_g), correction.matrix, correction.bias, correction.matrix_uncertainty,
                   correction.bias_uncertainty, profile_id, written)

    def as_float32(self) -> CalibrationRecord:
        """What the device will hold after the float32 round trip."""
        return CalibrationRecord.from_bytes(self.to_bytes())
