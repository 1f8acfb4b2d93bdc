"""Recordings: samples + timestamps + metadata, CSV interchange and a native format.

CSV interchange (DESIGN.md): a header row; ``t`` in seconds (optional where a
nominal rate is given), ``ax, ay, az`` in m/s^2 (or g / counts when declared);
other named columns are kept as channels (``theta``, ``ref``, ``step``, ...).
Lines starting with ``#`` are comments; accelrig writes its metadata into one
``# accelrig-meta: {json}`` comment line so a CSV round-trips losslessly.

Native format: a NumPy ``.npz`` archive (``t``, ``acc``, one array per channel
and the metadata as a JSON string).  It loads with no parsing at memory speed,
needs nothing beyond NumPy, is read with ``allow_pickle=False`` so a file can
never execute code, and keeps float64 exactly.
"""

from __future__ import annotations

import csv
import hashlib
import json
import os
import struct
import zipfile
import zlib
from array import array
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import numpy.lib.format as npy_format

from accelrig import __version__
from accelrig.errors import DataError
from accelrig.files import META_PREFIX, atomic_write, text_lines
from accelrig.result import to_json
from accelrig.segments import SEGMENT_SUFFIXES, read_arrays, resolve_range, utc_seconds
from accelrig.settings import Setting
from accelrig.spec import (
    Array,
    Field,
    Integer,
    ListOf,
    Nullable,
    Number,
    Object,
    OneOf,
    Plain,
    String,
    check,
    describe,
    optional,
)
from accelrig.units import STANDARD_GRAVITY, normalise_unit, scale_for_range, to_si

ACC_COLUMNS = ("ax", "ay", "az")
NATIVE_SUFFIX = ".npz"


@dataclass
class Recording:
    """A finite stretch of samples from one device.

    t         sample times, s, shape (n,), strictly increasing.
    acc       accelerations, shape (n, 3), in ``units``.
    units     "m/s^2", "g" or "counts".
    channels  extra per-sample columns by name, float64, shape (n,).
    meta      device identity, chip, range_g, scale (m/s^2 per count),
              requested_rate, delivered_rate, software_version, start_time, gaps, ...
    """

    t: np.ndarray
    acc: np.ndarray
    units: str = "m/s^2"
    channels: dict[str, np.ndarray] = field(default_factory=dict)
    meta: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.units = normalise_unit(self.units)
        self.t = np.asarray(self.t, dtype=float)
        self.acc = np.asarray(self.acc, dtype=float)
        if self.acc.ndim != 2 or self.acc.shape[1] != 3:
            raise DataError(f"a recording needs three acceleration axes, got shape {self.acc.shape}")
        if self.t.shape != (self.acc.shape[0],):
            raise DataError("a recording needs one timestamp per sample")
        for name, values in list(self.channels.items()):
            values = np.asarray(values, dtype=float)
            if values.shape != self.t.shape:
                raise DataError(f"channel {name!r} has {values.size} values for {self.t.size} samples")
            self.channels[name] = values

    def __len__(self) -> int:
        return self.t.size

    @property
    def duration(self) -> float:
        return float(self.t[-1] - self.t[0]) if len(self) > 1 else 0.0

    @property
    def rate(self) -> float:
        """Mean delivered rate from the timestamps, Hz."""
        if len(self) < 2 or self.duration <= 0:
            raise DataError("a recording needs at least two samples with increasing times to have a rate")
        return (len(self) - 1) / self.duration

    def to_si(self, check_units: bool = True) -> Recording:
        """The same recording with acc in m/s^2: raw = counts x nominal scale (meta['scale']).

        Units g and mg are standard g (9.80665 m/s^2) by definition, as the
        nominal scale is; a local g is only the size of the reference, never a unit.
        With ``check_units`` (the default), data whose size says the declared
        units are wrong are refused, naming the --units flag to use.
        """
        if check_units:
            check_declared_units(self)
        if self.units == "m/s^2":
            return self
        acc = to_si(self.acc, self.units, self.meta.get("scale"), STANDARD_GRAVITY)
        return Recording(self.t, acc, "m/s^2", dict(self.channels), dict(self.meta))

    def slice(self, start: int, stop: int) -> Recording:
        return Recording(
            self.t[start:stop],
            self.acc[start:stop],
            self.units,
            {k: v[start:stop] for k, v in self.channels.items()},
            dict(self.meta),
        )

    def content_hash(self) -> str:
        """sha256 of the numeric content: provenance for profiles."""
        h = hashlib.sha256()
        h.update(self.units.encode())
        h.update(np.ascontiguousarray(self.t).tobytes())
        h.update(np.ascontiguousarray(self.acc).tobytes())
        for name in sorted(self.channels):
            h.update(name.encode())
            h.update(np.ascontiguousarray(self.channels[name]).tobytes())
        return "sha256:" + h.hexdigest()


