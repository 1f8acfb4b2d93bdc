"""``accelrig fleet``: the fleet as the broker's retained status and meta messages say it is.

Each publishing daemon keeps, per device, a retained ``status`` (JSON, refreshed every
``status_seconds``; the last will turns it into ``{"state": "offline"}``) and a retained
``meta`` (the device, the profile in use).  Subscribing to them returns every device's latest
at once, so one short look at the broker is the whole table.
"""

from __future__ import annotations

import json
import textwrap
import threading
import time
from datetime import UTC, datetime

from accelrig.daemon import wire
from accelrig.tables import TERMINAL_WIDTH, fitted_lines


class FleetWatcher:
    """A live subscription to the fleet's retained ``status`` and ``meta``: ``snapshot()`` is every device's
    latest.  paho's network thread keeps it connected (it reconnects by itself when the broker comes back);
    ``error`` says why it is not connected, in one line."""

    def __init__(self, broker: str, *, site: str | None = None, prefix: str = wire.DEFAULT_PREFIX,
                 username: str | None = None, password: str | None = None, ca_file: str | None = None):
        self.parsed = wire.parse_broker(broker)
        self.site, self.prefix = site, prefix
        self.client = wire.make_client(f"accelrig-fleet-{wire.host_name()}-{time.time_ns() % 10**9}", self.parsed,
                                       username, password, ca_file, clean=True)
        self.client.on_connect = self._on_connect
        self.client.on_disconnect = self._on_disconnect
        self.client.on_message = self._on_message
        self.lock = threading.Lock()
        self.devices: dict[tuple[str, str], dict] = {}
        self.connected = False
        self.refused: str | None = None
        self.login_refused = False        # refused for its login: reconnecting with it is in vain
        self.error: str | None = None
        self.last_message = time.monotonic()

    def _on_connect(self, client, userdata, flags, reason, properties=None):
        if getattr(reason, "is_failure", False):
            self.refused = self.error = wire.connect_error(self.parsed, reason)
            self.login_refused = wire.login_refused(reason)
            return
        self.connected, self.error = True, None
        client.subscribe([(wire.topic(self.prefix, self.site or "+", "+", "status"), 1),
                          (wire.topic(self.prefix, self.site or "+", "+", "meta"), 1)])

    def _on_disconnect(self, client, userdata, flags, reason=None, properties=None):
        if self.connected:
            self.error = f"{self.parsed}: connection lost, reconnecting"
        self.connected = False

    def _on_message(self, client, userdata, message):
        where = wire.split_topic(self.prefix, message.topic)
        if where is None or not message.payload:
            return
        try:
            value = json.loads(message.payload)
        except ValueError:
            value = {"state": "unreadable status"}
        with self.lock:
            self.devices.setdefault(where[:2], {})[where[2]] = value
            self.last_message = time.monotonic()

    def start(self) -> FleetWatcher:
        """Connect (BrokerError in one line when the address is wrong) and keep the subscription live."""
        try:
            self.client.connect(self.parsed.host, self.parsed.port, keepalive=30)
        except OSError as exc:
            raise wire.BrokerError(f"{self.parsed}: cannot connect ({exc.strerror or exc})",
                                   "check the broker's address and that it is running") from None
        self.client.loop_start()
        return self

    def snapshot(self) -> dict[tuple[str, str], dict]:
        with self.lock:
            return {key: dict(value) for key, value in self.devices.items()}

    def close(self) -> None:
        self.client.disconnect()
        self.client.loop_stop()


def gather(broker: str, *, site: str | None = None, prefix: str = wire.DEFAULT_PREFIX,
           username: str | None = None, password: str | None = None, ca_file: str | None = None,
           timeout: float = 3.0, quiet: float = 0.5) -> dict[tuple[str, str], dict]:
    """{(site, device): {"status": ..., "meta": ...}} from the retained messages.

    Returns ``quiet`` seconds after the last message (retained ones come at once), at the
    latest after ``timeout``; BrokerError in one line when refused or unreachable.
    """
    watcher = FleetWatcher(broker, site=site, prefix=prefix, username=username, password=password,
                           ca_file=ca_file).start()
    try:
        start = time.monotonic()
        watcher.last_message = start
        while time.monotonic() - start < timeout and watcher.refused is None:
            time.sleep(0.05)
            if watcher.connected and time.monotonic() - watcher.last_message > quiet and watcher.devices:
                break
        if watcher.refused is not None:
            raise wire.BrokerError(watcher.refused)
        if not watcher.connected:
            raise wire.BrokerError(f"{watcher.parsed}: no answer within {timeout:g} s")
    finally:
        watcher.close()
    return watcher.snapshot()


