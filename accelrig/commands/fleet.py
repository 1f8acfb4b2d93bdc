"""accelrig fleet --broker URL [--site SITE] [--json]"""

from __future__ import annotations

import json

from accelrig.commands.collect import add_broker_arguments, broker_options


def register(sub, groups) -> None:
    p = sub.add_parser(
        "fleet",
        description="The devices publishing to an MQTT broker, from their retained status and meta messages: "
        "host, state, last seen, rate, gaps, profile and its age, and under the table what each daemon says is "
        "wrong (e.g. why a device is recording raw). One look, then exit. See docs/fleet.md.",
    )
    add_broker_arguments(p)
    p.add_argument("--timeout", type=float, default=3.0, help="seconds to wait for the broker's answer (default 3)")
    p.add_argument("--recalibrate-days", type=float,
                   help="mark devices whose profile is older than this many days as due for recalibration")
    p.add_argument("--json", action="store_true", help="print the rows as JSON")
    p.set_defaults(func=run)


def run(args) -> int:
    from accelrig.daemon.fleet import format_table, gather, rows

    table = rows(gather(args.broker, timeout=args.timeout, **broker_options(args)),
                 recalibrate_days=args.recalibrate_days)
    print(json.dumps(table, indent=2) if args.json else format_table(table, args.recalibrate_days))
    return 0