# A recording whose link lost more than this share of its samples says so (stderr, and the result's
# warnings): the gaps are kept and never interpolated, but estimates from it rest on fewer samples
# than its length suggests, and heavy loss is usually a cable, a radio or a host that cannot keep up.
LOSS_WARN_SHARE = 0.01


def lost_samples(meta: dict) -> int:
    """Samples the device or link reported lost (the gaps of known size in the metadata)."""
    return sum(max(int(g.get("missing", 0)), 0) for g in meta.get("gaps") or [] if isinstance(g, dict))


def _loss_kind(cause: str) -> tuple[str, str, str]:
    """(kind, what happened to the samples, what to do) for a gap's recorded cause."""
    c = str(cause).lower()
    if c.startswith("disk full"):
        return "disk", "dropped while the disk was full", "give the recordings more disk space"
    if c.startswith("fifo overflow"):
        return "fifo", "lost in the chip's FIFO (read too late)", "lower the rate or the host's load"
    if c.startswith("stalled"):
        return "stall", "not sent while the device stalled", "check the device's power and firmware"
    if c.startswith(("not recording", "crash")):
        return ("stopped", "not recorded while the recorder was stopped or restarting",
                "the daemon's log and journal say why it stopped (a reload, a restart, a crash)")
    if c.startswith("reader overrun"):
        return "overrun", "skipped by a reader that fell behind", "the host could not keep up: lower its load"
    if c.startswith("gap in the replayed recording"):
        return ("replayed", "already missing from the replayed recording (it records no cause)",
                "look at the original recording's source")
    if c.startswith("disconnected"):
        return "link", "lost while the device was disconnected", "check the cable or radio link"
    return "link", "lost on the link", "check the cable or radio link"


@dataclass
class Loss:
    """The samples a recording lacks, from its gap records (``loss_of``).

    ``counted``: the samples gaps of known size say are missing; ``estimated``: those of gaps of unknown size
    (-1) from the time they lasted and the nominal rate; ``unmeasured``: gaps of unknown size and unknown
    duration; ``seconds``: the time the gaps lasted, where known; ``by_kind``: samples per kind of cause, so
    the warning follows each gap's recorded cause (a full disk is not a cable).
    """

    delivered: int
    gaps: int = 0
    counted: int = 0
    estimated: int = 0
    unknown: int = 0           # gaps of unknown size
    unmeasured: int = 0        # ... of which the duration is unknown too
    seconds: float = 0.0
    nominal_rate: float | None = None
    by_kind: dict = field(default_factory=dict)   # (kind, what happened) -> [samples, what, advice]

    @property
    def missing(self) -> int:
        return self.counted + self.estimated

    def summary(self) -> str:
        """What a recording lacks, in one phrase: `no samples lost`, `N samples lost in G gaps ...`."""
        if not self.gaps:
            return "no samples lost"
        kept = "(kept as gaps, never filled in)"
        if not self.unknown:
            return f"{self.counted} samples lost in {_gaps(self.gaps)} {kept}"
        parts = [f"{self.counted} samples counted"] if self.counted else []
        if self.estimated or not self.unmeasured:
            parts.append(f"about {self.estimated} samples estimated at the nominal {self.nominal_rate:g} Hz over the "
                         f"{_gaps(self.unknown - self.unmeasured)} of unknown size")
        if self.unmeasured:
            parts.append(f"{_gaps(self.unmeasured)} of unknown size and length")
        return f"{_gaps(self.gaps)}, {self.seconds:.2f} s missing: {' and '.join(parts)} {kept}"

    def warning(self) -> str | None:
        """One line when more than LOSS_WARN_SHARE of the samples are missing, naming what lost them (the gaps'
        recorded causes) and what to do; else None."""
        total = self.delivered + self.missing
        if not total or self.missing / total <= LOSS_WARN_SHARE:
            return None
        about = "about " if self.estimated else ""
        share = f"{self.missing / total:.1%}, more than {LOSS_WARN_SHARE:.0%}"
        if {kind for kind, _ in self.by_kind} == {"link"}:
            return (f"the link lost {about}{self.missing} of {total} samples ({share}) in {_gaps(self.gaps)}: kept as "
                    "gaps, never filled in; check the cable or radio link")
        kinds = sorted(self.by_kind.values(), key=lambda k: -k[0])
        advice = list(dict.fromkeys(k[2] for k in kinds))
        return (f"{about}{self.missing} of {total} samples ({share}) are missing in {_gaps(self.gaps)}: "
                + "; ".join(f"{k[0]} {k[1]}" for k in kinds) + "; kept as gaps, never filled in; "
                + "; ".join(advice))


