"""Device URLs choose the driver, in the manner of pyserial's serial_for_url.

    sim://wheel?seed=3            replay://run.csv
    i2c://1/0x68?chip=mpu9250     serial:///dev/ttyUSB0?baud=921600
    ble://AA:BB:CC:DD:EE:FF
"""

from __future__ import annotations

from dataclasses import dataclass, field
from urllib.parse import parse_qsl, unquote

from accelrig.errors import DeviceError


@dataclass(frozen=True)
class DeviceURL:
    """A parsed device URL.  ``target`` is everything between ``://`` and ``?``."""

    raw: str
    scheme: str
    target: str
    params: dict[str, str] = field(default_factory=dict)

    @classmethod
    def parse(cls, url: str) -> DeviceURL:
        if "://" not in url:
            raise DeviceError(
                f"{url!r} is not a device URL",
                "write it as SCHEME://TARGET, e.g. sim://static or replay://run.csv; "
                "'accelrig devices' lists the schemes",
            )
        scheme, rest = url.split("://", 1)
        scheme = scheme.strip().lower()
        if not scheme:
            raise DeviceError(f"{url!r} has no scheme", "e.g. sim://static")
        target, _, query = rest.partition("?")
        params: dict[str, str] = {}
        for key, value in parse_qsl(query, keep_blank_values=True):
            if key in params:
                raise DeviceError(f"{url!r} gives the option {key!r} twice")
            params[key] = value
        return cls(raw=url, scheme=scheme, target=unquote(target), params=params)

    # Typed option access with errors that name the option and the URL.
    def get_str(self, key: str, default: str | None = None) -> str | None:
        return self.params.get(key, default)

    def get_float(self, key: str, default: float | None = None) -> float | None:
        if key not in self.params:
            return default
        try:
            return float(self.params[key])
        except ValueError:
            raise DeviceError(f"option {key}={self.params[key]!r} in {self.raw!r} is not a number") from None

    def get_int(self, key: str, default: int | None = None) -> int | None:
        if key not in self.params:
            return default
        try:
            return int(self.params[key], 0)
        except ValueError:
            raise DeviceError(f"option {key}={self.params[key]!r} in {self.raw!r} is not an integer") from None

    def get_choice(self, key: str, choices: tuple[str, ...], default: str) -> str:
        value = self.params.get(key, default)
        if value not in choices:
            raise DeviceError(
                f"option {key}={value!r} in {self.raw!r} is not one of {', '.join(choices)}"
            )
        return value

    # The two options every driver takes, checked the same way everywhere.
    def get_rate(self, default: float) -> float:
        """``rate=HZ``: requested sample rate, 1 .. 10000 Hz."""
        rate = self.get_float("rate", default)
        if not 1.0 <= rate <= 10000.0:
            raise DeviceError(f"rate={rate:g} Hz in {self.raw!r} is outside 1 .. 10000 Hz")
        return rate

    def get_range_g(self, default: float) -> float:
        """``range=G``: full scale +-G, one of the MEMS ranges 2, 4, 8, 16."""
        from accelrig.units import MEMS_RANGES_G

        range_g = self.get_float("range", default)
        if range_g not in MEMS_RANGES_G:
            raise DeviceError(f"range={range_g:g} in {self.raw!r} is not a MEMS range",
                              "use " + ", ".join(f"{r:g}" for r in MEMS_RANGES_G))
        return range_g

    def check_known(self, known: set[str]) -> None:
        """Refuse options a driver does not understand (a typo must not pass silently)."""
        unknown = sorted(set(self.params) - known)
        if unknown:
            raise DeviceError(
                f"unknown option(s) {', '.join(unknown)} in {self.raw!r}",
                f"this driver understands: {', '.join(sorted(known)) or 'no options'}",
            )
