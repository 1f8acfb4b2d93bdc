"""accelrig collect --broker URL --output DIR [--site SITE]"""

from __future__ import annotations

import signal
import threading


def add_broker_arguments(p, required: bool = True, broker_help: str = "") -> None:
    """The broker options ``collect``, ``fleet`` and ``tui`` share."""
    p.add_argument("--broker", required=required,
                   help=broker_help or "mqtt://HOST[:PORT] or mqtts://HOST[:PORT] (TLS)")
    p.add_argument("--site", help="one site (default: the whole fleet)")
    p.add_argument("--prefix", default="accelrig", help="first part of the topics (default accelrig)")
    p.add_argument("--username", help="user name at the broker")
    secret = p.add_mutually_exclusive_group()
    secret.add_argument("--password-file", metavar="FILE", help="file whose first line is the password")
    secret.add_argument("--password-env", metavar="VARIABLE", help="environment variable holding the password")
    p.add_argument("--ca-file", metavar="FILE", help="with mqtts://: the CA certificate(s) of the broker (PEM)")


def broker_options(args) -> dict:
    from accelrig.daemon.wire import read_password

    return {"site": args.site, "prefix": args.prefix, "username": args.username,
            "password": read_password(args.password_file, args.password_env), "ca_file": args.ca_file}


def register(sub, groups) -> None:
    p = sub.add_parser(
        "collect",
        description="Subscribe to the daemons' blocks on an MQTT broker and write them as segment files, "
        "OUTPUT/SITE/DEVICE/, the same files the daemons write locally (every accelrig reader takes them). "
        "Re-sent blocks are dropped by sequence number; what never arrived becomes a gap record. "
        "Runs until SIGTERM or Ctrl+C. See docs/fleet.md.",
    )
    add_broker_arguments(p)
    p.add_argument("--output", "-o", required=True, help="directory to write into")
    p.add_argument("--client-id", help="MQTT client id of this collector's persistent session "
                   "(default accelrig-collect-HOST-SITE)")
    p.add_argument("--segment-minutes", type=float, default=60.0,
                   help="start a new segment after this many minutes of data (default 60)")
    p.set_defaults(func=run)


def run(args) -> int:
    from pathlib import Path

    from accelrig.daemon.collector import Collector, log

    stop = threading.Event()
    for signum in (signal.SIGTERM, signal.SIGINT):
        signal.signal(signum, lambda *_: stop.set())
    collector = Collector(args.broker, Path(args.output), client_id=args.client_id,
                          segment_seconds=args.segment_minutes * 60.0, **broker_options(args))
    collector.connect()
    try:
        collector.run(stop)
    finally:
        collector.close()
        for line in collector.summary():
            log(line)
        log("stopped")
    return 0