def _gaps(n: int) -> str:
    return f"{n} gap" if n == 1 else f"{n} gaps"


def loss_of(delivered: int, gaps: list[dict], nominal_rate: float | None) -> Loss:
    """The Loss of ``delivered`` samples with these gap records ({"missing", "cause", "seconds"})."""
    loss = Loss(delivered, nominal_rate=nominal_rate)
    for g in gaps:
        if not isinstance(g, dict):
            continue
        missing, seconds = int(g.get("missing", g.get("samples", 0)) or 0), g.get("seconds")
        loss.gaps += 1
        if seconds is not None and seconds > 0:
            loss.seconds += float(seconds)
        if missing >= 0:
            loss.counted += missing
        else:
            loss.unknown += 1
            if seconds is not None and nominal_rate:
                missing = int(round(max(float(seconds), 0.0) * float(nominal_rate)))
                loss.estimated += missing
            else:
                loss.unmeasured += 1
                missing = 0
        kind, what, advice = _loss_kind(g.get("cause", ""))
        loss.by_kind.setdefault((kind, what), [0, what, advice])[0] += missing
    return loss


def loss_warning(rec: Recording) -> str | None:
    """One line when the recording lacks more than LOSS_WARN_SHARE of its samples, else None."""
    return loss_of(len(rec), rec.meta.get("gaps") or [], rec.meta.get("nominal_rate")).warning()


def count_scale(meta: dict) -> float | None:
    """m/s^2 per count of the device a recording came from: its ``scale``, else its
    ``range_g``'s nominal scale; None when neither is known."""
    if meta.get("scale"):
        return float(meta["scale"])
    if meta.get("range_g"):
        return scale_for_range(float(meta["range_g"]))
    return None


def default_meta(**values) -> dict:
    meta = {"software_version": __version__}
    meta.update(values)
    return meta


# --------------------------------------------------------------------------- CSV


# Bounds on what a reader holds in memory: a CSV is streamed into float64 rows and refused once it
# holds more values than this (512 MiB; 4.5 h of t,ax,ay,az at 2048 Hz, 46 h at 200 Hz); an .npz may
# declare at most this many values in all.  Longer sessions are segments (or split files).
MAX_VALUES = 1 << 26
MAX_META_CHARS = 1 << 24     # the metadata comment (its gap list grows with link losses)
# the sample rate a person gives for a file without t (--rate): finite, of an accelerometer
RATE = Setting("rate", "sample rate of a file without a t column", unit="Hz", low=0.0, low_open=True, high=100000.0)
LOWEST_RATE = 1.0            # Hz: no MEMS accelerometer samples slower; t advancing slower is t in ms

