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
from accelrig.errors import AccelrigError

COMMAND_MODULES = (
    "accelrig.commands.devices",
    "accelrig.commands.flash",
    "accelrig.commands.record",
    "accelrig.commands.tui",
    "accelrig.commands.calibrate_rotary",
    "accelrig.commands.calibrate_wheel",
    "accelrig.commands.verify_slider_crank",
    "accelrig.commands.calibrate_static",
    "accelrig.commands.profile",
    "accelrig.commands.noise",
)

HELP_ORDER = ("tui", "devices", "record", "calibrate", "verify", "plan", "noise", "profile", "flash")

GROUPS = {
    "calibrate": "compute a calibration from a recording",
    "verify": "verify a calibration under motion",
    "plan": "predict achievable uncertainties before taking data",
    "profile": "device profiles: list, show, validate, diff, apply, add",
}


def build_parser() -> argparse.ArgumentParser:
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
    for name, help_text in GROUPS.items():
        group_parser = sub.add_parser(name, help=help_text, description=help_text)
        groups[name] = group_parser.add_subparsers(dest=f"{name}_command", metavar="KIND")
        group_parser.set_defaults(func=_group_help(group_parser))
    for module_name in COMMAND_MODULES:
        importlib.import_module(module_name).register(sub, groups)
    # Hide groups nobody registered into yet, so --help never lists a command that does nothing.
    for name, group in groups.items():
        if not group.choices:
            sub._name_parser_map.pop(name, None)
            sub._choices_actions = [a for a in sub._choices_actions if a.dest != name]
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
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        return int(args.func(args) or 0)
    except AccelrigError as exc:
        if args.debug:
            raise
        print(f"accelrig: error: {exc}", file=sys.stderr)
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
