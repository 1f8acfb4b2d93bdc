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
import io
import json
import os
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from accelrig import __version__
from accelrig.errors import DataError
from accelrig.files import atomic_write, read_text_file
from accelrig.result import to_json
from accelrig.units import STANDARD_GRAVITY, normalise_unit, scale_for_range, to_si

META_PREFIX = "# accelrig-meta:"
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

        Unit g is standard g (9.80665 m/s^2) by definition, as the nominal
        scale is; a local g is only the size of the reference, never a unit.
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


def read_csv(path: str | os.PathLike, units: str | None = None, rate: float | None = None) -> Recording:
    """Read an interchange CSV.

    ``units`` overrides what the file's metadata says (default m/s^2).  ``rate``
    (Hz) supplies times for a file without a ``t`` column.
    """
    path = Path(path)
    header, data, meta = read_table(path, ACC_COLUMNS, "a recording CSV", "t,ax,ay,az")
    col = {name: i for i, name in enumerate(header)}
    acc = data[:, [col[c] for c in ACC_COLUMNS]]
    if "t" in col:
        t = data[:, col["t"]]
    else:
        rate = rate or meta.get("delivered_rate") or meta.get("nominal_rate")
        if not rate:
            raise DataError(f"{path}: no 't' column and no sample rate", "add a t column or give the rate (--rate HZ)")
        t = np.arange(data.shape[0]) / float(rate)
    channels = {name: data[:, i] for name, i in col.items() if name not in ("t",) + ACC_COLUMNS}
    file_units = meta.get("units", "m/s^2")
    rec_units = normalise_unit(units) if units else normalise_unit(file_units)
    meta.setdefault("source", str(path))
    meta["units"] = rec_units
    return Recording(t, acc, rec_units, channels, meta)


def read_table(path: Path, required: tuple[str, ...], what: str, example: str) -> tuple[list[str], np.ndarray, dict]:
    """Parse an interchange table: (header, float data (n, columns), metadata).

    ``#`` comments are skipped, accelrig's ``# accelrig-meta:`` line is read;
    every malformed line is an error naming the file and line.  A ``t``
    column, when present, must increase.
    """
    text = read_text_file(path, DataError, what)
    meta: dict = {}
    header: list[str] | None = None
    header_line = 0
    rows: list[list[float]] = []
    for lineno, line in enumerate(io.StringIO(text), start=1):
        stripped = line.strip()
        if not stripped:
            continue
        if stripped.startswith("#"):
            if stripped.startswith(META_PREFIX):
                try:
                    meta = json.loads(stripped[len(META_PREFIX):])
                except json.JSONDecodeError as exc:
                    raise DataError(f"{path}:{lineno}: metadata comment is not valid JSON ({exc.msg})") from None
            continue
        fields = next(csv.reader([stripped]))
        if header is None:
            header = [f.strip() for f in fields]
            header_line = lineno
            _check_header(path, lineno, header, required, what, example)
            continue
        if len(fields) != len(header):
            raise DataError(
                f"{path}:{lineno}: expected {len(header)} values ({','.join(header)}), got {len(fields)}"
            )
        try:
            rows.append([float(f) for f in fields])
        except ValueError:
            bad = next(f for f in fields if not _is_float(f))
            raise DataError(f"{path}:{lineno}: {bad.strip()!r} is not a number") from None
    if header is None:
        raise DataError(f"{path}: empty file", f"{what} needs a header row {example} and data rows")
    if not rows:
        raise DataError(f"{path}: header on line {header_line} but no data rows")
    data = np.asarray(rows, dtype=float)
    if not np.all(np.isfinite(data)):
        bad_row = int(np.argmax(~np.all(np.isfinite(data), axis=1)))
        raise DataError(f"{path}: row {bad_row + 1} of the data holds a NaN or infinite value")
    if "t" in header:
        t = data[:, header.index("t")]
        if t.size > 1 and not np.all(np.diff(t) > 0):
            k = int(np.argmax(np.diff(t) <= 0))
            raise DataError(f"{path}: time t does not increase at data row {k + 2}", "sort the file or fix the timestamps")
    return header, data, meta


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
    meta = dict(rec.meta)
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
    meta = dict(rec.meta)
    meta["units"] = rec.units
    arrays["meta_json"] = np.array(to_json(meta, indent=None, sort_keys=True))
    atomic_write(path, lambda fh: np.savez(fh, **arrays), text=False, overwrite=overwrite, inputs=inputs)


def load_native(path: str | os.PathLike) -> Recording:
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as z:
            meta = json.loads(str(z["meta_json"]))
            channels = {k[3:]: z[k] for k in z.files if k.startswith("ch_")}
            return Recording(z["t"], z["acc"], meta.get("units", "m/s^2"), channels, meta)
    except FileNotFoundError:
        raise DataError(f"{path}: no such file") from None
    except (ValueError, KeyError, OSError, EOFError, zipfile.BadZipFile) as exc:
        raise DataError(f"{path}: not an accelrig .npz recording ({exc or type(exc).__name__})") from None


def load_recording(path: str | os.PathLike, units: str | None = None, rate: float | None = None) -> Recording:
    """Load a CSV or native recording, chosen by the file suffix."""
    path = Path(path)
    if path.suffix.lower() == NATIVE_SUFFIX:
        rec = load_native(path)
        if units:
            rec = Recording(rec.t, rec.acc, units, rec.channels, rec.meta)
        return rec
    return read_csv(path, units=units, rate=rate)


def save_recording(rec: Recording, path: str | os.PathLike, overwrite: bool = True, inputs=()) -> None:
    """Write a CSV or native recording, chosen by the suffix; ``overwrite`` and ``inputs`` as in
    files.atomic_write (an existing file only with overwrite, never an input, never a special file)."""
    if Path(path).suffix.lower() == NATIVE_SUFFIX:
        save_native(rec, path, overwrite, inputs)
    else:
        write_csv(rec, path, overwrite=overwrite, inputs=inputs)


def guess_units(acc: np.ndarray) -> str:
    """Guess the units of raw accelerometer data from the size of gravity.

    A sensor that is mostly still reads |a| about 9.8 in m/s^2, about 1 in g and
    hundreds to tens of thousands in counts.  Used to catch a wrong --units.
    """
    norms = np.linalg.norm(np.asarray(acc, dtype=float), axis=1)
    m = float(np.median(norms)) if norms.size else 0.0
    if 0.5 < m < 2.0:
        return "g"
    if 4.0 < m < 25.0:
        return "m/s^2"
    if m > 100.0:
        return "counts"
    return "unknown"


def check_declared_units(rec: Recording) -> None:
    """Refuse data whose size says the declared units are wrong, naming the flag to use.

    Catches the common slips (a file in g read as m/s^2, counts read as g);
    data whose size fits no unit (strong motion) pass: the procedures' own
    checks judge them.
    """
    guess = guess_units(rec.acc)
    if guess in ("unknown", rec.units):
        return
    flag = {"m/s^2": "--units m/s2", "g": "--units g", "counts": "--units counts"}[guess]
    size = float(np.median(np.linalg.norm(rec.acc, axis=1)))
    raise DataError(f"the data were declared as {rec.units} but look like {guess} (median |a| about {size:.3g})",
                    f"use {flag}")

