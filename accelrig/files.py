"""Reading and writing files safely (ground floor: imports only the errors).

``atomic_write`` is the one way accelrig writes a file a person keeps: a crash
or an error mid-write leaves the old file (or none), never half a file.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

from accelrig.errors import AccelrigError, DataError

# The one metadata comment line of accelrig's interchange CSV (recording.py reads and writes it;
# segments.py writes it into the CSV copy of a segment).
META_PREFIX = "# accelrig-meta:"


def _umask() -> int:
    # os.umask can only be read by setting it; set it straight back.
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def atomic_write(path: str | os.PathLike, writer, text: bool) -> None:
    """Write through a temporary file in the same directory, then rename it into place.

    The file gets the mode an ordinary ``open()`` would give it (0666 less the
    umask), not mkstemp's private 0600, so a colleague or a service user can
    read a profile.  The directory is fsynced after the rename so the new
    name survives a power cut.
    """
    path = Path(path)
    directory = path.parent if str(path.parent) else Path(".")
    if not directory.is_dir():
        raise DataError(f"{path}: directory {directory} does not exist")
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=directory)
    try:
        os.fchmod(fd, 0o666 & ~_umask())
        with os.fdopen(fd, "w" if text else "wb", **({"encoding": "utf-8", "newline": ""} if text else {})) as fh:
            writer(fh)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        raise
    fsync_directory(directory)


def fsync_directory(directory: Path) -> None:
    """Make a rename or a new file in ``directory`` survive a power cut (best effort)."""
    try:
        fd = os.open(directory, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0))
    except OSError:
        return  # a directory that cannot be opened for reading (rare): the rename itself has happened
    try:
        os.fsync(fd)
    except OSError:
        pass  # some file systems refuse fsync on directories; the data file itself is synced
    finally:
        os.close(fd)


def read_text_file(path: str | os.PathLike, error: type[AccelrigError] = DataError, what: str = "a CSV file") -> str:
    """A whole text file, or ``error`` in one line saying why not (missing, a directory, binary)."""
    path = Path(path)
    try:
        return path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise error(f"{path}: no such file") from None
    except IsADirectoryError:
        raise error(f"{path}: is a directory, not {what}") from None
    except UnicodeDecodeError:
        raise error(f"{path}: not a text file, so not {what}") from None
    except OSError as exc:
        raise error(f"{path}: cannot read ({exc.strerror})") from None
