"""Reading and writing files safely (ground floor: imports only the errors).

``atomic_write`` is the one way accelrig writes a file a person keeps: a crash
or an error mid-write leaves the old file (or none), never half a file.
"""

from __future__ import annotations

import os
import stat
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


class OutputExists(DataError):
    """The output file exists and the command was not told to replace it."""


def writable_target(path: str | os.PathLike, overwrite: bool = True, inputs=()) -> Path:
    """The file a write to ``path`` lands on, after refusing what no write may destroy.

    A symlink is written through (its target is replaced, the link stays); a device node, a
    fifo, a socket or a folder is never replaced; an input of the same command is never
    written over; an existing file only with ``overwrite`` (the command's --force).  Commands
    call this before they start work, so an hour of recording is not lost to a refusal at the end.
    """
    path = Path(path)
    target = Path(os.path.realpath(path)) if path.is_symlink() else path
    try:
        st = os.stat(target)
    except FileNotFoundError:
        st = None
    except OSError as exc:
        raise DataError(f"{path}: cannot write ({exc.strerror})") from None
    if st is not None:
        if stat.S_ISDIR(st.st_mode):
            raise DataError(f"{path}: is a directory", "give a file name")
        if not stat.S_ISREG(st.st_mode):
            kind = ("a device" if stat.S_ISCHR(st.st_mode) or stat.S_ISBLK(st.st_mode)
                    else "a fifo" if stat.S_ISFIFO(st.st_mode) else "a socket" if stat.S_ISSOCK(st.st_mode)
                    else "a special file")
            raise DataError(f"{path}: is {kind}, not a regular file: refusing to replace it", "give a file name")
        for source in inputs:
            try:
                same = os.path.samefile(target, source)
            except OSError:
                continue
            if same:
                raise DataError(f"{path}: is also an input of this command: refusing to write over it",
                                "write the output to another file")
        if not overwrite:
            raise OutputExists(f"{path}: exists", "use --force to replace it, or choose another name")
    directory = target.parent if str(target.parent) else Path(".")
    if not directory.is_dir():
        raise DataError(f"{path}: directory {directory} does not exist")
    return target


def atomic_write(path: str | os.PathLike, writer, text: bool, overwrite: bool = True, inputs=(),
                 mode: int = 0o666) -> None:
    """Write through a temporary file in the same directory, then rename it into place.

    What may be written is decided by ``writable_target`` (symlinks written through, special
    files and inputs refused, an existing file only with ``overwrite``).  Without
    ``overwrite`` the file is created exclusively (a hard link of the finished temporary
    file, which fails if the name exists), so two writers never replace each other's file.
    The file gets ``mode`` less the umask (an ordinary ``open()`` gives 0666 less the umask),
    not mkstemp's private 0600, so a colleague or a service user can read a profile.  The
    directory is fsynced after the rename so the new name survives a power cut.  Any OSError
    (read-only folder, full disk, file size limit) is one DataError naming the file.
    """
    shown = Path(path)
    path = writable_target(path, overwrite, inputs)
    directory = path.parent if str(path.parent) else Path(".")
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=directory)
    except OSError as exc:
        raise DataError(f"{shown}: cannot write in {directory} ({exc.strerror})") from None
    try:
        os.fchmod(fd, mode & ~_umask())
        with os.fdopen(fd, "w" if text else "wb", **({"encoding": "utf-8", "newline": ""} if text else {})) as fh:
            writer(fh)
            fh.flush()
            os.fsync(fh.fileno())
        if overwrite:
            os.replace(tmp, path)
        else:
            _link_exclusive(tmp, path, shown)
    except OSError as exc:
        _remove(tmp)
        if isinstance(exc, FileExistsError):
            raise OutputExists(f"{shown}: exists", "use --force to replace it, or choose another name") from None
        raise DataError(f"{shown}: cannot write ({exc.strerror or exc})") from None
    except BaseException:
        _remove(tmp)
        raise
    _remove(tmp)
    fsync_directory(directory)


def _link_exclusive(tmp: str, path: Path, shown: Path) -> None:
    """Give the finished file its name only if the name is free (atomic: link fails with EEXIST)."""
    try:
        os.link(tmp, path)
    except FileExistsError:
        raise
    except OSError:
        # a file system without hard links: claim the name exclusively, then fill it by rename
        os.close(os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600))
        os.replace(tmp, path)


def _remove(tmp: str) -> None:
    try:
        os.unlink(tmp)
    except FileNotFoundError:
        pass


def accelrig_home() -> Path:
    """The user's accelrig data directory: $ACCELRIG_HOME, else $XDG_DATA_HOME/accelrig, else
    ~/.local/share/accelrig (the profile store, the TUI's captures, simulated devices' records)."""
    home = os.environ.get("ACCELRIG_HOME")
    if home:
        return Path(home)
    xdg = os.environ.get("XDG_DATA_HOME")
    return (Path(xdg) if xdg else Path.home() / ".local" / "share") / "accelrig"


def make_dirs(path: Path, mode: int = 0o755) -> None:
    """Create ``path`` and its missing parents with ``mode`` less the umask (never world-writable when
    the umask is 000: 0755 stays 0755); an OSError is one DataError."""
    missing = []
    p = Path(path)
    while not p.exists() and p != p.parent:
        missing.append(p)
        p = p.parent
    for d in reversed(missing):
        try:
            os.mkdir(d, mode)   # the kernel takes the umask off
        except FileExistsError:
            pass   # made by a concurrent writer: fine
        except OSError as exc:
            raise DataError(f"{path}: cannot create the folder ({exc.strerror})") from None
    if not Path(path).is_dir():
        raise DataError(f"{path}: is not a folder")


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
    """A whole text file (a UTF-8 BOM dropped), or ``error`` in one line saying why not (missing, a
    directory, binary, unreadable); the same checks as ``text_lines``, whose lines it joins."""
    return "".join(line for _, line in text_lines(path, error, what))


def text_lines(path: str | os.PathLike, error: type[AccelrigError] = DataError, what: str = "a CSV file",
               max_line: int = 1 << 24):
    """The lines of a text file, streamed (memory bounded by ``max_line``), a UTF-8 BOM dropped.

    Yields (line number, line).  Every failure is ``error`` in one line: missing, a directory,
    unreadable, binary (naming the line), a line longer than ``max_line`` characters.
    """
    path = Path(path)
    try:
        fh = open(path, encoding="utf-8-sig", newline="")   # -sig: what spreadsheet programs write first
    except FileNotFoundError:
        raise error(f"{path}: no such file") from None
    except IsADirectoryError:
        raise error(f"{path}: is a directory, not {what}") from None
    except OSError as exc:
        raise error(f"{path}: cannot read ({exc.strerror})") from None
    lineno = 0
    with fh:
        while True:
            lineno += 1
            try:
                line = fh.readline(max_line + 1)
            except UnicodeDecodeError:
                raise error(f"{path}:{lineno}: not a text file, so not {what}") from None
            except OSError as exc:
                raise error(f"{path}: cannot read ({exc.strerror})") from None
            if not line:
                return
            if len(line) > max_line:
                raise error(f"{path}:{lineno}: line longer than {max_line} characters, so not {what}")
            if "\x00" in line:
                raise error(f"{path}:{lineno}: holds NUL bytes, so not {what}")
            yield lineno, line
