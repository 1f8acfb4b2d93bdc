"""The driver interface and the plugin registry.

Drivers are found through the ``accelrig.drivers`` entry-point group; the
built-in ones in ``drivers/`` (import name ``accelrig_drivers``) register there
exactly as a third-party plugin would.  A driver module must import without its
optional dependency: it imports that dependency inside ``open`` (or
``discover``) and raises MissingExtraError when it is absent.
"""

from __future__ import annotations

import abc
from dataclasses import asdict, dataclass, field
from importlib.metadata import entry_points
from typing import ClassVar

from accelrig.acquisition.block import Block
from accelrig.acquisition.flash import FlashPlan, FlashReport
from accelrig.acquisition.url import DeviceURL
from accelrig.errors import DeviceError

ENTRY_POINT_GROUP = "accelrig.drivers"


@dataclass
class DeviceInfo:
    """What a driver knows about the device it opened."""

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
    extra: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        d = asdict(self)
        d["channels"] = list(self.channels)
        return d


class Driver(abc.ABC):
    """One open device.  Use as a context manager or call open()/close()."""

    scheme: ClassVar[str]
    description: ClassVar[str]
    # pip extra that provides the driver's optional dependency, if any.
    extra: ClassVar[str | None] = None

    def __init__(self, url: DeviceURL):
        self.url = url
        self.info: DeviceInfo | None = None

    @classmethod
    def discover(cls) -> list[str]:
        """URLs of devices this driver can find right now (may be empty)."""
        return []

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

    def plan_flash(self, profile, force: bool = False) -> "FlashPlan":
        """Work out what storing ``profile``'s calibration on the device would write.

        Reads the device, writes nothing.  Drivers whose devices can hold a
        calibration override this and ``flash``; they refuse a profile made for
        another device with ``accelrig.profiles.check_compatible`` unless
        ``force``, and put its warnings in the plan's notes.
        """
        raise DeviceError(
            f"{self.scheme}:// devices cannot store a calibration",
            "keep the profile on the host and apply it to the stream instead",
        )

    def flash(self, plan: "FlashPlan") -> "FlashReport":
        """Write a plan made by ``plan_flash``, read it back and verify."""
        raise DeviceError(f"{self.scheme}:// devices cannot store a calibration")

    def __enter__(self) -> "Driver":
        self.info = self.open()
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def load_drivers() -> dict[str, type[Driver]]:
    """All installed drivers by URL scheme.

    A plugin that fails to import is reported as a DeviceError naming it, never
    skipped silently.
    """
    drivers: dict[str, type[Driver]] = {}
    for ep in entry_points(group=ENTRY_POINT_GROUP):
        try:
            cls = ep.load()
        except Exception as exc:  # a broken third-party plugin must be named
            raise DeviceError(
                f"driver plugin {ep.name!r} ({ep.value}) failed to load: {exc}",
                "reinstall or uninstall the package that provides it",
            ) from exc
        if not (isinstance(cls, type) and issubclass(cls, Driver)):
            raise DeviceError(f"driver plugin {ep.name!r} ({ep.value}) is not an accelrig Driver")
        drivers[ep.name] = cls
    return drivers


def driver_for(url: str | DeviceURL) -> Driver:
    """Parse ``url`` and return an unopened driver for it."""
    parsed = url if isinstance(url, DeviceURL) else DeviceURL.parse(url)
    drivers = load_drivers()
    try:
        cls = drivers[parsed.scheme]
    except KeyError:
        known = ", ".join(f"{s}://" for s in sorted(drivers)) or "none installed"
        raise DeviceError(
            f"unknown device URL scheme {parsed.scheme!r} in {parsed.raw!r}",
            f"installed drivers: {known}",
        ) from None
    return cls(parsed)
