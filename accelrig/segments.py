"""Recordings streamed to disk in segments: bounded memory for any duration, nothing lost to a crash.

API (stable: ``accelrig record`` and the daemon build on it)

``SegmentWriter(directory, *, stem, meta, scale, channels=(), segment_seconds=3600.0,
segment_bytes=256 MiB, csv=False, fsync_seconds=5.0, finisher=None)``
    ``.write(t, counts, channels=None)``  one block: ``t`` float64 seconds in the caller's time base
        (UTC epoch seconds in ``record`` and the daemon; int64 is taken as nanoseconds),
        ``counts`` int16 (n, 3), ``channels`` {name: float64 (n,)} for the names given at creation.
    ``.gap(t, samples, cause, seconds=None)``  a gap record: ``samples`` missing (-1: unknown)
        from time ``t`` on, ``cause`` in words ("disconnect", "fifo overflow", "disk full", ...).
    ``.close() -> list[Path]``  finishes the open segment; returns every segment this writer finished.
    ``.samples_written``, ``.bytes_written``, ``.segments_finished``, ``.open_path``, ``.pending``.
    Disk full (ENOSPC, EDQUOT) raises ``accelrig.errors.StorageFull`` and leaves the writer
    consistent: the block is either wholly in the open segment or not at all, so the caller can
    count it as a "disk full" gap and call ``write`` again later.
    A rotated segment is finished (turned into Parquet) in ``write``'s thread, or, with a
    ``finisher``, by that Finisher's thread; ``close`` finishes what is left in the caller's thread.
``Finisher(log=None)``  one thread that finishes the segments rotated by any number of writers,
    one at a time (the daemon's devices share one): a device's loop never waits for a
    conversion, and the conversions' memory is one segment's row group, not one per device.
    Creating it pays pyarrow's one-time costs (import, lazily built tables: about 50 MB of
    resident memory) at once, so they show at start rather than at the first rotation.
    ``.close(timeout)`` stops the thread.
``recover(directory) -> list[RecoveryReport]``  finishes segments a crash (kill -9, power cut)
    left open, up to their last complete block, each report saying what was lost.
``read_arrays(path, start=None, stop=None, stem=None, units="m/s^2")``  the arrays of a segment
    file or a directory of one device's segments over [start, stop) (stored time base, seconds):
    ``(t, acc, units, channels, meta)``, what ``accelrig.recording.Recording`` is built from.
    ``accelrig.recording.read_segments`` returns that Recording, and ``load_recording`` dispatches
    here for a directory or a ``.parquet`` / ``.seg`` file, so every reader takes segments.

Files, in one directory per device (one ``stem``):

* ``STEM.NNNNNN[.YYYYmmddTHHMMSSZ].seg``: the open segment, append-only.  An 8-byte file magic,
  then frames: ``<4s magic, u8 kind, 3 pad, u32 length, u32 crc32>`` + payload, the crc
  covering kind, length and payload.  Kinds: header (JSON), data (``u32 n``, int64 ns times,
  int16 counts (n, 3), float64 per channel), gap (JSON).  Each frame goes to the file in one
  ``write`` of unbuffered I/O, so a ``kill -9`` leaves every complete frame readable; a torn
  last frame fails its length or crc and is the only thing lost.
* ``STEM.NNNNNN[...].parquet``: a finished segment, written beside as a temporary file, synced
  and renamed into place (whole or absent).  Columns ``time`` (timestamp, ns, delta encoded),
  ``ax ay az`` (int16 counts), one float64 column per channel; the key ``accelrig`` of the file's
  metadata holds JSON: scale (m/s^2 per count), device identity, range, rates, the time base,
  gap records, sample count and first/last times.  pandas (``read_parquet``) and pyarrow read it
  without accelrig.
* ``.lock``: held (``fcntl.flock``) by the one process writing into the directory, with its pid and
  command line; a second writer is refused naming it.  The kernel releases it when the writer exits,
  however (kill -9 included), so a stale file never blocks the next one; a clean close removes it.
"""

from __future__ import annotations

import errno
import fcntl
import json
import os
import re
import struct
import threading
import time
import zlib
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from accelrig.errors import DataError, StorageError, StorageFull, printable
from accelrig.files import META_PREFIX, fsync_directory
from accelrig.result import to_json

FILE_MAGIC = b"ACCSEG1\n"
FRAME = struct.Struct("<4sB3xII")   # magic, kind, length, crc32(kind + length + payload)
FRAME_MAGIC = b"ASF1"
HEADER, DATA, GAP = 1, 2, 3
OPEN_SUFFIX = ".seg"
FINISHED_SUFFIX = ".parquet"
SEGMENT_SUFFIXES = (OPEN_SUFFIX, FINISHED_SUFFIX)
FORMAT = "accelrig-segment"
FORMAT_VERSION = 1
META_KEY = b"accelrig"
ROW_GROUP = 1 << 17                 # samples per Parquet row group (and per read when finishing): 64 s at 2048 Hz
NS = 1_000_000_000
STEM_PATTERN = re.compile(r"[A-Za-z0-9][A-Za-z0-9_-]*")
NAME_PATTERN = re.compile(r"^(?P<stem>[A-Za-z0-9][A-Za-z0-9_-]*)\.(?P<index>\d{6})(?:\.(?P<stamp>\d{8}T\d{6}Z))?"
                          r"(?P<suffix>\.seg|\.parquet)$")
FULL_ERRNOS = (errno.ENOSPC, errno.EDQUOT)
LOCK_NAME = ".lock"
RESERVED_COLUMNS = ("time", "ax", "ay", "az")


def to_ns(t) -> np.ndarray:
    """Seconds (float) to int64 nanoseconds, rounded to the nearest ns without float64's
    loss at epoch magnitudes (whole seconds and the fraction are converted apart); int64
    input is taken as nanoseconds already."""
    t = np.asarray(t)
    if t.dtype.kind in "iu":
        return t.astype(np.int64)
    t = t.astype(np.float64)
    whole = np.floor(t)
    return whole.astype(np.int64) * NS + np.round((t - whole) * NS).astype(np.int64)


def ns_to_seconds(ns) -> np.ndarray:
    """int64 nanoseconds to float seconds, the inverse of ``to_ns`` (exact for float64 epoch times)."""
    ns = np.asarray(ns, dtype=np.int64)
    whole, frac = np.divmod(ns, NS)
    return whole.astype(np.float64) + frac.astype(np.float64) / NS


