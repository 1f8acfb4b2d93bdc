"""What a driver says about flashing a calibration, independent of the link.

A driver that can store a calibration implements ``Driver.plan_flash`` (read
what the device holds now, work out what a Correction would write, touch
nothing) and ``Driver.flash`` (write the plan, read it back, verify).  The
orchestration (checking the profile against the device, rendering the plan)
is accelrig.profiles.flash; these classes live here, below it, because the
drivers build them and drivers never import profiles.
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
    # the writes are registers of one part: a profile that does not name its chip is refused
    chip_specific: bool = False


@dataclass
class FlashReport:
    """What happened: each write read back and compared."""

    device: str
    verified: bool
    readback: list[FlashWrite] = field(default_factory=list)  # current = read back, new = intended
    residual: dict = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)

