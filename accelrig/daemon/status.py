"""The daemon's status socket: a unix socket only its owner may use, answering one JSON document per connection.

``serve`` runs in the daemon; ``query`` is the client (``accelrig daemon
status`` and the TUI's daemon screen both use it); ``format_table`` renders
the answer for a terminal.
"""

from __future__ import annotations

import json
import os
import socket
import stat
import textwrap
import threading
from collections.abc import Callable
from pathlib import Path

from accelrig.errors import AccelrigError
from accelrig.tables import TERMINAL_WIDTH, fitted_lines


class StatusError(AccelrigError):
    """The daemon's status could not be read."""

    exit_code = 8


def _answers(path: Path) -> bool:
    try:
        with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as sock:
            sock.settimeout(1.0)
            sock.connect(str(path))
        return True
    except OSError:
        return False


class StatusServer:
    """Answers every connection with ``snapshot()`` as JSON, then closes it."""

    def __init__(self, path: Path, snapshot: Callable[[], dict]):
        self.path = Path(path)
        self.snapshot = snapshot
        self._sock: socket.socket | None = None
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def start(self) -> None:
        from accelrig.daemon.config import ConfigError

        path = self.path
        if path.exists() or path.is_symlink():
            if _answers(path):
                raise ConfigError(f"status_socket: another daemon answers on {path}",
                                  "stop it first, or give this one its own output and status_socket")
            if not stat.S_ISSOCK(path.lstat().st_mode):
                raise ConfigError(f"status_socket: {path} exists and is not a socket", "choose another path")
            path.unlink()   # left by a daemon that was killed
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise ConfigError(f"status_socket: cannot create {path.parent} ({exc.strerror})") from None
        sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        old = os.umask(0o177)        # born owner-only: no moment when others could connect
        try:
            sock.bind(str(path))
        except OSError as exc:
            sock.close()
            raise ConfigError(f"status_socket: cannot create {path} ({exc.strerror})",
                              "choose a path the daemon may write (e.g. under output)") from None
        finally:
            os.umask(old)
        os.chmod(path, 0o600)
        sock.listen(8)
        sock.settimeout(0.5)
        self._sock = sock
        self._thread = threading.Thread(target=self._serve, name="accelrig status socket", daemon=True)
        self._thread.start()

    def _serve(self) -> None:
        while not self._stop.is_set():
            try:
                conn, _ = self._sock.accept()
            except TimeoutError:
                continue
            except OSError:
                return
            with conn:
                try:
                    conn.settimeout(2.0)
                    conn.sendall(json.dumps(self.snapshot(), default=str).encode("utf-8") + b"\n")
                except OSError:
                    pass  # the client went away

    def stop(self) -> None:
        self._stop.set()
        if self._sock is not None:
            self._sock.close()
        if self._thread is not None:
            self._thread.join(2.0)
        try:
            self.path.unlink()
        except FileNotFoundError:
            pass


def query(path: str | os.PathLike, timeout: float = 3.0) -> dict:
    """The status a running daemon reports on its socket; StatusError in one line when there is none."""
    path = Path(path)
    if not path.exists():
        raise StatusError(f"no status socket at {path}: is the daemon running?",
                          "start it with 'accelrig daemon --config FILE', or give its --socket")
    try:
        with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as sock:
            sock.settimeout(timeout)
            sock.connect(str(path))
            data = b""
            while chunk := sock.recv(65536):
                data += chunk
    except PermissionError:
        raise StatusError(f"{path}: permission denied (the status socket is its owner's only)",
                          "run as the daemon's user") from None
    except ConnectionRefusedError:
        raise StatusError(f"{path}: nobody answers (a daemon that was killed left it)",
                          "start the daemon again") from None
    except OSError as exc:
        raise StatusError(f"{path}: {exc.strerror or exc}") from None
    try:
        return json.loads(data)
    except ValueError:
        raise StatusError(f"{path}: the answer is not the daemon's JSON status") from None


COLUMNS = (
    ("name", "device"), ("state", "state"), ("rate", "Hz"), ("delivered", "delivered"), ("written", "written"),
    ("dropped", "dropped"), ("missing", "missing"), ("gaps", "gaps"), ("connects", "connects"),
    ("size", "written MB"), ("profile", "profile"),
)
# what a narrow table keeps first, most important first: whether each device records, its losses, the profile;
# delivered is written + dropped (the CLI stacks the rest under the table, the TUI names what it left out)
PRIORITY = ("name", "state", "rate", "gaps", "missing", "dropped", "profile", "size", "written", "connects",
            "delivered")


def device_row(d: dict) -> dict[str, str]:
    """One device's status as table cells (shared by the CLI table and the TUI screen)."""
    return {
        "name": d["name"],
        "state": d["state"],
        "rate": f"{d['delivered_rate']:.1f}" if d.get("delivered_rate") else "-",
        "delivered": str(d["delivered"]),
        "written": str(d["written"]),
        "dropped": str(d["dropped"]),
        "missing": str(d["missing"]),
        "gaps": str(d["gaps"]),
        "connects": str(d["connects"]),
        "size": f"{d['bytes_written'] / 1e6:.1f}",
        "profile": str(d["profile"]),
    }


def format_table(status: dict, width: int = TERMINAL_WIDTH) -> str:
    """What ``accelrig daemon status`` prints, in lines of at most ``width`` characters: every column (those
    that do not fit stacked under the first table, each part led by the device), then what is wrong."""
    daemon = status["daemon"]
    keys = [key for key, _ in COLUMNS]
    rows, paths = [], []
    for d in status["devices"]:
        row = device_row(d)
        if "/" in row["profile"]:   # a profile file: its name in the table, its path under it
            paths.append(f"{d['name']}: profile {row['profile']}")
            row["profile"] = Path(row["profile"]).name
        rows.append([row[key] for key in keys])

    def wrapped(text: str) -> list[str]:   # a long path or message breaks at spaces, never mid-word
        return textwrap.wrap(text, width, subsequent_indent="  ", break_long_words=False, break_on_hyphens=False)

    lines = wrapped(f"accelrig daemon pid {daemon['pid']}, up {daemon['uptime']:.0f} s, config {daemon['config']}, "
                    f"output {daemon['output']}")
    lines += fitted_lines([title for _, title in COLUMNS], rows, [keys.index(key) for key in PRIORITY], width)
    for path in paths:
        lines += wrapped(path)
    for d in status["devices"]:
        if d.get("error"):
            lines += wrapped(f"{d['name']}: {d['error']}")
    for d in status["devices"]:
        if d.get("mqtt"):
            lines += wrapped(f"{d['name']}: mqtt: {mqtt_summary(d['mqtt'])}")
    return "\n".join(lines)


def mqtt_summary(m: dict) -> str:
    """One device's publishing, in words (daemon status, status lines)."""
    text = (f"{'connected to' if m['connected'] else 'not connected to'} {m['broker']}, {m['spooled']} spooled "
            f"({m['spool_bytes'] / 1e6:.1f} MB), {m['acknowledged']} acknowledged")
    if m["dropped_samples"]:
        text += f", {m['dropped_samples']} samples dropped from a full spool (sent as gaps)"
    if m.get("reconnects"):
        text += f", {m['reconnects']} reconnects"
    if m.get("error"):
        text += f" ({m['error']})"
    return text
