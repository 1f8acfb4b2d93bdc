"""The driver interface and the plugin registry.

Drivers are found through the ``accelrig.drivers`` entry-point group; the
built-in ones in ``drivers/`` (import name ``accelrig_drivers``) register there
exactly as a third-party plugin would.  A driver module must import without its
optional dependency: it imports that dependency inside ``open`` (or
``discover``) and raises MissingExtraError when it is absent.
"""

from __future__ import annotations

import abc
from dataclasses import dataclass, field, fields
from importlib.metadata import entry_points
from typing import ClassVar

from accelrig.acquisition.block import Block
from accelrig.acquisition.flash import FlashPlan, FlashReport
from accelrig.acquisition.url import DeviceURL
from accelrig.errors import DeviceError
from accelrig.result import Correction

ENTRY_POINT_GROUP = "accelrig.drivers"


@dataclass
class DeviceInfo:
    """What a driver knows about the device it opened.

    The fields after ``channels`` are known only to some drivers (None
    otherwise); ``extra`` holds driver-specific facts shown to people and read
    by no code.
    """

    driver: str                      # URL scheme of the driver
    url: str
    chip: str                        # e.g. "mpu9250", "icm20948", "sim"
    identity: str                    # serial number, BLE address, bus/address, or sim seed
    range_g: float                   # full scale, +-g
    scale: float                     # m/s^2 per count (nominal)
    requested_rate: float            # Hz
    nominal_rate: float              # Hz the device was configured for
    who_am_i: int | None = None
    channels: tuple[str, ...] = ()   # extra per-sample channels the device delivers
    part: str | None = None                  # the exact part WHO_AM_I names, e.g. "MPU-9255"
    rate_plan: str | None = None             # how the chip makes the rate asked for
    firmware: str | None = None              # firmware version (accelrig-protocol devices)
    calibration_store: bool | None = None    # the firmware can keep a calibration record
    samples_per_frame: int | None = None     # samples per data frame on the link
    link_stats: object | None = None         # protocol.LinkStats: what the link got wrong, counted
    delivered_rate: float | None = None      # Hz, measured against the host clock
    clock_alignment: dict | None = None      # how device time was aligned to host time
    hardware_bias_removed: list | None = None  # m/s^2 the chip subtracts already (flashed offsets)
    offsets_applied: dict | None = None      # the flash report's residual of a profile written at open
    truth: dict | None = None                # a simulated device's ground truth
    extra: dict = field(default_factory=dict)

    # The facts only some drivers know stay under "extra" in to_dict(), where
    # recordings and profiles have always had them.
    _KNOWN_TO_SOME = ("part", "rate_plan", "firmware", "calibration_store", "samples_per_frame", "link_stats",
                      "delivered_rate", "clock_alignment", "hardware_bias_removed", "offsets_applied", "truth")

    def to_dict(self) -> dict:
        d = {f.name: getattr(self, f.name) for f in fields(self)
             if f.name not in self._KNOWN_TO_SOME and f.name != "extra"}
        d["channels"] = list(self.channels)
        known = {name: getattr(self, name) for name in self._KNOWN_TO_SOME if getattr(self, name) is not None}
        d["extra"] = {**known, **self.extra}
        return d


