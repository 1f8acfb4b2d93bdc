"""accelrig tui [--device URL]: the guided calibration interface."""

from __future__ import annotations

from accelrig.errors import DeviceError, require_extra


def register(sub, groups) -> None:
    p = sub.add_parser(
        "tui",
        description="Open the terminal interface. With no --device it opens on a simulated static rig, "
        "so it works without hardware.",
    )
    p.add_argument("--device", default=None,
                   help="device URL to open first (default: sim://static, a simulated device)")
    p.add_argument("--profile-dir", default=None,
                   help="directory the wizards offer for saving profiles, captures and reports (default: profiles "
                   "into the profile store, $ACCELRIG_HOME/profiles; captures and reports beside it)")
    p.add_argument("--daemon", metavar="SOCKET_OR_CONFIG", default=None,
                   help="watch a running daemon's devices (read-only): its status socket or its configuration")
    from accelrig.commands.collect import add_broker_arguments

    add_broker_arguments(p, required=False, broker_help="open on the fleet screen: the devices publishing to "
                         "this MQTT broker, live and read-only (mqtt://HOST[:PORT] or mqtts:// for TLS)")
    p.add_argument("--recalibrate-days", type=float,
                   help="fleet screen: mark devices whose profile is older than this many days as due")
    p.set_defaults(func=run)


def run(args) -> int:
    import sys

    require_extra("textual", "the TUI", "textual", "tui")  # says which extra is missing
    if not (sys.stdin.isatty() and sys.stdout.isatty()):
        # drawn into a pipe, the app would never see a key and never exit
        raise DeviceError("accelrig tui needs a terminal: standard input or output is not one",
                          "run it in a terminal; from scripts use the other commands (record, calibrate, ...)")
    from accelrig.tui.app import DEFAULT_DEVICE, AccelrigApp

    socket = None
    if args.daemon is not None:
        from accelrig.daemon.config import load_config

        socket = load_config(args.daemon).status_socket if args.daemon.endswith((".yaml", ".yml")) else args.daemon
    fleet = None
    if args.broker is not None:
        from accelrig.commands.collect import broker_options
        from accelrig.daemon.wire import parse_broker
        from accelrig.tui.screens.fleet import FleetOptions

        parse_broker(args.broker)   # a wrong URL is refused here, in one line, before the screen opens
        fleet = FleetOptions(args.broker, recalibrate_days=args.recalibrate_days, **broker_options(args))
    app = AccelrigApp(device=args.device or DEFAULT_DEVICE, profile_dir=args.profile_dir, daemon_socket=socket,
                      fleet=fleet)
    app.run()
    return int(app.return_code or 0)
