"""Units at the edges.  Inside accelrig everything is SI: m/s^2, s, rad, Hz."""

from __future__ import annotations

import numpy as np

from accelrig.errors import DataError

STANDARD_GRAVITY = 9.80665  # m/s^2, the default g; a local g is an option (--g)

# The full-scale settings of MEMS accelerometers (+-g), in the order of their 2-bit register code.
MEMS_RANGES_G = (2.0, 4.0, 8.0, 16.0)

# The rails of a sensor's signed 16-bit output, counts.
COUNT_MIN = -32768
COUNT_MAX = 32767
# How close to a rail a sample counts as saturated: one count, because some parts clip
# symmetrically at +-32767, and counts turned into m/s^2 and back may land one count off.
SATURATION_MARGIN = 1

# Accepted spellings of the acceleration units a file or flag may declare.
_UNIT_ALIASES = {
    "m/s2": "m/s^2",
    "m/s^2": "m/s^2",
    "mps2": "m/s^2",
    "si": "m/s^2",
    "g": "g",
    "counts": "counts",
    "count": "counts",
    "lsb": "counts",
}


def normalise_unit(unit: str) -> str:
    """Return the canonical spelling of an acceleration unit or raise DataError."""
    key = unit.strip().lower().replace(" ", "")
    try:
        return _UNIT_ALIASES[key]
    except KeyError:
        raise DataError(
            f"unknown acceleration unit {unit!r}",
            "use one of: m/s2, g, counts",
        ) from None


def to_si(values: np.ndarray, unit: str, scale: float | None = None, g: float = STANDARD_GRAVITY) -> np.ndarray:
    """Convert accelerations in ``unit`` to m/s^2.

    ``scale`` (m/s^2 per count) is needed only for counts.
    """
    unit = normalise_unit(unit)
    values = np.asarray(values, dtype=float)
    if unit == "m/s^2":
        return values
    if unit == "g":
        return values * g
    if scale is None or not np.isfinite(scale) or scale <= 0:
        raise DataError(
            "data are in counts but the counts-to-m/s^2 scale is unknown",
            "give the sensor range (--range-g) or the scale, or convert the file to m/s^2",
        )
    return values * scale


def scale_for_range(range_g: float, bits: int = 16, g: float = STANDARD_GRAVITY) -> float:
    """m/s^2 per count of a full-scale +-range_g sensor with a signed ``bits`` output."""
    return range_g * g / 2 ** (bits - 1)


def saturated(values: np.ndarray, scale: float | None = None, margin: int = SATURATION_MARGIN) -> np.ndarray:
    """Where a sample may have been clipped by the sensor: the one saturation rule.

    ``values`` are int16 counts, or m/s^2 (counts x ``scale``) when ``scale``
    (m/s^2 per count) is given: those are turned back into counts first.  A
    value is saturated at either rail, -32768 or +32767, or within ``margin``
    counts of it.  Returns booleans of the values' shape.
    """
    counts = np.asarray(values) if scale is None else np.rint(np.asarray(values, dtype=float) / scale)
    return (counts >= COUNT_MAX - margin) | (counts <= COUNT_MIN + margin)