def _utc_stamp(ns: int) -> str:
    return time.strftime("%Y%m%dT%H%M%SZ", time.gmtime(ns // NS))


def _iso(ns: int) -> str:
    return time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime(ns // NS))


# --------------------------------------------------------------------------- frames


def _frame(kind: int, payload: bytes) -> bytes:
    head = struct.pack("<BI", kind, len(payload))
    return FRAME.pack(FRAME_MAGIC, kind, len(payload), zlib.crc32(payload, zlib.crc32(head))) + payload


def _data_payload(t_ns: np.ndarray, counts: np.ndarray, channels: list[np.ndarray]) -> bytes:
    parts = [struct.pack("<I", t_ns.size), t_ns.astype("<i8").tobytes(), counts.astype("<i2").tobytes()]
    parts += [np.asarray(c, dtype="<f8").tobytes() for c in channels]
    return b"".join(parts)


@dataclass
class Scan:
    """What the complete frames of an open segment hold."""

    path: Path
    header: dict
    data: list[tuple[int, int]] = field(default_factory=list)   # (payload offset, samples) per data frame
    gaps: list[dict] = field(default_factory=list)
    samples: int = 0
    first_ns: int | None = None
    last_ns: int | None = None
    end: int = 0                  # offset after the last complete frame
    size: int = 0                 # file size
    lost_samples: int | None = 0  # samples in the torn last frame, when its header says (None: unknown)
    problem: str | None = None    # why the scan stopped before the end of the file
    starts: np.ndarray | None = None   # the sample index each data frame starts at (built when reading)

    @property
    def lost_bytes(self) -> int:
        return self.size - self.end


def scan(path: str | os.PathLike) -> Scan:
    """Walk an open segment's frames, checking each crc; stops at the first incomplete or bad one."""
    path = Path(path)
    try:
        with open(path, "rb") as fh:
            if fh.read(len(FILE_MAGIC)) != FILE_MAGIC:
                raise DataError(f"{path}: not an accelrig open segment (wrong magic)")
            size = os.fstat(fh.fileno()).st_size
            header, offset, problem, n_torn = _next_frame(fh, len(FILE_MAGIC), size)
            if header is None or header[0] != HEADER:
                raise DataError(f"{path}: the segment header is incomplete or damaged ({problem or 'no header'})",
                                "the file holds no samples that can be read")
            result = Scan(path, json.loads(header[1]), end=offset, size=size)
            n_channels = len(result.header.get("channels", []))
            while True:
                start = offset
                frame, offset, problem, n_torn = _next_frame(fh, offset, size, keep_data=False)
                if frame is None:
                    result.problem = problem
                    result.lost_samples = n_torn
                    break
                kind, payload = frame
                if kind == DATA:
                    n = struct.unpack_from("<I", payload)[0]
                    if len(payload) != 4 + n * (8 + 6 + 8 * n_channels):
                        result.problem = f"a data frame at byte {start} has the wrong length"
                        result.lost_samples = None
                        break
                    t_ns = np.frombuffer(payload, "<i8", n, 4)
                    result.data.append((start + FRAME.size, n))
                    if n:
                        result.first_ns = int(t_ns[0]) if result.first_ns is None else result.first_ns
                        result.last_ns = int(t_ns[-1])
                    result.samples += n
                elif kind == GAP:
                    result.gaps.append(json.loads(payload))
                result.end = offset
            return result
    except FileNotFoundError:
        raise DataError(f"{path}: no such file") from None
    except OSError as exc:
        raise DataError(f"{path}: cannot read ({exc.strerror})") from None


def _next_frame(fh, offset: int, size: int, keep_data: bool = True):
    """(kind, payload) of the frame at ``offset`` and the offset after it, or (None, offset, why, torn samples)."""
    fh.seek(offset)
    head = fh.read(FRAME.size)
    if not head:
        return None, offset, None, 0
    if len(head) < FRAME.size:
        return None, offset, "the last frame's header is incomplete", None
    magic, kind, length, crc = FRAME.unpack(head)
    if magic != FRAME_MAGIC:
        return None, offset, f"no frame at byte {offset} (damaged)", None
    payload = fh.read(length)
    if len(payload) < length:
        torn = struct.unpack_from("<I", payload)[0] if kind == DATA and len(payload) >= 4 else None
        return None, offset, "the last frame is incomplete (the writer stopped mid-block)", torn
    if zlib.crc32(payload, zlib.crc32(struct.pack("<BI", kind, length))) != crc:
        torn = struct.unpack_from("<I", payload)[0] if kind == DATA and length >= 4 else None
        return None, offset, f"the frame at byte {offset} fails its checksum", torn
    return (kind, payload), offset + FRAME.size + length, None, 0


def _read_scanned(scanned: Scan, lo: int, hi: int):
    """Samples [lo, hi) of a scanned open segment: (t_ns, counts, channels list)."""
    names = scanned.header.get("channels", [])
    parts_t, parts_c, parts_ch = [], [], [[] for _ in names]
    if scanned.starts is None or len(scanned.starts) != len(scanned.data):
        scanned.starts = np.cumsum([0] + [n for _, n in scanned.data])
    first = max(int(np.searchsorted(scanned.starts, lo, "right")) - 1, 0)   # the frame holding sample lo
    position = int(scanned.starts[first]) if scanned.data else 0
    with open(scanned.path, "rb") as fh:
        for offset, n in scanned.data[first:]:
            if position >= hi:
                break
            if position + n <= lo or not n:
                position += n
                continue
            fh.seek(offset + 4)
            raw = fh.read(n * (14 + 8 * len(names)))
            a, b = max(lo - position, 0), min(hi - position, n)
            parts_t.append(np.frombuffer(raw, "<i8", n)[a:b])
            parts_c.append(np.frombuffer(raw, "<i2", n * 3, 8 * n).reshape(n, 3)[a:b])
            for k in range(len(names)):
                parts_ch[k].append(np.frombuffer(raw, "<f8", n, 14 * n + 8 * n * k)[a:b])
            position += n
    cat = (lambda parts, empty: np.concatenate(parts) if parts else empty)
    return (cat(parts_t, np.empty(0, np.int64)), cat(parts_c, np.empty((0, 3), np.int16)),
            [cat(p, np.empty(0)) for p in parts_ch])


# --------------------------------------------------------------------------- writer


class DirectoryLock:
    """The one writer of a directory of segments: ``DIR/.lock``, flock'ed while held, naming its holder.

    Two writers in one directory interleave segments that overlap in time (each at its own rate), and then
    no reader can use the directory; the second is refused instead, naming the first (pid, command).
    """

    def __init__(self, directory: str | os.PathLike):
        import sys

        self.path = Path(directory) / LOCK_NAME
        while True:
            try:
                fd = os.open(self.path, os.O_RDWR | os.O_CREAT | getattr(os, "O_CLOEXEC", 0), 0o644)
            except OSError as exc:
                raise _storage_error(exc, self.path) from None
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                holder = os.read(fd, 4096).decode("utf-8", "replace").strip()
                os.close(fd)
                raise StorageError(f"{self.path.parent}: another process is recording into it"
                                   + (f" (pid {printable(holder)})" if holder else "")
                                   + ": refusing to write a second recording among its segments",
                                   "record into another directory, or stop that process first") from None
            # the holder may have removed the file between our open and our lock: then hold the new one
            try:
                same = os.fstat(fd).st_ino == os.stat(self.path).st_ino
            except FileNotFoundError:
                same = False
            if same:
                break
            os.close(fd)
        os.ftruncate(fd, 0)
        os.write(fd, f"{os.getpid()}: {' '.join(sys.argv)[:400]}\n".encode())
        self._fd: int | None = fd

    def release(self) -> None:
        if self._fd is None:
            return
        self.path.unlink(missing_ok=True)   # removed while still held: the next writer opens a fresh file
        os.close(self._fd)
        self._fd = None


class SegmentWriter:
    """Streams blocks into rotating segments in ``directory``; see the module docstring.

    It holds the directory's lock (DirectoryLock) from construction to ``close``.
    """

    def __init__(self, directory: str | os.PathLike, *, stem: str, meta: dict, scale: float,
                 channels: tuple[str, ...] | list[str] = (), segment_seconds: float = 3600.0,
                 segment_bytes: int = 256 * 2**20, csv: bool = False, fsync_seconds: float = 5.0,
                 finisher: Finisher | None = None):
        if not STEM_PATTERN.fullmatch(stem):
            raise DataError(f"segment name {stem!r} must be letters, digits, '-' or '_', starting with a letter "
                            "or digit")
        bad = [c for c in channels if c in RESERVED_COLUMNS]
        if bad:
            raise DataError(f"channel name(s) {', '.join(bad)} clash with the columns {', '.join(RESERVED_COLUMNS)}")
        if not segment_seconds > 0 or not segment_bytes > 0:
            raise DataError("segment_seconds and segment_bytes must be positive")
        self.directory = Path(directory)
        try:
            self.directory.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise StorageError(f"{self.directory}: cannot create the output directory ({exc.strerror})",
                               "choose a directory you may write to") from None
        if not os.access(self.directory, os.W_OK | os.X_OK):
            raise StorageError(f"{self.directory}: the output directory is not writable",
                               "choose a directory you may write to, or fix its permissions")
        self._dir_lock = DirectoryLock(self.directory)   # a second writer is refused here
        self.stem = stem
        self.meta = dict(meta)
        self.meta.setdefault("time_base", "utc")
        self.scale = float(scale)
        self.channels = tuple(channels)
        self.segment_ns = int(min(segment_seconds, 1e9) * NS)
        self.segment_bytes = int(min(segment_bytes, 2**62))
        self.csv = csv
        self.fsync_seconds = fsync_seconds
        self.finisher = finisher
        self._pending_lock = threading.Lock()   # pending and _finished (the finisher's thread changes them)
        self._finishing = threading.Lock()      # held while one of this writer's segments is converted
        try:
            self._index = _next_index(self.directory, stem)
        except BaseException:
            # no writer came of it: a lock kept would refuse this process's own next writer (a daemon's
            # reconnect) for as long as it runs
            self._dir_lock.release()
            raise
        self._fd: int | None = None
        self.open_path: Path | None = None
        self._size = 0
        self._seg_first_ns: int | None = None
        self._seg_samples = 0
        self._last_ns: int | None = None
        self._last_sync = time.monotonic()
        self._finished: list[Path] = []
        self.pending: list[Path] = []   # closed segments not yet finished (disk full while converting)
        self.samples_written = 0
        self.bytes_written = 0

    @property
    def segments_finished(self) -> int:
        return len(self._finished)

    def __enter__(self) -> SegmentWriter:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # ----------------------------------------------------------------- data
    def write(self, t, counts, channels: dict | None = None) -> None:
        """Append one block: all of it in the open segment, or (StorageFull, other error) none of it."""
        counts = np.asarray(counts)
        if counts.dtype != np.int16 or counts.ndim != 2 or counts.shape[1] != 3:
            raise ValueError(f"counts must be int16 of shape (n, 3), got {counts.dtype} {counts.shape}")
        t_ns = to_ns(t)
        n = counts.shape[0]
        if t_ns.shape != (n,):
            raise ValueError("one time per sample")
        channels = channels or {}
        if set(channels) != set(self.channels):
            raise ValueError(f"channels {sorted(channels)} differ from the writer's {sorted(self.channels)}")
        if not n:
            return
        if np.any(np.diff(t_ns) <= 0) or (self._last_ns is not None and t_ns[0] <= self._last_ns):
            raise DataError(f"{self.stem}: sample times do not increase at {float(t_ns[0]) / NS:.9f} s",
                            "the writer stores blocks in time order; fix the time base")
        self._rotate_if_due(int(t_ns[0]))
        payload = _data_payload(t_ns, counts, [channels[name] for name in self.channels])
        self._append(_frame(DATA, payload), int(t_ns[0]))
        self._last_ns = int(t_ns[-1])
        self._seg_samples += n
        self.samples_written += n

    def gap(self, t, samples: int, cause: str, seconds: float | None = None) -> None:
        """Record ``samples`` missing (-1: unknown) from time ``t`` on, and why."""
        t_ns = int(to_ns(np.asarray([t]))[0])   # seconds, or int ns
        record = {"t_ns": t_ns, "samples": int(samples), "cause": str(cause),
                  "seconds": None if seconds is None else float(seconds)}
        self._rotate_if_due(t_ns)
        self._append(_frame(GAP, json.dumps(record).encode()), t_ns)

    def close(self) -> list[Path]:
        """Finish the open segment (and any left pending by a full disk); the finished paths."""
        try:
            if self._fd is not None:
                self._close_open()
            self._finish_pending()
        finally:
            # released even with a segment left pending by a full disk: it is closed, complete and readable,
            # and the next writer into the directory (the daemon's next connection) must not be refused
            self._dir_lock.release()
        return list(self._finished)

    # ----------------------------------------------------------------- internals
    def _rotate_if_due(self, t_ns: int) -> None:
        if self._fd is None:
            return
        if (self._seg_first_ns is not None and t_ns - self._seg_first_ns >= self.segment_ns) \
                or self._size >= self.segment_bytes:
            self._close_open()
            if self.finisher is not None:
                self.finisher.submit(self)
                return
            try:
                self._finish_pending()
            except StorageFull:
                pass  # the closed segment stays complete and readable as it is; finished at the next try

    def _open(self, t_ns: int) -> None:
        stamp = f".{_utc_stamp(t_ns)}" if self.meta.get("time_base") == "utc" else ""
        path = self.directory / f"{self.stem}.{self._index:06d}{stamp}{OPEN_SUFFIX}"
        header = {"format": FORMAT, "version": FORMAT_VERSION, "stem": self.stem, "index": self._index,
                  "scale": self.scale, "channels": list(self.channels), "meta": self.meta}
        data = FILE_MAGIC + _frame(HEADER, to_json(header, indent=None, sort_keys=True).encode())
        try:
            fd = os.open(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT | os.O_EXCL | getattr(os, "O_CLOEXEC", 0), 0o666)
        except OSError as exc:
            raise _storage_error(exc, path) from None
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)   # recover() leaves a segment being written alone
        try:
            _write_all(fd, data)
        except OSError as exc:
            os.close(fd)
            path.unlink(missing_ok=True)
            raise _storage_error(exc, path) from None
        self._fd, self.open_path, self._size = fd, path, len(data)
        self._seg_first_ns, self._seg_samples = None, 0
        self._index += 1
        fsync_directory(self.directory)
        self.bytes_written += len(data)

    def _append(self, frame: bytes, t_ns: int) -> None:
        if self._fd is None:
            self._open(t_ns)
        try:
            _write_all(self._fd, frame)
        except OSError as exc:
            # take the partial frame back out: the block is in the segment wholly or not at all
            try:
                os.ftruncate(self._fd, self._size)
            except OSError:
                # a torn tail fails its crc and ends the segment for every reader: the next
                # block starts a new segment rather than land behind it
                self._close_open()
            raise _storage_error(exc, self.open_path or self.pending[-1]) from None
        self._size += len(frame)
        self.bytes_written += len(frame)
        if self._seg_first_ns is None:
            self._seg_first_ns = t_ns
        if time.monotonic() - self._last_sync >= self.fsync_seconds:
            self._sync()

    def _sync(self) -> None:
        """Push the open segment to the disk (against power cuts; a crash of the process loses nothing
        written already).  Best effort: the block is in the file whatever fsync says, so a failure
        here must not be reported as a block not written; the next interval tries again."""
        try:
            os.fsync(self._fd)
        except OSError:
            pass
        self._last_sync = time.monotonic()

    def _close_open(self) -> None:
        fd, path = self._fd, self.open_path
        self._fd, self.open_path = None, None
        try:
            os.fsync(fd)
        except OSError:
            pass  # the data are in the page cache; finishing reads them back and syncs the result
        os.close(fd)
        with self._pending_lock:
            self.pending.append(path)

    def _finish_pending(self) -> None:
        """Finish the closed segments, oldest first (in this thread; one of the writer's segments at a
        time, whichever thread asks: ``close`` waits for a conversion the finisher has begun)."""
        with self._finishing:
            while True:
                with self._pending_lock:
                    if not self.pending:
                        return
                    path = self.pending[0]
                finished = finish_segment(path, csv=self.csv)   # StorageFull: stays pending
                with self._pending_lock:
                    self.pending.pop(0)
                    if finished is not None:
                        self._finished.append(finished)


class Finisher:
    """One thread finishing the segments that writers rotate, one conversion at a time.

    Writers built with ``finisher=`` hand it their closed segments instead of converting them in
    the thread that writes, so acquisition never waits for pyarrow, and however many writers
    rotate at the same moment, one conversion's memory is in use.  A conversion that fails (a
    full disk) leaves the segment pending, complete and readable; the writer's next rotation
    or its ``close`` tries again.
    """

    def __init__(self, log: Callable[[str], None] | None = None):
        self.log = log
        self._queue: deque[SegmentWriter] = deque()
        self._wake = threading.Condition()
        self._closed = False
        self._prepared = threading.Event()
        self._failed: BaseException | None = None
        self._thread = threading.Thread(target=self._run, name="accelrig segment finisher", daemon=True)
        self._thread.start()
        self._prepared.wait()
        if self._failed is not None:   # pyarrow missing or broken: said at start, not at the first rotation
            raise self._failed

    def submit(self, writer: SegmentWriter) -> None:
        with self._wake:
            if writer not in self._queue:
                self._queue.append(writer)
            self._wake.notify()

    def close(self, timeout: float | None = None) -> bool:
        """Stop the thread after the conversion under way (what is queued stays pending in its
        writer, whose ``close`` finishes it); True when the thread has ended."""
        with self._wake:
            self._closed = True
            self._wake.notify()
        self._thread.join(timeout)
        return not self._thread.is_alive()

    def _run(self) -> None:
        try:
            _prepare_pyarrow()   # in this thread: its own first-use memory (malloc arena) shows at start too
        except BaseException as exc:
            self._failed = exc
            return
        finally:
            self._prepared.set()
        while True:
            with self._wake:
                while not self._queue and not self._closed:
                    self._wake.wait()
                if self._closed:
                    return
                writer = self._queue.popleft()
            try:
                writer._finish_pending()
            except Exception as exc:   # a full disk, an I/O error, or a bug: the segment stays pending
                if self.log is not None:
                    self.log(f"{writer.stem}: a rotated segment is not finished yet ({exc}); it stays readable "
                             "as it is and is tried again at the next rotation or at close")


def _write_all(fd: int, data: bytes) -> None:
    view = memoryview(data)
    while view:
        written = os.write(fd, view)
        view = view[written:]


def _storage_error(exc: OSError, path) -> StorageError:
    if exc.errno in FULL_ERRNOS:
        return StorageFull(f"{path}: the disk is full ({exc.strerror})",
                           "free space or point the output elsewhere; nothing half-written was kept")
    return StorageError(f"{path}: cannot write ({exc.strerror})", "check the disk and the directory's permissions")


def _next_index(directory: Path, stem: str) -> int:
    indexes = [int(m["index"]) for m in map(NAME_PATTERN.match, os.listdir(directory)) if m and m["stem"] == stem]
    return max(indexes) + 1 if indexes else 0


# --------------------------------------------------------------------------- finishing


def finish_segment(path: str | os.PathLike, csv: bool = False, recovered: dict | None = None) -> Path | None:
    """Convert a closed open segment into its Parquet file (atomically), then remove it.

    Only the complete frames are converted.  Returns the Parquet path, or None when the
    segment held neither samples nor gap records (it is removed).  A full disk raises
    StorageFull and leaves the open segment as it was.
    """
    import pyarrow as pa

    path = Path(path)
    scanned = scan(path)
    if not scanned.samples and not scanned.gaps and not recovered:
        path.unlink()
        return None
    header = scanned.header
    names = header.get("channels", [])
    info = {"format": FORMAT, "version": FORMAT_VERSION, "stem": header["stem"], "index": header["index"],
            "scale": header["scale"], "units": "counts", "channels": names, "samples": scanned.samples,
            "first_ns": scanned.first_ns, "last_ns": scanned.last_ns, "gaps": scanned.gaps, "meta": header["meta"],
            **_rates(scanned.samples, scanned.first_ns, scanned.last_ns,
                     [g for g in scanned.gaps if scanned.first_ns is not None
                      and scanned.first_ns < g["t_ns"] <= scanned.last_ns])}
    if recovered:
        info["recovered"] = recovered
    schema = _schema(header["meta"].get("time_base") == "utc", names, info)
    target = path.with_suffix(FINISHED_SUFFIX)
    tmp = target.with_name(f".{target.name}.tmp")
    try:
        with _parquet_writer(tmp, schema) as out:
            for lo in range(0, scanned.samples, ROW_GROUP):   # one row group in memory at a time
                out.write_table(_table(schema, *_read_scanned(scanned, lo, min(lo + ROW_GROUP, scanned.samples))))
        fd = os.open(tmp, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
        os.replace(tmp, target)
        fsync_directory(target.parent)
        if csv:
            write_segment_csv(target)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        raise _storage_error(exc, target) from None
    finally:
        # malloc keeps what the conversion freed (and pyarrow's own pool the little it still takes
        # from it); a daemon converting a segment an hour for weeks would otherwise hold its peak
        pa.system_memory_pool().release_unused()
        pa.default_memory_pool().release_unused()
    path.unlink()
    fsync_directory(target.parent)
    return target


def _schema(utc: bool, names: list[str], info: dict):
    import pyarrow as pa

    fields = [pa.field("time", pa.timestamp("ns", tz="UTC" if utc else None)),
              *(pa.field(a, pa.int16()) for a in ("ax", "ay", "az")), *(pa.field(c, pa.float64()) for c in names)]
    return pa.schema(fields, metadata={META_KEY: to_json(info, indent=None, sort_keys=True).encode()})


# Conversions allocate from the C library's malloc, not pyarrow's default pool (mimalloc in
# pyarrow 26), which kept 7-9 MB more resident after each device's first conversion in the
# 8-device soak; malloc's freed memory goes back through malloc_trim (release_unused).


def _parquet_writer(sink, schema):
    import pyarrow as pa
    import pyarrow.parquet as pq

    return pq.ParquetWriter(sink, schema, compression="zstd", use_dictionary=["ax", "ay", "az"],
                            column_encoding={"time": "DELTA_BINARY_PACKED"}, write_statistics=["time"],
                            memory_pool=pa.system_memory_pool())


def _table(schema, t_ns: np.ndarray, counts: np.ndarray, chans: list[np.ndarray]):
    """One row group's table: times (ns), counts (n, 3), the channels in the schema's order."""
    import pyarrow as pa

    pool = pa.system_memory_pool()
    columns = [pa.array(t_ns, type=schema.field("time").type, memory_pool=pool),
               *(pa.array(counts[:, k], memory_pool=pool) for k in range(3)),
               *(pa.array(c, memory_pool=pool) for c in chans)]
    return pa.Table.from_arrays(columns, schema=schema)


def _prepare_pyarrow() -> None:
    """Import pyarrow and finish a small segment in memory: its one-time costs (the import, the
    tables its conversions build at first use, the Parquet writer's code read from disk: about
    50 MB resident, measured with pyarrow 26) are paid now, not at the first rotation."""
    import pyarrow as pa

    schema = _schema(True, [], {})
    with _parquet_writer(pa.BufferOutputStream(), schema) as out:
        out.write_table(_table(schema, np.arange(64, dtype=np.int64), np.zeros((64, 3), np.int16), []))
    pa.system_memory_pool().release_unused()


def _rates(samples: int, first_ns: int | None, last_ns: int | None, gaps: list[dict]) -> dict:
    """The rates over a stretch of samples (a segment, a range read): delivered (samples received per
    second) and device (with the samples its gap records say were lost), None if it spans no time."""
    span = (last_ns - first_ns) / NS if first_ns is not None and last_ns is not None else 0.0
    missing = sum(g["samples"] for g in gaps if g["samples"] > 0)
    return {"delivered_rate": (samples - 1) / span if span > 0 else None,
            "device_rate": (samples - 1 + missing) / span if span > 0 else None}


def write_segment_csv(parquet_path: Path) -> Path:
    """The interchange CSV of a finished segment beside it (counts, times in the stored time base, s)."""
    import pyarrow.parquet as pq

    from accelrig.files import atomic_write

    pf = pq.ParquetFile(parquet_path)
    info = json.loads(pf.schema_arrow.metadata[META_KEY])
    names = info["channels"]
    meta = dict(info["meta"], scale=info["scale"], units="counts", gaps=info["gaps"], segment=parquet_path.name)
    target = parquet_path.with_suffix(".csv")

    def write(fh) -> None:
        fh.write(META_PREFIX + " " + to_json(meta, indent=None, sort_keys=True) + "\n")
        fh.write(",".join(["t", "ax", "ay", "az", *names]) + "\n")
        for group in range(pf.num_row_groups):
            table = pf.read_row_group(group)
            t = ns_to_seconds(table.column("time").cast("int64").to_numpy())
            cols = [t, *(table.column(a).to_numpy() for a in ("ax", "ay", "az")),
                    *(table.column(c).to_numpy() for c in names)]
            np.savetxt(fh, np.column_stack(cols), fmt=["%.9f", "%d", "%d", "%d"] + ["%.10g"] * len(names),
                       delimiter=",")

    atomic_write(target, write, text=True)
    return target


# --------------------------------------------------------------------------- recovery


@dataclass
class RecoveryReport:
    """One segment a crash left open, and what became of it."""

    segment: Path                  # the open segment found
    finished: Path | None          # its Parquet file (None: it held nothing)
    samples: int                   # samples kept
    blocks: int                    # complete data blocks kept
    lost_bytes: int                # bytes after the last complete frame (a torn block)
    lost_samples: int | None       # samples in that torn block, when its header says (None: unknown)
    problem: str | None            # why the tail was unreadable

    def __str__(self) -> str:
        if self.finished is None and not self.samples and self.problem:
            return f"{self.segment.name}: {self.problem}"
        kept = f"{self.samples} samples in {self.blocks} complete blocks kept"
        if not self.lost_bytes:
            # the file's blocks, not the time the writer was down (a gap record states that)
            return f"{self.segment.name}: closed after a crash: {kept}; no block lost"
        torn = ("an incomplete block of unknown size" if self.lost_samples is None
                else f"an incomplete block of {self.lost_samples} samples")
        return f"{self.segment.name}: closed after a crash: {kept}; {self.lost_bytes} trailing bytes lost ({torn})"


def recover(directory: str | os.PathLike) -> list[RecoveryReport]:
    """Finish every open segment in ``directory`` that no writer holds (a crash left it), up to its
    last complete block; the loss is stated in each report and in the finished file's metadata."""
    directory = Path(directory)
    reports = []
    for path in sorted(directory.glob("*" + OPEN_SUFFIX)):
        if not NAME_PATTERN.match(path.name) or _held(path):
            continue
        finished = path.with_suffix(FINISHED_SUFFIX)
        if finished.exists() and _complete_parquet(finished):
            path.unlink()   # the crash came between the rename and the removal: the Parquet file is whole
            continue
        try:
            scanned = scan(path)
        except DataError as exc:
            reports.append(_unreadable(path, exc))
            continue
        recovered = {"recovered_at": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
                     "lost_bytes": scanned.lost_bytes, "lost_samples": scanned.lost_samples,
                     "problem": scanned.problem}
        if scanned.lost_bytes:
            # the torn block's samples never reached the file: a gap record says so where it was
            t_ns = scanned.last_ns + 1 if scanned.last_ns is not None else None
            recovered["gap"] = {"t_ns": t_ns, "samples": -1 if scanned.lost_samples is None else scanned.lost_samples,
                                "cause": "crash (incomplete block)", "seconds": None}
        result = finish_segment(path, recovered=recovered)
        reports.append(RecoveryReport(path, result, scanned.samples, len(scanned.data), scanned.lost_bytes,
                                      scanned.lost_samples, scanned.problem))
    return reports


def _unreadable(path: Path, exc: DataError) -> RecoveryReport:
    """A segment without a readable header: torn at creation (removed: it held no sample) or not ours (left)."""
    size = path.stat().st_size
    with open(path, "rb") as fh:
        start = fh.read(len(FILE_MAGIC))
    torn = FILE_MAGIC.startswith(start) or (start == FILE_MAGIC and size < 4096)
    if torn:
        path.unlink()
        return RecoveryReport(path, None, 0, 0, size, 0, "the writer stopped while creating it (no samples yet)")
    return RecoveryReport(path, None, 0, 0, 0, 0, f"left alone: {exc.message}")


def _held(path: Path) -> bool:
    """True while a live writer holds the segment (its lock)."""
    try:
        fd = os.open(path, os.O_RDONLY)
    except FileNotFoundError:
        return True
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        return False
    except BlockingIOError:
        return True
    finally:
        os.close(fd)


def _complete_parquet(path: Path) -> bool:
    import pyarrow.parquet as pq

    try:
        pq.ParquetFile(path)
        return True
    except Exception:   # pyarrow raises several types for a damaged file; any means "not whole"
        return False


# --------------------------------------------------------------------------- reading


@dataclass
class _Part:
    path: Path
    info: dict                     # stem, index, scale, channels, meta, gaps, samples, first_ns, last_ns
    scanned: Scan | None = None    # an open segment's scan
    parquet: object | None = None  # a finished segment's pyarrow.parquet.ParquetFile

    def groups(self) -> list[tuple[int, int | None, int | None]]:
        """(rows, first ns, last ns) of each row group (an open segment is one group); None: not recorded."""
        if self.scanned is not None:
            return [(self.scanned.samples, self.scanned.first_ns, self.scanned.last_ns)]
        out = []
        for i in range(self.parquet.metadata.num_row_groups):
            group = self.parquet.metadata.row_group(i)
            stats = group.column(0).statistics
            known = stats is not None and stats.has_min_max
            out.append((group.num_rows, stats.min_raw if known else None, stats.max_raw if known else None))
        return out

    def times(self, group: int) -> np.ndarray:
        """A group's sample times, ns (its time column alone)."""
        if self.scanned is not None:
            return _read_scanned(self.scanned, 0, self.scanned.samples)[0]
        return self.parquet.read_row_group(group, columns=["time"]).column("time").cast("int64").to_numpy()

    def rows(self, group: int, a: int, b: int):
        """Rows [a, b) of a group: (t_ns, [ax, ay, az] counts, [channel arrays])."""
        if self.scanned is not None:
            t_ns, counts, chans = _read_scanned(self.scanned, a, b)
            return t_ns, [counts[:, k] for k in range(3)], chans
        table = self.parquet.read_row_group(group).slice(a, b - a)
        return (table.column("time").cast("int64").to_numpy(), [table.column(x).to_numpy() for x in ("ax", "ay", "az")],
                [table.column(c).to_numpy() for c in self.info["channels"]])


def segment_files(path: str | os.PathLike, stem: str | None = None) -> list[Path]:
    """The segment files ``path`` names (a file, or a directory of one device's segments), in order."""
    path = Path(path)
    if not path.exists():
        raise DataError(f"{path}: no such file or directory")
    if path.is_file():
        if not NAME_PATTERN.match(path.name) and path.suffix not in SEGMENT_SUFFIXES:
            raise DataError(f"{path}: not an accelrig segment (.parquet or .seg)")
        return [path]
    found: dict[tuple[str, int], Path] = {}
    for name in os.listdir(path):
        m = NAME_PATTERN.match(name)
        if not m or (stem is not None and m["stem"] != stem):
            continue
        key = (m["stem"], int(m["index"]))
        if key not in found or m["suffix"] == FINISHED_SUFFIX:   # a finished segment wins over its leftover
            found[key] = path / name
    stems = sorted({s for s, _ in found})
    if not found:
        raise DataError(f"{path}: no segments{f' named {stem}' if stem else ''} in this directory",
                        "record into it first, or name a .parquet/.seg file")
    if len(stems) > 1:
        raise DataError(f"{path}: holds the segments of several devices ({', '.join(stems)})",
                        "point at one device's directory or file")
    return [found[k] for k in sorted(found)]


def _part(path: Path) -> _Part:
    if path.suffix == OPEN_SUFFIX:
        scanned = scan(path)
        h = scanned.header
        info = {"stem": h["stem"], "index": h["index"], "scale": h["scale"], "channels": h.get("channels", []),
                "meta": h["meta"], "gaps": scanned.gaps, "samples": scanned.samples,
                "first_ns": scanned.first_ns, "last_ns": scanned.last_ns}
        return _Part(path, info, scanned)
    import pyarrow.parquet as pq

    try:
        parquet = pq.ParquetFile(path)
        metadata = parquet.schema_arrow.metadata or {}
    except FileNotFoundError:
        raise DataError(f"{path}: no such file") from None
    except Exception as exc:   # pyarrow's errors for a file that is not Parquet vary by version
        raise DataError(f"{path}: not a readable Parquet file ({exc})") from None
    if META_KEY not in metadata:
        raise DataError(f"{path}: a Parquet file without accelrig's metadata (not a segment)")
    info = json.loads(metadata[META_KEY])
    gaps = list(info.get("gaps", []))
    if info.get("recovered", {}).get("gap"):
        gaps.append(info["recovered"]["gap"])
    info["gaps"] = gaps
    return _Part(path, info, parquet=parquet)


def read_arrays(path: str | os.PathLike, start: float | None = None, stop: float | None = None,
                stem: str | None = None, units: str = "m/s^2"):
    """Samples of a segment file or directory with stored time in [start, stop) (seconds, stored time base).

    Returns ``(t, acc, units, channels, meta)``: ``t`` seconds from the first sample returned (its
    stored time is ``meta['time_origin']``, also as ``time_origin_ns``); ``acc`` float64 in
    ``units`` ("m/s^2": counts x scale, or "counts"); gap records as ``meta['gaps']`` (index in the
    returned samples, missing, cause, seconds).  The metadata are the first segment's, except where the
    segments read differ in their calibration: then ``meta['spans']`` says which samples are raw counts
    and which calibrated, with which profile (``_describe_spans``).  Memory: the returned arrays plus one
    row group.
    """
    parts = [_part(p) for p in segment_files(path, stem)]
    lo_ns = None if start is None else int(to_ns(np.asarray([start]))[0])
    hi_ns = None if stop is None else int(to_ns(np.asarray([stop]))[0])
    # pass 1: the rows of each row group in range, from the groups' recorded time spans; only
    # a group the range cuts has its time column read
    plan = []   # (part, group, a, b)
    for part in parts:
        for group, (rows, first, last) in enumerate(part.groups()):
            if not rows or (first is not None and hi_ns is not None and first >= hi_ns) \
                    or (last is not None and lo_ns is not None and last < lo_ns):
                continue
            inside = first is not None and last is not None and (lo_ns is None or first >= lo_ns) \
                and (hi_ns is None or last < hi_ns)
            a, b = 0, rows
            if not inside:
                times = part.times(group)
                a = 0 if lo_ns is None else int(np.searchsorted(times, lo_ns, "left"))
                b = rows if hi_ns is None else int(np.searchsorted(times, hi_ns, "left"))
            if b > a:
                plan.append((part, group, a, b))
    total = sum(b - a for _, _, a, b in plan)
    if not total:
        raise DataError(f"{path}: no samples between {start} and {stop}" if start is not None or stop is not None
                        else f"{path}: the segments hold no samples")
    used = list({id(part): part for part, _, _, _ in plan}.values())   # the segments read, in order
    _check_in_time_order(path, used)
    _check_one_device_state(path, used)
    # a channel some segments lack (a daemon that recorded raw counts only until its profile came) is NaN there
    names = list(dict.fromkeys(name for part in used for name in part.info["channels"]))
    scale = float(used[0].info["scale"])
    factor = 1.0 if units == "counts" else scale
    t = np.empty(total)
    acc = np.empty((total, 3))
    channels = {name: np.full(total, np.nan) for name in names}
    origin_ns = None
    filled = 0
    starts = {}   # part path -> index of its first returned sample
    for part, group, a, b in plan:
        t_ns, axes, chans = part.rows(group, a, b)
        origin_ns = int(t_ns[0]) if origin_ns is None else origin_ns
        starts.setdefault(part.path, filled)
        k = t_ns.size
        t[filled:filled + k] = (t_ns - origin_ns) / NS
        for axis in range(3):
            np.multiply(axes[axis], factor, out=acc[filled:filled + k, axis])
        for name, values in zip(part.info["channels"], chans, strict=True):
            channels[name][filled:filled + k] = values
        filled += k
    # gap records at their place among the returned samples (the same float arithmetic as t)
    gaps: list[dict] = []
    for part in parts:
        for g in part.info["gaps"]:
            g_ns = g.get("t_ns")
            if g_ns is None:
                if part.path not in starts:
                    continue
                index = starts[part.path]
            elif (lo_ns is not None and g_ns < lo_ns) or (hi_ns is not None and g_ns >= hi_ns):
                continue
            else:
                index = int(np.searchsorted(t, (np.int64(g_ns) - origin_ns) / NS, "left"))
            gaps.append({"index": index, "missing": g["samples"], "cause": g["cause"],
                         "seconds": g.get("seconds"), "segment": part.path.name})
    meta = _current_meta(used[0].info["meta"])
    # over what was read: the gap records between its first and last sample
    meta.update(_rates(total, origin_ns, origin_ns + int(round(float(t[-1]) * NS)),
                       [{"samples": g["missing"]} for g in gaps if 0 < g["index"] < total]))
    meta.update(scale=scale, units=units, gaps=gaps, time_origin=float(ns_to_seconds([origin_ns])[0]),
                time_origin_ns=origin_ns, segments=list(dict.fromkeys(p.path.name for p, _, _, _ in plan)),
                source=str(path))
    _describe_spans(meta, used, starts, total)
    return t, acc, units, channels, meta


# What a daemon's segment says about its calibration: the profile it used ("profile"), why it recorded raw
# counts only ("recording_raw"), what its calibrated channels are ("calibrated_channels").  They hold for that
# segment; a read over segments whose calibration differs describes each stretch instead (``spans``).
CALIBRATION_KEYS = ("profile", "recording_raw", "calibrated_channels")
CALIBRATED = ("cal_x", "cal_y", "cal_z")


def _describe_spans(meta: dict, used: list, starts: dict, total: int) -> None:
    """When the segments read differ in their calibration (a daemon that recorded raw counts until its profile
    came, or changed profile on a reload), the first segment's profile, recording_raw and calibrated_channels
    would describe only its own stretch: they are replaced by ``meta['spans']``, one per stretch (samples
    [first, stop) of what was read, its segments, whether cal_x, cal_y, cal_z hold calibrated values there,
    the profile, why it is raw), and ``recording_raw`` names the raw stretches."""
    spans: list[dict] = []
    for part in used:
        stored = _current_meta(part.info["meta"])
        state = {"calibrated": all(name in part.info["channels"] for name in CALIBRATED),
                 "profile": stored.get("profile"), "recording_raw": stored.get("recording_raw")}
        first = starts[part.path]
        if spans and all(spans[-1][key] == value for key, value in state.items()):
            spans[-1]["segments"][1] = part.path.name
            continue
        if spans:
            spans[-1]["stop"] = first
        spans.append({"first": first, "stop": total, "segments": [part.path.name, part.path.name], **state})
    if len(spans) < 2:
        return
    described = next((_current_meta(p.info["meta"]).get("calibrated_channels") for p in used
                      if _current_meta(p.info["meta"]).get("calibrated_channels")), None)
    for key in CALIBRATION_KEYS:
        meta.pop(key, None)
    meta["spans"] = spans
    raw = [s for s in spans if not s["calibrated"]]
    if raw:
        meta["recording_raw"] = "; ".join(
            f"samples {s['first']}-{s['stop'] - 1} of {total} ({s['segments'][0]} to {s['segments'][1]}) hold raw "
            f"counts only" + (f": {s['recording_raw']}" if s["recording_raw"] else "") for s in raw)
    if described:
        meta["calibrated_channels"] = {**described, "where": "the spans with calibrated true (NaN elsewhere); "
                                       "each span names its profile"}


def _check_in_time_order(path, used: list[_Part]) -> None:
    """Each segment read must begin after the one before it ends: two that overlap in time are two recordings
    written into one directory at once (a second writer, before writers took the directory's lock), and
    their samples cannot be one time series.  Said as such, not as the time-base error it would become."""
    previous = None
    for part in used:
        first, last = part.info.get("first_ns"), part.info.get("last_ns")
        if first is None or last is None:
            continue
        if previous is not None and first <= previous.info["last_ns"]:
            span = (lambda p: f"{_iso(p.info['first_ns'])} to {_iso(p.info['last_ns'])}")
            raise DataError(f"{path}: two recordings overlap in time in this directory: segments "
                            f"{previous.path.name} ({span(previous)}) and {part.path.name} ({span(part)})",
                            "two writers recorded into it at once; move one recording's segments to a "
                            "directory of their own, or read a stretch where only one recorded with --start/--stop")
        previous = part


def _check_one_device_state(path, used: list[_Part]) -> None:
    """The segments read must share the count scale and the offsets flashed to the chip: one recording
    takes one of each, and a profile applied across a change would subtract the flashed bias from data
    that never had it removed, or twice (a daemon that recorded raw until its profile came, then flashed)."""
    scales = {p.info["scale"] for p in used}
    if len(scales) > 1:
        raise DataError(f"{path}: the segments were recorded at different scales {sorted(scales)} (range changed)",
                        _stretches_hint(used, lambda p: p.info["scale"]))
    states: dict[str, _Part] = {}   # flashed offsets -> the first segment with them

    def flashed(part: _Part) -> str:
        removed = _current_meta(part.info["meta"]).get("hardware_bias_removed")
        return ("no offsets flashed" if removed is None
                else "offsets [" + ", ".join(f"{float(v):.4g}" for v in removed) + "] m/s^2 flashed")

    for part in used:
        states.setdefault(flashed(part), part)
    if len(states) > 1:
        raise DataError(f"{path}: the chip's flashed offsets change between the segments read ("
                        + "; ".join(f"{said} from {part.path.name}" + (f" ({_iso(part.info['first_ns'])})"
                                                                        if part.info.get("first_ns") else "")
                                    for said, part in states.items()) + ")",
                        _stretches_hint(used, flashed))


def _stretches_hint(used: list[_Part], state) -> str:
    """How to read each stretch of one state: with UTC segments, the --stop/--start of the first change
    (the read is [start, stop), so the same time ends one stretch and begins the next)."""
    generic = "read each stretch separately with --start/--stop"
    if used[0].info["meta"].get("time_base") != "utc":
        return generic
    for before, after in zip(used, used[1:], strict=False):
        first_ns = after.info.get("first_ns")
        if state(before) != state(after) and first_ns:
            when = time.strftime("%Y-%m-%dT%H:%M:%S", time.gmtime(first_ns // NS)) + f".{first_ns % NS // 1000:06d}Z"
            return (f"read each stretch separately: --stop {when} ends the one before the change, "
                    f"--start {when} begins the one after")
    return generic


def _current_meta(stored: dict) -> dict:
    """A segment's metadata in the shape recordings have now.

    Earlier daemons (and the collector, which keeps what a daemon announced) wrote the device as a
    dict under "device"; recordings name it at the top level (identity, chip,
    range, scale, flashed offsets), which is where profile checks look.  Without this, weeks of
    older daemon output would not name their device: the check would be skipped and flashed
    offsets subtracted twice.
    """
    meta = dict(stored)
    old = meta.get("device")
    if isinstance(old, dict):
        facts = dict(old.get("extra") or {})
        meta["device"] = old.get("url")
        for key in ("identity", "driver", "chip", "who_am_i", "range_g", "scale", "requested_rate", "nominal_rate"):
            meta.setdefault(key, old.get(key))
        for key in ("hardware_bias_removed", "truth"):
            if facts.get(key) is not None:
                meta.setdefault(key, facts.pop(key))
        meta.setdefault("device_facts", facts)
    return meta


def resolve_range(path: str | os.PathLike, start: float | str | None,
                  stop: float | str | None) -> tuple[float | None, float | None]:
    """``start``/``stop`` as people give them (seconds from the first sample, or an ISO-8601
    UTC time such as 2026-11-24T01:00:00Z) turned into stored-time-base seconds for read_arrays."""
    if start is None and stop is None:
        return None, None
    parts = [_part(p) for p in segment_files(path)]
    firsts = [p.info["first_ns"] for p in parts if p.info["first_ns"] is not None]
    if not firsts:
        raise DataError(f"{path}: the segments hold no samples")
    first = float(ns_to_seconds([min(firsts)])[0])
    utc = parts[0].info["meta"].get("time_base") == "utc"
    return tuple(_bound(path, name, value, first, utc) for name, value in (("start", start), ("stop", stop)))


def _bound(path, name: str, value, first: float, utc: bool) -> float | None:
    if value is None:
        return None
    try:
        return first + float(value)
    except ValueError:
        pass
    when = utc_seconds(name, value)
    if not utc:
        raise DataError(f"{path}: its times are not UTC, so --{name} takes seconds from the first sample")
    return when


def utc_seconds(name: str, value) -> float:
    """An ISO-8601 time as people give --start/--stop (2026-11-24T01:00:00Z; without a zone it is UTC) as
    UTC epoch seconds: the one parser for segments and files alike."""
    from datetime import UTC, datetime

    try:
        when = datetime.fromisoformat(str(value).replace("Z", "+00:00"))
    except ValueError:
        raise DataError(f"--{name} {value!r} is neither seconds nor an ISO-8601 time",
                        "give seconds from the first sample, or e.g. 2026-11-24T01:00:00Z") from None
    if when.tzinfo is None:
        when = when.replace(tzinfo=UTC)
    return when.timestamp()
