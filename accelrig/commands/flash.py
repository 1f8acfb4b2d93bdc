"""accelrig flash PROFILE --device URL [--dry-run] [--yes] [--force]

Shows exactly what would be written (every write: target, current value,
new value, meaning; what stays in the host profile; notes), asks on a
terminal, writes, reads back and verifies.  Works with any driver that
implements Driver.plan_flash / Driver.flash (accelrig.profiles.flash).
"""

from __future__ import annotations

import sys

from accelrig.errors import DeviceError, printable


def register(sub, groups) -> None:
    p = sub.add_parser(
        "flash",
        description="Write a profile's calibration to a device. Shows the plan first and asks before writing; "
        "without a terminal it writes only with --yes.",
    )
    p.add_argument("profile", help="profile YAML file")
    p.add_argument("--device", required=True, metavar="URL", help="device URL, e.g. serial:///dev/ttyUSB0 or i2c://1/0x68")
    p.add_argument("--dry-run", action="store_true", help="show what would be written and stop")
    p.add_argument("--yes", "-y", action="store_true", help="write without asking")
    p.add_argument("--force", action="store_true",
                   help="write even if the profile was made for another chip, range or device")
    p.set_defaults(func=run)


def _confirm() -> bool:
    if not sys.stdin or not sys.stdin.isatty():
        raise DeviceError("refusing to write without confirmation: standard input is not a terminal",
                          "pass --yes to write from a script, or --dry-run to only look")
    sys.stdout.write("write? [y/N] ")
    sys.stdout.flush()
    answer = sys.stdin.readline().strip().lower()
    return answer in ("y", "yes")


def run(args) -> int:
    from accelrig.acquisition.driver import driver_for
    from accelrig.profiles import load_profile
    from accelrig.profiles.flash import format_plan, format_report, plan_flash

    profile = load_profile(args.profile)
    with driver_for(args.device) as driver:
        plan = plan_flash(driver, profile, args.force)
        # the plan quotes the profile (its identity, warnings): each line escaped before the terminal sees it
        print("\n".join(printable(line) for line in format_plan(plan).splitlines()))
        if args.dry_run:
            print("dry run: nothing written")
            return 0
        if not args.yes and not _confirm():
            print("nothing written")
            return 1
        report = driver.flash(plan)
        print(format_report(report))
    if not report.verified:
        raise DeviceError(f"flash of {args.device} did not verify: the device holds something else than was written",
                          "flash again; if it persists the device's storage is faulty")
    return 0