# The metadata fields readers and procedures use, typed; other fields are kept as plain data.
_TEXT = Nullable(OneOf((String(), Number()), expected="a string"))
_RATE = Nullable(Number(exclusive_minimum=0.0))
META = Object({
    "units": optional(String(enum=("m/s^2", "m/s2", "g", "mg", "counts"))),
    "identity": optional(_TEXT), "device": optional(_TEXT), "driver": optional(_TEXT), "chip": optional(_TEXT),
    "source": optional(_TEXT), "start_time": optional(_TEXT), "software_version": optional(_TEXT),
    "who_am_i": optional(Nullable(Integer(minimum=0, maximum=255))),
    "range_g": optional(_RATE), "scale": optional(_RATE),
    "requested_rate": optional(_RATE), "nominal_rate": optional(_RATE), "delivered_rate": optional(_RATE),
    "device_rate": optional(_RATE),
    "gaps": optional(Nullable(ListOf(Object({"index": Field(Integer(minimum=0)), "missing": Field(Integer())},
                                            additional=Plain())))),
    "hardware_bias_removed": optional(Nullable(Array((3,)))),
    "temperature_c": optional(Nullable(Number())),
}, additional=Plain())


def check_meta(meta, where: str) -> dict:
    """A recording's metadata, its fields' types checked (DataError naming the field)."""
    if not isinstance(meta, dict):
        raise DataError(f"{where}: the metadata must be a JSON object, got {describe(meta)}")
    check(META, meta, DataError, where=f"{where}: metadata ")
    return meta


def read_csv(path: str | os.PathLike, units: str | None = None, rate: float | None = None,
             default_units: str = "m/s^2") -> Recording:
    """Read an interchange CSV.

    ``units`` overrides what the file's metadata says (``default_units`` when it says nothing: m/s^2, or
    counts for a rotary bench's MEMS log).  ``rate`` (Hz) supplies times for a file without a ``t`` column.
    """
    path = Path(path)
    header, data, meta = read_table(path, ACC_COLUMNS, "a recording CSV", "t,ax,ay,az")
    col = {name: i for i, name in enumerate(header)}
    acc = data[:, [col[c] for c in ACC_COLUMNS]]
    if "t" in col:
        t = data[:, col["t"]]
        if t.size > 1 and (t.size - 1) / (t[-1] - t[0]) < LOWEST_RATE:
            step = float(np.median(np.diff(t)))
            raise DataError(f"{path}: t advances {step:g} per sample ({(t.size - 1) / (t[-1] - t[0]):.3g} Hz): "
                            "no accelerometer samples that slowly", "is t in milliseconds? give t in seconds")
    else:
        rate = RATE.parse(rate) or meta.get("delivered_rate") or meta.get("nominal_rate")
        if not rate:
            raise DataError(f"{path}: no 't' column and no sample rate", "add a t column or give the rate (--rate HZ)")
        t = np.arange(data.shape[0]) / float(rate)
    channels = {name: data[:, i] for name, i in col.items() if name not in ("t",) + ACC_COLUMNS}
    file_units = meta.get("units", default_units)
    rec_units = normalise_unit(units) if units else normalise_unit(file_units)
    meta.setdefault("source", str(path))
    meta["units"] = rec_units
    return Recording(t, acc, rec_units, channels, meta)


