"""What flashing a calibration to a device means, independent of the link.

A driver that can store a calibration implements ``Driver.plan_flash`` (read
what the device holds now, work out what would be written, touch nothing) and
``Driver.flash`` (write the plan, read it back, verify).  The CLI and the TUI
show the plan, ask, then call ``flash``; neither knows registers or frames.
"""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass
class FlashWrite:
    """One thing that will be written: a register field or a firmware record."""

    target: str        # e.g. "XA_OFFSET (0x77/0x78)" or "firmware calibration record"
    current: object    # value the device holds now (as read)
    new: object        # value that will be written
    meaning: str = ""  # e.g. "offset x: -0.0421 m/s^2 -> -43 steps of 0.98 mg"


@dataclass
class FlashPlan:
    """Everything the operator must see before agreeing to a write."""

    device: str                                   # URL / identity of the device
    writes: list[FlashWrite] = field(default_factory=list)
    # what the device cannot represent and so stays in the host profile
    # (e.g. gain and misalignment for chip offset registers, the bias remainder
    # below one register step), in m/s^2 or dimensionless, with its meaning
    residual: dict = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    payload: object = None                        # driver-private data for flash()


@dataclass
class FlashReport:
    """What happened: each write read back and compared."""

    device: str
    verified: bool
    readback: list[FlashWrite] = field(default_factory=list)  # current = read back, new = intended
    residual: dict = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)


# Fields of a profile's ``device`` block that must match the opened device
# (DeviceInfo attribute, label).  who_am_i tells chip variants apart.
_MATCHED_FIELDS = (("chip", "chip"), ("who_am_i", "WHO_AM_I"), ("range_g", "range"), ("identity", "device identity"))


def _same(field_name: str, a, b) -> bool:
    if field_name == "range_g":
        try:
            return abs(float(a) - float(b)) < 1e-9
        except (TypeError, ValueError):
            return False
    if field_name == "who_am_i":
        try:
            return int(str(a), 0) == int(str(b), 0)
        except ValueError:
            return False
    return str(a).strip().lower() == str(b).strip().lower()


def profile_mismatches(profile, info) -> tuple[list[str], list[str]]:
    """Compare a profile's ``device`` block with an opened device's DeviceInfo.

    Returns (mismatches, unchecked): what differs, and what the profile or
    the device does not record so could not be compared.
    """
    recorded = getattr(profile, "device", None) or {}
    mismatches, unchecked = [], []
    for field_name, label in _MATCHED_FIELDS:
        want = recorded.get(field_name)
        have = getattr(info, field_name, None)
        if want is None or have is None:
            if field_name != "who_am_i":  # only chips have one
                unchecked.append(f"{label} not checked (the {'profile' if want is None else 'device'} does not record it)")
            continue
        if not _same(field_name, want, have):
            mismatches.append(f"{label}: profile {want!r}, device {have!r}")
    return mismatches, unchecked


def check_profile_for_device(profile, info, force: bool = False) -> list[str]:
    """Refuse a profile made for another chip, range or device unless ``force``.

    Every flashing path (CLI, TUI, any driver) calls this before
    ``Driver.plan_flash``; drivers do not repeat it, so ``force`` works the
    same everywhere.  Returns notes for the plan (what was forced, what could
    not be checked).
    """
    from accelrig.errors import ProfileError

    mismatches, unchecked = profile_mismatches(profile, info)
    if mismatches and not force:
        raise ProfileError(
            "the profile was made for another device: " + "; ".join(mismatches),
            "flash a profile made on this device, or pass --force to write it anyway",
        )
    return [f"FORCED despite mismatch: {m}" for m in mismatches] + unchecked
