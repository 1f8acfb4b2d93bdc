"""systemd's notify protocol, written directly (sd_notify(3)): one datagram per message to $NOTIFY_SOCKET.

With ``Type=notify`` systemd waits for ``READY=1``; with ``WatchdogSec=`` it
expects ``WATCHDOG=1`` at least every $WATCHDOG_USEC microseconds and kills
the service when they stop.  Outside systemd (no NOTIFY_SOCKET) every call
does nothing.
"""

from __future__ import annotations

import os
import socket


def notify(message: str) -> bool:
    """Send ``message`` (e.g. "READY=1\\nSTATUS=...") to systemd; False when not run by systemd."""
    address = os.environ.get("NOTIFY_SOCKET")
    if not address:
        return False
    if address.startswith("@"):           # an abstract socket
        address = "\0" + address[1:]
    try:
        with socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM | socket.SOCK_CLOEXEC) as sock:
            sock.connect(address)
            sock.sendall(message.encode("utf-8"))
    except OSError:
        return False  # systemd went away or the socket is not ours: nothing to tell
    return True


def watchdog_interval() -> float | None:
    """Seconds between WATCHDOG=1 messages (half systemd's limit), or None when no watchdog is set."""
    usec = os.environ.get("WATCHDOG_USEC")
    pid = os.environ.get("WATCHDOG_PID")
    if not usec or (pid and pid.strip() != str(os.getpid())):
        return None
    try:
        value = int(usec)
    except ValueError:
        return None
    return value / 2e6 if value > 0 else None