def read_table(path: Path, required: tuple[str, ...], what: str, example: str) -> tuple[list[str], np.ndarray, dict]:
    """Parse an interchange table: (header, float data (n, columns), metadata).

    Streamed line by line into a float64 buffer, so memory is the numbers' own
    size (bounded by MAX_VALUES), never the text's.  ``#`` comments are skipped,
    accelrig's ``# accelrig-meta:`` line is read and its fields' types checked;
    every malformed line is an error naming the file and line.  A ``t``
    column, when present, must increase.
    """
    meta: dict = {}
    header: list[str] | None = None
    header_line = 0
    values = array("d")
    width = 0
    for lineno, line in text_lines(path, DataError, what, MAX_META_CHARS):
        stripped = line.strip()
        if not stripped:
            continue
        if stripped.startswith("#"):
            if stripped.startswith(META_PREFIX):
                meta = _parse_meta(stripped[len(META_PREFIX):], f"{path}:{lineno}")
            continue
        fields = _fields(stripped, path, lineno)
        if header is None:
            header = [f.strip() for f in fields]
            header_line = lineno
            _check_header(path, lineno, header, required, what, example)
            width = len(header)
            continue
        if len(fields) != width:
            raise DataError(f"{path}:{lineno}: expected {width} values ({','.join(header)}), got {len(fields)}")
        try:
            values.extend([float(f) for f in fields])
        except ValueError:
            bad = next(f for f in fields if not _is_float(f))
            shown = bad.strip() if len(bad) <= 40 else bad.strip()[:37] + "..."
            raise DataError(f"{path}:{lineno}: {shown!r} is not a number") from None
        if len(values) > MAX_VALUES:
            raise DataError(f"{path}:{lineno}: more than {MAX_VALUES} values, more than accelrig holds in memory",
                            "split the recording into shorter files")
    if header is None:
        raise DataError(f"{path}: empty file", f"{what} needs a header row {example} and data rows")
    if not values:
        raise DataError(f"{path}: header on line {header_line} but no data rows")
    data = np.frombuffer(values, dtype=float).reshape(-1, width)
    finite = np.isfinite(data)
    if not finite.all():
        row, column = (int(i) for i in np.argwhere(~finite)[0])
        raise DataError(f"{path}: row {row + 1} of the data holds a NaN or infinite value "
                        f"({data[row, column]} in column {header[column]})", "every value must be a finite number")
    if "t" in header:
        t = data[:, header.index("t")]
        if t.size > 1 and not np.all(np.diff(t) > 0):
            k = int(np.argmax(np.diff(t) <= 0))
            raise DataError(f"{path}: time t does not increase at data row {k + 2}", "sort the file or fix the timestamps")
    return header, data, meta


def _fields(line: str, path: Path, lineno: int) -> list[str]:
    if '"' not in line:
        return line.split(",")   # the common case, without the csv module's per-line cost
    try:
        return next(csv.reader([line]))
    except csv.Error as exc:
        raise DataError(f"{path}:{lineno}: not a CSV row ({exc})") from None


def _parse_meta(text: str, where: str) -> dict:
    try:
        meta = json.loads(text)
    except json.JSONDecodeError as exc:
        raise DataError(f"{where}: metadata comment is not valid JSON ({exc.msg})") from None
    except (ValueError, RecursionError) as exc:   # a 5000-digit integer, nesting beyond the parser
        raise DataError(f"{where}: metadata comment cannot be read ({str(exc).splitlines()[0][:80]})") from None
    return check_meta(meta, where)


def _is_float(text: str) -> bool:
    try:
        float(text)
        return True
    except ValueError:
        return False


def _check_header(path: Path, lineno: int, header: list[str], required: tuple[str, ...], what: str,
                  example: str) -> None:
    if any(_is_float(h) for h in header):
        raise DataError(f"{path}:{lineno}: the first row holds numbers, not column names", f"add a header row {example}")
    missing = [c for c in required if c not in header]
    if missing:
        raise DataError(
            f"{path}:{lineno}: header lacks column(s) {', '.join(missing)}",
            f"{what} needs a header {example}",
        )
    dup = sorted({h for h in header if header.count(h) > 1})
    if dup:
        raise DataError(f"{path}:{lineno}: column(s) {', '.join(dup)} appear twice in the header")


def write_csv(rec: Recording, path: str | os.PathLike | None = None, stream=None, overwrite: bool = True,
              inputs=()) -> None:
    """Write an interchange CSV to ``path`` (atomically; see files.atomic_write for ``overwrite`` and
    ``inputs``) or to an open text ``stream``."""
    meta = {k: v for k, v in rec.meta.items() if k != "file"}   # where it was read from is not its content
    meta["units"] = rec.units
    names = ["t", *ACC_COLUMNS, *rec.channels]
    columns = [rec.t, rec.acc[:, 0], rec.acc[:, 1], rec.acc[:, 2], *rec.channels.values()]
    data = np.column_stack(columns) if len(rec) else np.empty((0, len(names)))
    # counts are integers: write them without a decimal tail; floats keep full precision.
    fmt = ["%.9f"] + (["%d"] * 3 if rec.units == "counts" else ["%.10g"] * 3) + ["%.10g"] * len(rec.channels)

    def _write(fh) -> None:
        fh.write(META_PREFIX + " " + to_json(meta, indent=None, sort_keys=True) + "\n")
        fh.write(",".join(names) + "\n")
        np.savetxt(fh, data, fmt=fmt, delimiter=",")

    if stream is not None:
        _write(stream)
        return
    atomic_write(path, _write, text=True, overwrite=overwrite, inputs=inputs)


