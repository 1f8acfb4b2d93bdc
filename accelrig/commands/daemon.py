"""accelrig daemon --config FILE | daemon check FILE | daemon status"""

from __future__ import annotations

import json

from accelrig.errors import DataError


def register(sub, groups) -> None:
    p = sub.add_parser(
        "daemon",
        description="Record several devices to disk for weeks: reconnects, gaps recorded with their cause, "
        "SIGTERM/SIGINT stop cleanly, SIGHUP reloads the configuration. A device whose profile is missing "
        "records its raw counts anyway, in state 'recording raw' with the reason in its status, log and "
        "segments (per device, without_profile: stop stops it instead); the reload after filing the profile "
        "restarts it with it. See docs/daemon.md.",
        epilog="Minimal configuration: 'output: DIR' and 'devices: [{url: sim://still?seed=1, name: bench-a}]'. "
        "The JSON Schema is profiles/daemon-config-v1.json.",
    )
    p.add_argument("--config", metavar="FILE", help="the daemon's YAML configuration (run the daemon)")
    p.set_defaults(func=run)
    kinds = p.add_subparsers(dest="daemon_command", metavar="ACTION")
    check = kinds.add_parser("check", help="validate a configuration without starting anything",
                             description="Validate a configuration without opening any device: every field, "
                             "the device URLs, profile files (and their chip against the one a URL names), "
                             "flash only where the device can hold offsets, and that the output can be "
                             "written; notes say what will be looked up when the devices answer.")
    check.add_argument("config", help="the daemon's YAML configuration")
    check.set_defaults(func=run_check)
    status = kinds.add_parser("status", help="the devices of a running daemon, as a table",
                              description="Ask a running daemon for its devices' status through its socket: "
                              "every configured device (state starting until it connects), and under the "
                              "table what is wrong with each (e.g. why it is recording raw).")
    where = status.add_mutually_exclusive_group(required=True)
    where.add_argument("--config", dest="status_config", metavar="FILE",
                       help="the running daemon's configuration (finds its socket)")
    where.add_argument("--socket", metavar="PATH", help="the daemon's status socket")
    status.add_argument("--json", action="store_true", help="print the daemon's JSON answer")
    status.set_defaults(func=run_status)
    schema = kinds.add_parser("schema", help="print the configuration's JSON Schema",
                              description="Print the JSON Schema of the configuration (as published in "
                              "profiles/daemon-config-v1.json).")
    schema.set_defaults(func=run_schema)


def run(args) -> int:
    if not args.config:
        raise DataError("accelrig daemon needs --config FILE",
                        "or one of: daemon check FILE, daemon status, daemon schema (see docs/daemon.md)")
    from accelrig.daemon.service import run_daemon

    return run_daemon(args.config)


def run_check(args) -> int:
    from accelrig.daemon.config import check_config, load_config

    config = load_config(args.config)
    notes = check_config(config)
    print(f"{args.config}: valid: {len(config.devices)} device(s) "
          f"({', '.join(d.name for d in config.devices)}), output {config.output}, "
          f"status socket {config.status_socket}")
    for note in notes:
        print(f"  {note}")
    return 0


def run_status(args) -> int:
    from accelrig.daemon.status import format_table, query

    if args.socket:
        path = args.socket
    else:
        from accelrig.daemon.config import load_config

        path = load_config(args.status_config).status_socket
    answer = query(path)
    print(json.dumps(answer, indent=2) if args.json else format_table(answer))
    return 0


def run_schema(args) -> int:
    from accelrig.daemon.config import json_schema_text

    print(json_schema_text(), end="")
    return 0
