"""``accelrig fleet``: the fleet as the broker's retained status and meta messages say it is.

Each publishing daemon keeps, per device, a retained ``status`` (JSON, refreshed every
``status_seconds``; the last will turns it into ``{"state": "offline"}``) and a retained
``meta`` (the device, the profile in use).  Subscribing to them returns every device's latest
at once, so one short look at the broker is the whole table.
"""

from __future__ import annotations

import json
import threading
import time
from datetime import UTC, datetime

from accelrig.daemon import wire


def gather(broker: str, *, site: str | None = None, prefix: str = wire.DEFAULT_PREFIX,
           username: str | None = None, password: str | None = None, ca_file: str | None = None,
           timeout: float = 3.0, quiet: float = 0.5) -> dict[tuple[str, str], dict]:
    """{(site, device): {"status": ..., "meta": ...}} from the retained messages.

    Returns ``quiet`` seconds after the last message (retained ones come at once), at the
    latest after ``timeout``; BrokerError in one line when refused or unreachable.
    """
    parsed = wire.parse_broker(broker)
    client = wire.make_client(f"accelrig-fleet-{wire.host_name()}-{time.time_ns() % 10**9}", parsed,
                              username, password, ca_file, clean=True)
    devices: dict[tuple[str, str], dict] = {}
    lock = threading.Lock()
    outcome: dict = {}
    last = [time.monotonic()]

    def on_connect(client, userdata, flags, reason, properties=None):
        if getattr(reason, "is_failure", False):
            outcome["refused"] = wire.connect_error(parsed, reason)
            return
        outcome["connected"] = True
        client.subscribe([(wire.topic(prefix, site or "+", "+", "status"), 1),
                          (wire.topic(prefix, site or "+", "+", "meta"), 1)])

    def on_message(client, userdata, message):
        where = wire.split_topic(prefix, message.topic)
        if where is None or not message.payload:
            return
        try:
            value = json.loads(message.payload)
        except ValueError:
            value = {"state": "unreadable status"}
        with lock:
            devices.setdefault(where[:2], {})[where[2]] = value
            last[0] = time.monotonic()

    client.on_connect = on_connect
    client.on_message = on_message
    try:
        client.connect(parsed.host, parsed.port, keepalive=30)
    except OSError as exc:
        raise wire.BrokerError(f"{parsed}: cannot connect ({exc.strerror or exc})",
                               "check the broker's address and that it is running") from None
    client.loop_start()
    try:
        start = time.monotonic()
        last[0] = start
        while time.monotonic() - start < timeout and "refused" not in outcome:
            time.sleep(0.05)
            if "connected" in outcome and time.monotonic() - last[0] > quiet and devices:
                break
        if "refused" in outcome:
            raise wire.BrokerError(outcome["refused"])
        if "connected" not in outcome:
            raise wire.BrokerError(f"{parsed}: no answer within {timeout:g} s")
    finally:
        client.disconnect()
        client.loop_stop()
    with lock:
        return dict(devices)


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
        about = meta.get("device") if isinstance(meta.get("device"), dict) else {}
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
            "rate": status.get("delivered_rate"), "nominal_rate": about.get("nominal_rate"),
            "gaps": status.get("gaps"), "missing": status.get("missing"),
            "spooled": mqtt.get("spooled"), "spool_dropped_samples": mqtt.get("dropped_samples"),
            "profile": f"{profile.get('procedure')}/{profile.get('method')}" if profile else None,
            "profile_created": profile.get("created"), "profile_age_seconds": age, "recalibration": due,
        })
    return out


def format_table(table: list[dict], recalibrate_days: float | None = None) -> str:
    if not table:
        return "no devices have published under this prefix and site"
    head = ["site/device", "host", "state", "last seen", "rate Hz", "gaps", "spooled", "profile", "profile age"]
    if recalibrate_days is not None:
        head.append(f"recal ({recalibrate_days:g} d)")
    lines = [head]
    for r in table:
        line = [f"{r['site']}/{r['device']}", r["host"] or "-", r["state"] or "-",
                f"{_age(r['seconds_since_seen'])} ago" if r["seconds_since_seen"] is not None else "-",
                f"{r['rate']:.1f}" if r["rate"] else "-", str(r["gaps"]) if r["gaps"] is not None else "-",
                str(r["spooled"]) if r["spooled"] is not None else "-", r["profile"] or "none",
                _age(r["profile_age_seconds"])]
        if recalibrate_days is not None:
            line.append(r["recalibration"])
        lines.append(line)
    widths = [max(len(str(line[i])) for line in lines) for i in range(len(head))]
    return "\n".join("  ".join(str(v).ljust(w) for v, w in zip(line, widths, strict=True)).rstrip()
                     for line in lines)