# ------------------------------------------------------------------- native (.npz)


def save_native(rec: Recording, path: str | os.PathLike, overwrite: bool = True, inputs=()) -> None:
    arrays = {"t": rec.t, "acc": rec.acc}
    for name, values in rec.channels.items():
        arrays["ch_" + name] = values
    meta = {k: v for k, v in rec.meta.items() if k != "file"}   # where it was read from is not its content
    meta["units"] = rec.units
    arrays["meta_json"] = np.array(to_json(meta, indent=None, sort_keys=True))
    atomic_write(path, lambda fh: np.savez(fh, **arrays), text=False, overwrite=overwrite, inputs=inputs)


def load_native(path: str | os.PathLike) -> Recording:
    """Read a native .npz recording: sizes checked from the headers before anything is inflated,
    float or integer arrays only (no objects, no complex), every value finite, metadata typed."""
    path = Path(path)
    try:
        _check_npz(path)
        with np.load(path, allow_pickle=False) as z:
            meta = _parse_meta(str(z["meta_json"]), str(path))
            arrays = {k: z[k] for k in z.files if k in ("t", "acc") or k.startswith("ch_")}
    except FileNotFoundError:
        raise DataError(f"{path}: no such file") from None
    except IsADirectoryError:
        raise DataError(f"{path}: is a directory, not an .npz recording") from None
    except MemoryError:
        raise DataError(f"{path}: too large to hold in memory") from None
    except (ValueError, KeyError, OSError, EOFError, zipfile.BadZipFile, zlib.error, struct.error, OverflowError,
            NotImplementedError, RuntimeError) as exc:
        # zipfile raises NotImplementedError (a compression method or zip version it lacks) and
        # RuntimeError (an encrypted member): neither is a bug here, both are a file accelrig did not write
        raise DataError(f"{path}: not an accelrig .npz recording ({str(exc)[:120] or type(exc).__name__})") from None
    for name in ("t", "acc"):
        if name not in arrays:
            raise DataError(f"{path}: not an accelrig .npz recording (no array {name!r})")
    for name, values in arrays.items():
        finite = np.isfinite(values)
        if not finite.all():
            row = int(np.argwhere(~finite)[0][0])
            raise DataError(f"{path}: array {name} holds a NaN or infinite value at row {row} "
                            f"({values.reshape(len(values), -1)[row].tolist()})", "every value must be a finite number")
    channels = {k[3:]: v for k, v in arrays.items() if k.startswith("ch_")}
    return Recording(arrays["t"], arrays["acc"], meta.get("units", "m/s^2"), channels, meta)


def _check_npz(path: Path) -> None:
    """Refuse an .npz before np.load inflates it: not a zip, a zip bomb, an array too large, of a wrong type."""
    with open(path, "rb") as fh:
        magic = fh.read(6)
    if magic == b"\x93NUMPY":
        raise DataError(f"{path}: not an accelrig .npz recording (a single .npy array)",
                        "save recordings with accelrig record")
    if not zipfile.is_zipfile(path):
        raise DataError(f"{path}: not an accelrig .npz recording (not a zip archive)")
    budget = 8 * MAX_VALUES
    with zipfile.ZipFile(path) as archive:
        for info in archive.infolist():
            name = info.filename[:-4] if info.filename.endswith(".npy") else info.filename
            limit = MAX_META_CHARS * 4 if name == "meta_json" else budget
            if info.file_size > limit + 4096:
                raise DataError(f"{path}: array {name} declares {info.file_size} bytes uncompressed, more than "
                                f"accelrig holds ({limit} bytes)", "is it a zip bomb? split long recordings")
            with archive.open(info) as member:
                version = npy_format.read_magic(member)
                read_header = npy_format.read_array_header_1_0 if version == (1, 0) else npy_format.read_array_header_2_0
                shape, _, dtype = read_header(member)
            if name == "meta_json":
                if dtype.kind != "U" or shape != ():
                    raise DataError(f"{path}: meta_json is not a string")
                continue
            if dtype.kind == "c":
                raise DataError(f"{path}: array {name} is complex", "a recording holds real numbers")
            if dtype.kind not in "fiu":
                raise DataError(f"{path}: array {name} holds {dtype}, not numbers")
            nbytes = int(np.prod(shape, dtype=object)) * 8   # held as float64 once loaded
            if nbytes > budget:
                raise DataError(f"{path}: array {name} declares shape {shape}, more than accelrig holds in memory",
                                "split long recordings")
            budget -= nbytes


