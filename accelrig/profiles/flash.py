"""Flashing a profile to a device: the one place a profile meets a device's calibration storage.

The profile is checked against the device here, once (``check_compatible``,
so ``--force`` means what it means everywhere); the driver is handed only
the Correction and the profile's id and works out the registers or frames
(``Driver.plan_flash``), then writes and reads them back (``Driver.flash``).
The plan is rendered to text here for the CLI and the TUI alike.

``device`` below is an opened Driver or a Session (whose device lock keeps a
flash from interleaving with the pump's reads): both offer ``info``,
``plan_flash`` and ``flash``.
"""

from __future__ import annotations

import hashlib
from urllib.parse import urlencode

import numpy as np
import yaml

from accelrig.acquisition.driver import Driver, driver_for
from accelrig.acquisition.flash import FlashPlan, FlashReport, FlashWrite
from accelrig.acquisition.url import DeviceURL
from accelrig.errors import ProfileError
from accelrig.profiles.apply import CLI_FORCE_HINT, check_compatible
from accelrig.profiles.io import Profile, load_profile


def profile_id(profile: Profile) -> bytes:
    """8 bytes that identify a profile's content (first bytes of the SHA-256 of its YAML)."""
    text = yaml.safe_dump(profile.data, sort_keys=True)
    return hashlib.sha256(text.encode("utf-8")).digest()[:8]


def plan_flash(device, profile: Profile, force: bool = False, force_hint: str = CLI_FORCE_HINT) -> FlashPlan:
    """What storing ``profile``'s correction on ``device`` would write; reads the device, writes nothing.

    A profile made for another device, chip, range or scale is refused
    (ProfileError) unless ``force``; so is one that does not name its chip
    when the writes are registers of one part.  What could not be checked,
    and what ``force`` let through, ends the plan's notes.  ``force_hint`` says how to force where the
    refusal is shown ("" where it cannot be forced).
    """
    same_device = "use the profile made for this device"
    checks = check_compatible(profile, device.info.to_dict(), "counts", force, force_hint or same_device)
    if profile.correction is None:
        raise ProfileError("the profile holds no correction to flash", "calibrate first, then save the profile")
    plan = device.plan_flash(profile.correction, profile_id(profile))
    if plan.chip_specific and profile.device.get("chip") is None:
        problem = "the profile does not say which chip it was made for"
        if not force:
            raise ProfileError(problem, same_device + (f", or {force_hint}" if force_hint else ""))
        plan.notes.append(f"forced: {problem}")
    plan.notes.extend(checks)
    return plan


def flash_url_profile(driver: Driver) -> None:
    """Write the profile a device URL names (``profile=PATH``) to the just-opened device.

    Chip offset registers are volatile, so a URL that names a profile has it
    written on every open, before the first sample is read.
    """
    path = driver.url.get_str("profile")
    if not path:
        return
    report = driver.flash(plan_flash(driver, load_profile(path)))
    driver.info.offsets_applied = report.residual


def url_reapplying(url: str, profile_path) -> str | None:
    """``url`` with ``profile=PROFILE_PATH``, for a device whose calibration store is volatile (its driver takes
    ``profile=``: chip offset registers, which a reopen resets), so every open writes the profile again; None
    for a device that keeps what was flashed (a firmware record) or takes no such option."""
    known = driver_for(url).known_options() or set()
    if "profile" not in known:
        return None
    parsed = DeviceURL.parse(url)
    params = {**parsed.params, "profile": str(profile_path)}
    return f"{url.partition('?')[0]}?{urlencode(params, safe='/:~,')}"


def _cell(value) -> str:
    return "(none)" if value is None else str(value)


def _writes_table(rows: list[FlashWrite], current_label: str = "current", new_label: str = "new",
                  width: int | None = None) -> list[str]:
    """One line per write; when that is wider than ``width`` (a dialog at 80 columns), each write's
    meaning goes on a line of its own under it, so the columns stay columns instead of wrapping."""
    table = [("target", current_label, new_label, "meaning")] + [
        (w.target, _cell(w.current), _cell(w.new), w.meaning) for w in rows
    ]
    widths = [max(len(r[i]) for r in table) for i in range(3)]
    lines = ["  " + "  ".join(r[i].ljust(widths[i]) for i in range(3)) + "  " + r[3] for r in table]
    if width is None or max(len(line) for line in lines) <= width:
        return lines
    return [line for r in table for line in
            ("  " + "  ".join(r[i].ljust(widths[i]) for i in range(3)).rstrip(), "      " + r[3])]


def _value_text(value) -> str:
    """A residual figure with no u beside it, to 6 significant digits (the profile keeps it whole), lists and
    matrices too: the registers' step is about 0.01 m/s^2, and "-0.0020423482931097026" said no more than
    "-0.00204235"."""
    if isinstance(value, float | np.floating):
        return f"{float(value):.6g}"
    if isinstance(value, list | tuple):
        return "[" + ", ".join(_value_text(v) for v in value) + "]"
    return str(value)


def format_plan(plan: FlashPlan, width: int | None = None) -> str:
    """The plan as a person reads it before agreeing: every write, what stays on the host, the notes.
    ``width``: the columns the text is shown in (the TUI's dialog), else the table keeps one line a write."""
    lines = [f"Flash plan for {plan.device}: {len(plan.writes)} write(s)"]
    lines += _writes_table(plan.writes, width=width)
    if plan.residual:
        lines.append("Residual (what the device cannot hold exactly; the host profile keeps it):")
        lines += [f"  {name}: {_value_text(value)}" for name, value in plan.residual.items()]
    lines += [f"  note: {note}" for note in plan.notes]
    return "\n".join(lines)


def format_report(report: FlashReport) -> str:
    """What was written, read back and compared."""
    lines = [f"{'VERIFIED' if report.verified else 'NOT VERIFIED'}: {report.device}"]
    if report.readback:
        lines += _writes_table(report.readback, "read back", "intended")
    lines += [f"  note: {note}" for note in report.notes]
    return "\n".join(lines)
