"""accelrig flash PROFILE --device URL [--dry-run] [--yes] [--force]

Shows exactly what would be written (every write: target, current value,
new value, meaning; what stays in the host profile; notes), asks on a
terminal, writes, reads back and verifies.  Works with any driver that
implements Driver.plan_flash / Driver.flash.
"""

from __future__ import annotations

import sys

from accelrig.acquisition.driver import driver_for
from accelrig.acquisition.flash import FlashPlan, FlashReport, check_profile_for_device
from accelrig.errors import DeviceError


def register(sub, groups) -> None:
    p = sub.add_parser(
        "flash",
        help="write a profile's calibration to the device, read it back and verify",
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


def _cell(value) -> str:
    return "(none)" if value is None else str(value)


def format_writes(rows, current_label: str = "current", new_label: str = "new") -> list[str]:
    table = [("target", current_label, new_label, "meaning")] + [
        (w.target, _cell(w.current), _cell(w.new), w.meaning) for w in rows
    ]
    widths = [max(len(r[i]) for r in table) for i in range(3)]
    return ["  " + "  ".join(r[i].ljust(widths[i]) for i in range(3)) + "  " + r[3] for r in table]


def _residual_lines(residual: dict) -> list[str]:
    out = []
    for name, value in residual.items():
        text = f"{value:.4g}" if isinstance(value, float) else str(value)
        out.append(f"  {name}: {text}")
    return out


def format_plan(plan: FlashPlan) -> str:
    lines = [f"Flash plan for {plan.device}: {len(plan.writes)} write(s)"]
    lines += format_writes(plan.writes)
    if plan.residual:
        lines.append("Residual (what the device cannot hold exactly; the host profile keeps it):")
        lines += _residual_lines(plan.residual)
    for note in plan.notes:
        lines.append(f"  note: {note}")
    return "\n".join(lines)


def format_report(report: FlashReport) -> str:
    lines = [f"{'VERIFIED' if report.verified else 'NOT VERIFIED'}: {report.device}"]
    if report.readback:
        lines += format_writes(report.readback, "read back", "intended")
    for note in report.notes:
        lines.append(f"  note: {note}")
    return "\n".join(lines)


def _confirm() -> bool:
    if not sys.stdin or not sys.stdin.isatty():
        raise DeviceError("refusing to write without confirmation: standard input is not a terminal",
                          "pass --yes to write from a script, or --dry-run to only look")
    sys.stdout.write("write? [y/N] ")
    sys.stdout.flush()
    answer = sys.stdin.readline().strip().lower()
    return answer in ("y", "yes")


def run(args) -> int:
    from accelrig.profiles import load_profile

    profile = load_profile(args.profile)
    with driver_for(args.device) as driver:
        notes = check_profile_for_device(profile, driver.info, force=args.force)
        plan = driver.plan_flash(profile)
        plan.notes = notes + list(plan.notes)
        print(format_plan(plan))
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