def load_recording(path: str | os.PathLike, units: str | None = None, rate: float | None = None,
                   start: float | str | None = None, stop: float | str | None = None,
                   default_units: str = "m/s^2") -> Recording:
    """Load a CSV or native recording, or segments (a directory of them, a .parquet or .seg file),
    chosen by the file suffix.

    ``start``/``stop`` keep a time range: seconds from the first sample, or an ISO-8601 UTC time
    such as 2026-11-24T01:00:00Z (segments, and files whose metadata give their UTC time origin).
    ``units`` overrides what the file declares; ``default_units`` stands for a CSV that declares nothing.
    """
    rec = _load(Path(path), units, rate, start, stop, default_units)
    # where it was read from, whatever its header declares as its "source" (a description such as "imucal
    # sensor 3"): a profile keeps this, so that a certificate can find the file again (report.recompute)
    rec.meta["file"] = str(path)
    return rec


def _load(path: Path, units, rate, start, stop, default_units="m/s^2") -> Recording:
    if path.is_dir() or path.suffix.lower() in SEGMENT_SUFFIXES:
        return read_segments(path, *resolve_range(path, start, stop), units="counts" if units == "counts" else None)
    if start is not None or stop is not None:
        return time_range(load_recording(path, units, rate, default_units=default_units), start, stop)
    if path.suffix.lower() == NATIVE_SUFFIX:
        rec = load_native(path)
        if units:
            rec = Recording(rec.t, rec.acc, units, rec.channels, rec.meta)
        return rec
    if path.suffix.lower() in (".yaml", ".yml", ".json"):
        # the usual slip: a profile or a saved result where the recording belongs
        raise DataError(f"{path}: a {path.suffix[1:].upper()} file (a profile or a saved result?), not a recording",
                        "give the recording: a CSV, a .npz or segments (a .parquet/.seg file or their folder)")
    return read_csv(path, units=units, rate=rate, default_units=default_units)


def read_segments(path: str | os.PathLike, start: float | None = None, stop: float | None = None,
                  units: str | None = None) -> Recording:
    """The Recording of a segment file or a directory of one device's segments over [start, stop)
    (seconds in the stored time base, UTC epoch for ``record`` and the daemon); in m/s^2
    (counts x scale) unless ``units`` is "counts".  t counts from the first sample returned."""
    t, acc, rec_units, channels, meta = read_arrays(path, start, stop, units=units or "m/s^2")
    return Recording(t, acc, rec_units, channels, meta)


def time_range(rec: Recording, start: float | str | None, stop: float | str | None) -> Recording:
    """The samples from ``start`` to before ``stop``: seconds from the first sample, or an ISO-8601 UTC time
    when the recording carries absolute time (time_base "utc" and time_origin, the UTC epoch seconds of
    t = 0, as ``record`` and the daemon write them)."""
    t0 = rec.t[0] if len(rec) else 0.0
    bounds = []
    for name, value in (("start", start), ("stop", stop)):
        if value is None:
            bounds.append(None)
            continue
        try:
            bounds.append(t0 + float(value))
            continue
        except ValueError:
            pass
        when = utc_seconds(name, value)
        if utc_origin(rec) is None:
            raise DataError(f"--{name} {value}: {rec.meta.get('source', 'the recording')} carries no absolute time "
                            "(its metadata give no UTC time origin), so a UTC time cannot be placed in it",
                            f"give --{name} in seconds from the first sample")
        bounds.append(when - float(rec.meta["time_origin"]))
    lo = 0 if bounds[0] is None else int(np.searchsorted(rec.t, bounds[0], "left"))
    hi = len(rec) if bounds[1] is None else int(np.searchsorted(rec.t, bounds[1], "left"))
    if hi <= lo:
        raise DataError(f"no samples from {'the first sample' if start is None else start} to before "
                        f"{'the end' if stop is None else stop} (the recording spans {rec.duration:.3f} s"
                        + (f" from {_utc_text(rec.meta['time_origin'] + t0)}" if utc_origin(rec) is not None else "") + ")")
    return rec.slice(lo, hi)