def _parse_utc(text) -> datetime | None:
    if not text:
        return None
    try:
        return datetime.fromisoformat(str(text).replace("Z", "+00:00"))
    except ValueError:
        return None


def _age(seconds: float | None) -> str:
    if seconds is None:
        return "-"
    for unit, size in (("d", 86400), ("h", 3600), ("min", 60)):
        if seconds >= size:
            return f"{seconds / size:.1f} {unit}"
    return f"{seconds:.0f} s"


def rows(devices: dict, now: datetime | None = None, recalibrate_days: float | None = None) -> list[dict]:
    """One row per device: what the table shows (also ``--json``)."""
    now = now or datetime.now(UTC)
    out = []
    for (site, device), d in sorted(devices.items()):
        status, meta = (v if isinstance(v, dict) else {} for v in (d.get("status"), d.get("meta")))
        seen = _parse_utc(status.get("utc"))
        profile = meta.get("profile") if isinstance(meta.get("profile"), dict) else {}
        created = _parse_utc(profile.get("created"))
        age = (now - created).total_seconds() if created else None
        due = None
        if recalibrate_days is not None:
            due = "no profile" if created is None else ("due" if age > recalibrate_days * 86400 else "ok")
        mqtt = status.get("mqtt") or {}
        out.append({
            "site": site, "device": device, "host": status.get("host") or meta.get("host"),
            "state": status.get("state"), "last_seen": status.get("utc"),
            "seconds_since_seen": (now - seen).total_seconds() if seen else None,
            "rate": status.get("delivered_rate"), "nominal_rate": meta.get("nominal_rate"),
            "gaps": status.get("gaps"), "missing": status.get("missing"),
            "spooled": mqtt.get("spooled"), "spool_dropped_samples": mqtt.get("dropped_samples"),
            "profile": f"{profile.get('procedure')}/{profile.get('method')}" if profile else None,
            "profile_created": profile.get("created"), "profile_age_seconds": age, "recalibration": due,
            "error": status.get("error"),   # what is wrong, as the daemon says it (e.g. why it records raw)
        })
    return out


def columns(recalibrate_days: float | None = None) -> list[str]:
    """The table's column titles (``accelrig fleet`` and the TUI's fleet screen)."""
    head = ["site/device", "host", "state", "last seen", "rate Hz", "gaps", "spooled", "profile", "profile age"]
    if recalibrate_days is not None:
        head.append(f"recal ({recalibrate_days:g} d)")
    return head


# what a narrow table keeps first, most important first (titles of columns(); the recalibration column, when
# asked for, after gaps): whether each device records and when it was last heard of
PRIORITY = ("site/device", "state", "last seen", "rate Hz", "gaps", "RECAL", "profile age", "profile", "spooled",
            "host")


def priority(recalibrate_days: float | None = None) -> list[int]:
    """Indices of columns(), most important first (``accelrig fleet`` and the TUI's fleet screen)."""
    titles = columns(recalibrate_days)
    recal = titles[-1] if recalibrate_days is not None else None
    return [titles.index(recal if title == "RECAL" else title) for title in PRIORITY
            if title != "RECAL" or recal is not None]


def cells(r: dict, recalibrate_days: float | None = None) -> list[str]:
    """One row of ``rows()`` as the table's texts, in the order of ``columns()``."""
    line = [f"{r['site']}/{r['device']}", r["host"] or "-", r["state"] or "-",
            f"{_age(r['seconds_since_seen'])} ago" if r["seconds_since_seen"] is not None else "-",
            f"{r['rate']:.1f}" if r["rate"] else "-", str(r["gaps"]) if r["gaps"] is not None else "-",
            str(r["spooled"]) if r["spooled"] is not None else "-", r["profile"] or "none",
            _age(r["profile_age_seconds"])]
    if recalibrate_days is not None:
        line.append(r["recalibration"])
    return line


NO_DEVICES = "no devices have published under this prefix and site"


def format_table(table: list[dict], recalibrate_days: float | None = None, width: int = TERMINAL_WIDTH) -> str:
    """What ``accelrig fleet`` prints, in lines of at most ``width`` characters: every column (those that do
    not fit stacked under the first table, each part led by the device), then what is wrong."""
    if not table:
        return NO_DEVICES
    lines = fitted_lines(columns(recalibrate_days), [cells(r, recalibrate_days) for r in table],
                         priority(recalibrate_days), width)
    for note in notes(table):
        lines += textwrap.wrap(note, width, subsequent_indent="  ", break_long_words=False, break_on_hyphens=False)
    return "\n".join(lines)


def notes(table: list[dict]) -> list[str]:
    """What the daemons say is wrong, one line per device, under the table (``accelrig fleet``, the TUI)."""
    return [f"{r['site']}/{r['device']}: {r['error']}" for r in table if r.get("error")]
