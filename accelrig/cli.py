"""The ``accelrig`` command.

Each subcommand lives in its own module under ``accelrig.commands`` and
exposes ``register(subparsers, groups)``; ``groups`` holds the sub-subparsers
of the grouped commands (``calibrate``, ``verify``, ``plan``, ``profile``).
An expected failure (AccelrigError) prints one line and exits non-zero; other
exceptions are bugs and keep their traceback.  ``--debug`` shows tracebacks
for expected failures too.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys

from accelrig import __version__
from accelrig.errors import AccelrigError, printable

# Every command: one-line help, and the modules that register it (``register(subparsers,
# groups)``).  A module is imported only when its command is run, so ``accelrig --help``
# and each command start without the others' machinery; a command module imports its own
# machinery inside ``run()``.
COMMANDS = {
    "calibrate": ("compute a calibration from a recording",
                  ("accelrig.commands.calibrate_static", "accelrig.commands.calibrate_wheel",
                   "accelrig.commands.calibrate_rotary")),
    "verify": ("verify a calibration under motion", ("accelrig.commands.verify_slider_crank",)),
    "plan": ("predict achievable uncertainties before taking data", ("accelrig.commands.calibrate_wheel",)),
    "profile": ("device profiles: list, show, validate, diff, apply, add", ("accelrig.commands.profile",)),
    "devices": ("list installed drivers and the devices they find", ("accelrig.commands.devices",)),
    "flash": ("write a profile's calibration to the device, read it back and verify", ("accelrig.commands.flash",)),
    "record": ("record a device to disk: segment directory, .parquet, .csv or .npz", ("accelrig.commands.record",)),
    "tui": ("guided calibration in the terminal (connect, live view, wizards)", ("accelrig.commands.tui",)),
    "noise": ("noise figures (Allan deviation) of a still recording", ("accelrig.commands.noise",)),
    "report": ("calibration certificate (HTML or PDF) from a profile, a result or a campaign",
               ("accelrig.commands.report",)),
    "daemon": ("record several devices to disk for weeks (check, status)", ("accelrig.commands.daemon",)),
    "collect": ("store the fleet's data from an MQTT broker as segment files", ("accelrig.commands.collect",)),
    "fleet": ("the devices publishing to an MQTT broker, as a table", ("accelrig.commands.fleet",)),
}

# Commands with kinds (``accelrig calibrate static``): their modules register into these.
GROUPS = ("calibrate", "verify", "plan", "profile")

HELP_ORDER = ("tui", "devices", "record", "calibrate", "verify", "plan", "noise", "profile", "report", "flash", "daemon",
              "collect", "fleet")


def build_parser(argv: list[str] | None = None) -> argparse.ArgumentParser:
    """The parser: every command listed, the one ``argv`` names (if any) defined in full."""
    argv = sys.argv[1:] if argv is None else argv
    chosen = next((arg for arg in argv if not arg.startswith("-")), None)
    parser = argparse.ArgumentParser(
        prog="accelrig",
        description="Calibrate 3-axis MEMS accelerometers with cheap rigs and keep them calibrated.",
        epilog="Device URLs: sim://RIG, replay://FILE.csv, i2c://BUS/ADDR, serial://PORT, ble://ADDRESS. "
        "'accelrig devices' lists the installed drivers.",
    )
    parser.add_argument("--version", action="version", version=f"accelrig {__version__}")
    parser.add_argument("--debug", action="store_true", help="show tracebacks for expected errors")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    groups: dict[str, argparse._SubParsersAction] = {}
    for name in GROUPS:
        help_text = COMMANDS[name][0]
        group_parser = sub.add_parser(name, help=help_text, description=help_text)
        groups[name] = group_parser.add_subparsers(dest=f"{name}_command", metavar="KIND")
        group_parser.set_defaults(func=_group_help(group_parser))
    for name, (help_text, modules) in COMMANDS.items():
        if name == chosen:
            for module_name in modules:
                importlib.import_module(module_name).register(sub, groups)
        elif name not in GROUPS:
            sub.add_parser(name, help=help_text)  # listed by --help; defined when it is the one run
    # --help lists commands in the order a newcomer uses them
    order = {name: i for i, name in enumerate(HELP_ORDER)}
    sub._choices_actions.sort(key=lambda a: order.get(a.dest, len(order)))
    return parser


def _group_help(group_parser: argparse.ArgumentParser):
    def show(args) -> int:
        group_parser.print_help()
        return 2

    return show


def main(argv: list[str] | None = None) -> int:
    parser = build_parser(argv)
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        return int(args.func(args) or 0)
    except AccelrigError as exc:
        if args.debug:
            raise
        print(f"accelrig: error: {printable(exc)}", file=sys.stderr)   # a file's text never drives the terminal
        return exc.exit_code
    except KeyboardInterrupt:
        print("accelrig: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        # the reader went away (e.g. `accelrig profile show X | head`): not an error;
        # point stdout at devnull so the interpreter's final flush stays quiet
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0


if __name__ == "__main__":
    sys.exit(main())