def utc_origin(rec: Recording) -> float | None:
    """The UTC epoch seconds of t = 0 when the recording carries absolute time (``record`` and the daemon
    write time_base "utc" and time_origin), else None."""
    if rec.meta.get("time_base") == "utc" and isinstance(rec.meta.get("time_origin"), int | float):
        return float(rec.meta["time_origin"])
    return None


def _utc_text(epoch: float) -> str:
    from datetime import UTC, datetime

    return datetime.fromtimestamp(float(epoch), UTC).isoformat(timespec="milliseconds").replace("+00:00", "Z")


def save_recording(rec: Recording, path: str | os.PathLike, overwrite: bool = True, inputs=()) -> None:
    """Write a CSV or native recording, chosen by the suffix; ``overwrite`` and ``inputs`` as in
    files.atomic_write (an existing file only with overwrite, never an input, never a special file)."""
    if Path(path).suffix.lower() == NATIVE_SUFFIX:
        save_native(rec, path, overwrite, inputs)
    else:
        write_csv(rec, path, overwrite=overwrite, inputs=inputs)


def guess_units(acc: np.ndarray) -> str:
    """Guess the units of raw accelerometer data from the size of gravity.

    A sensor that is mostly still reads |a| about 9.8 in m/s^2, about 1 in g, about 1000 in
    milli-g (mg) and hundreds to tens of thousands in counts.  Used to catch a wrong --units.
    "mg" is also the size of counts of a part with about 1000 counts per g (a +-32 g range,
    some 12-bit parts): a file declared as counts with its scale is never refused for it.
    """
    norms = np.linalg.norm(np.asarray(acc, dtype=float), axis=1)
    m = float(np.median(norms)) if norms.size else 0.0
    if 0.5 < m < 2.0:
        return "g"
    if 4.0 < m < 25.0:
        return "m/s^2"
    if 500.0 < m < 2000.0:
        return "mg"
    if m > 100.0:
        return "counts"
    return "unknown"


def check_declared_units(rec: Recording) -> None:
    """Refuse data whose size says the declared units are wrong, naming the flag to use.

    Catches the common slips (a file in g read as m/s^2, counts read as g, milli-g read as
    anything else); data whose size fits no unit (strong motion) pass: the procedures' own
    checks judge them.
    """
    guess = guess_units(rec.acc)
    if guess in ("unknown", rec.units):
        return
    size = float(np.median(np.linalg.norm(rec.acc, axis=1)))
    if rec.units == "counts" and guess == "mg":
        if count_scale(rec.meta) is not None:
            return   # counts of a part with about 1000 counts per g, and the file gives their scale
        raise DataError(f"the data were declared as counts, without a counts-to-m/s^2 scale, and look like "
                        f"milli-g (median |a| about {size:.3g})",
                        "use --units mg if they are milli-g; counts need the sensor's range (--range-g G)")
    if guess == "mg":
        raise DataError(f"the data were declared as {rec.units} but look like milli-g (median |a| about {size:.3g})",
                        "use --units mg; if they are counts of a part with about 1000 counts per g, "
                        "--units counts with the sensor's range (--range-g G)")
    flag = {"m/s^2": "--units m/s2", "g": "--units g", "counts": "--units counts"}[guess]
    if guess == "counts" and count_scale(rec.meta) is None:
        flag += " with the sensor's range (--range-g G)"
    raise DataError(f"the data were declared as {rec.units} but look like {guess} (median |a| about {size:.3g})",
                    f"use {flag}")
