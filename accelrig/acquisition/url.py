"""Device URLs choose the driver, in the manner of pyserial's serial_for_url.

    sim://wheel?seed=3            replay://run.csv
    i2c://1/0x68?chip=mpu9250     serial:///dev/ttyUSB0?baud=921600
    ble://AA:BB:CC:DD:EE:FF
"""

from __future__ import annotations

from dataclasses import dataclass, field
from urllib.parse import parse_qsl, unquote

from accelrig.errors import DataError, DeviceError
from accelrig.settings import Setting


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

    def get_float(self, key: str, default: float | None = None, low: float | None = None,
                  high: float | None = None, low_open: bool = False, unit: str = "") -> float | None:
        """``key=X`` as a finite number within [low, high] (low exclusive with ``low_open``), or ``default``."""
        return self._number(key, default, "float", low, high, low_open, unit)

    def get_int(self, key: str, default: int | None = None, low: int | None = None,
                high: int | None = None) -> int | None:
        """``key=N`` as a whole number (decimal or 0x..) within [low, high], or ``default``."""
        if key in self.params:
            try:
                value = int(self.params[key], 0)
            except ValueError:
                raise DeviceError(f"option {key}={self.params[key]!r} in {self.raw!r} is not an integer") from None
            if abs(value) > 2 ** 63:
                raise DeviceError(f"option {key}={self.params[key][:20]}... in {self.raw!r} is too large")
            return self._number(key, default, "int", low, high, False, "", value)
        return default

    def _number(self, key, default, kind, low, high, low_open, unit, value=None):
        """One check for every numeric option: the declared Setting bounds (accelrig.settings) say what
        is refused, in the words a flag or a form field would use."""
        if key not in self.params:
            return default
        setting = Setting(key, key, unit=unit, kind=kind, low=low, high=high, low_open=low_open)
        try:
            return setting.parse(self.params[key] if value is None else value, where=f"option {key} in {self.raw!r}:")
        except DataError as exc:
            raise DeviceError(exc.message, exc.hint) from None

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
        return self.get_float("rate", default, low=1.0, high=10000.0, unit="Hz")

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