class Driver(abc.ABC):
    """One open device.  Use as a context manager or call open()/close()."""

    scheme: ClassVar[str]
    description: ClassVar[str]
    # a driver on a simulated rig also takes the options of the rig its URL names (besides ``option_help``'s)
    takes_rig_options: ClassVar[bool] = False
    # pip extra that provides the driver's optional dependency, if any.
    extra: ClassVar[str | None] = None

    def __init__(self, url: DeviceURL):
        self.url = url
        self.info: DeviceInfo | None = None

    @classmethod
    def discover(cls) -> list[str]:
        """URLs of devices this driver can find right now (may be empty)."""
        return []

    @classmethod
    def option_help(cls) -> dict[str, str]:
        """The options this driver's URLs take, each with what it does (``accelrig devices --verbose``)."""
        return {}

    def known_options(self) -> set[str] | None:
        """The URL options this driver understands (None: it checks them only when it opens)."""
        return None

    def chip_named(self) -> str | None:
        """The chip this URL names, known without opening anything (a profile's chip is compared with it
        before a deployment starts); None: known only once the device answers."""
        return None

    def check_url(self) -> None:
        """Refuse, without opening anything, a URL with an option this driver does not know: a typo is
        a mistake to correct, not a device to keep reconnecting to (the daemon checks this at start)."""
        known = self.known_options()
        if known is not None:
            self.url.check_known(known)

    @abc.abstractmethod
    def open(self) -> DeviceInfo:
        """Connect and configure the device; return what it is."""

    @abc.abstractmethod
    def read(self, timeout: float = 0.1) -> list[Block]:
        """Return the blocks that arrived, waiting at most ``timeout`` seconds.

        Returns an empty list when nothing arrived.  Raises DeviceError when the
        device is gone.  A finite source (replay, scripted simulation) sets
        ``at_end`` once everything has been delivered.
        """

    @abc.abstractmethod
    def close(self) -> None:
        """Release the device.  Safe to call twice."""

    @property
    def at_end(self) -> bool:
        return False

    @property
    def link_down(self) -> str | None:
        """Why no data can arrive right now though the device is still open (a link being re-established,
        in words), or None.  A recording that ends meanwhile counts the time since its last sample as lost."""
        return None

    @property
    def can_flash(self) -> bool:
        """Whether the device can store a calibration: its driver writes one (overrides ``plan_flash``) and
        the device, once open, does not say it cannot (``info.calibration_store`` False).  Before ``open`` only
        the driver is known (the daemon's configuration check); the one test of both, for every caller."""
        if type(self).plan_flash is Driver.plan_flash:
            return False
        return self.info is None or self.info.calibration_store is not False

    def plan_flash(self, correction: Correction, profile_id: bytes) -> FlashPlan:
        """Work out what storing ``correction`` on the device would write.

        Reads the device, writes nothing.  Drivers whose devices can hold a
        calibration override this and ``flash``; ``profile_id`` (8 bytes) names
        the profile for a device that keeps it.  Whether the profile suits the
        device is checked before, by accelrig.profiles.flash.
        """
        raise DeviceError(
            f"{self.scheme}:// devices cannot store a calibration",
            "keep the profile on the host and apply it to the stream instead",
        )

    def flash(self, plan: FlashPlan) -> FlashReport:
        """Write a plan made by ``plan_flash``, read it back and verify."""
        raise DeviceError(f"{self.scheme}:// devices cannot store a calibration")

    def __enter__(self) -> Driver:
        self.info = self.open()
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def _load(ep) -> type[Driver]:
    """The driver class of one entry point; a plugin that fails to import is named, never skipped."""
    try:
        cls = ep.load()
    except Exception as exc:  # a broken third-party plugin must be named
        raise DeviceError(
            f"driver plugin {ep.name!r} ({ep.value}) failed to load: {exc}",
            "reinstall or uninstall the package that provides it",
        ) from exc
    if not (isinstance(cls, type) and issubclass(cls, Driver)):
        raise DeviceError(f"driver plugin {ep.name!r} ({ep.value}) is not an accelrig Driver")
    return cls


def load_drivers() -> dict[str, type[Driver]]:
    """All installed drivers by URL scheme (each one's module imported)."""
    return {ep.name: _load(ep) for ep in entry_points(group=ENTRY_POINT_GROUP)}


def driver_for(url: str | DeviceURL) -> Driver:
    """Parse ``url`` and return an unopened driver for it; only that scheme's driver is imported."""
    parsed = url if isinstance(url, DeviceURL) else DeviceURL.parse(url)
    found = entry_points(group=ENTRY_POINT_GROUP, name=parsed.scheme)
    if not found:
        known = ", ".join(sorted(f"{ep.name}://" for ep in entry_points(group=ENTRY_POINT_GROUP))) or "none installed"
        raise DeviceError(
            f"unknown device URL scheme {parsed.scheme!r} in {parsed.raw!r}",
            f"installed drivers: {known}",
        )
    return _load(next(iter(found)))(parsed)
