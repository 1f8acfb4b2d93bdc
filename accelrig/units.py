"""Units at the edges.  Inside accelrig everything is SI: m/s^2, s, rad, Hz."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from accelrig.errors import DataError

STANDARD_GRAVITY = 9.80665  # m/s^2, the default g; a local g is an option (--g, or --latitude and --height)

# Gravity on Earth runs from 9.780 (equator, sea level) to 9.832 m/s^2 (poles).  Standard gravity stands
# for any of those: a rectangular distribution from 9.780 to 9.832 around it, u = half-width / sqrt(3)
# (the half-width is the larger side, 9.80665 - 9.780).
EARTH_GRAVITY_RANGE = (9.780, 9.832)
STANDARD_GRAVITY_U = (STANDARD_GRAVITY - EARTH_GRAVITY_RANGE[0]) / 3**0.5
# Normal gravity (the formula) misses the local gravity anomaly: free-air anomalies are a few 1e-4 m/s^2
# in the plains (rms about 3e-4 worldwide) and reach 2-3e-3 in high mountains.  1e-3 m/s^2 (1e-4 of g)
# covers the plains at 3 sd and most places at 1 sd; for better, give a surveyed g with --g and --g-u.
NORMAL_GRAVITY_U = 1e-3

# WGS-84 (NIMA TR8350.2, 3rd ed., 2000, ch. 4): normal gravity on the ellipsoid (Somigliana's closed
# form, eq. 4-1) and its height dependence (the second-order free-air expansion, eq. 4-3).
_WGS84_GAMMA_E = 9.7803253359        # m/s^2 at the equator
_WGS84_K = 0.00193185265241          # Somigliana's constant (b gamma_p - a gamma_e) / (a gamma_e)
_WGS84_E2 = 0.00669437999013         # first eccentricity squared
_WGS84_A = 6378137.0                 # semi-major axis, m
_WGS84_F = 1.0 / 298.257223563       # flattening
_WGS84_M = 0.00344978650684          # omega^2 a^2 b / GM


def normal_gravity(latitude_deg: float, height_m: float = 0.0) -> float:
    """Normal gravity of the WGS-84 ellipsoid (equal to GRS80's to 1e-8 m/s^2), m/s^2.

    gamma(phi) = gamma_e (1 + k sin^2 phi) / sqrt(1 - e^2 sin^2 phi)            (Somigliana)
    gamma(phi, h) = gamma(phi) [1 - 2 (1 + f + m - 2 f sin^2 phi) h / a + 3 h^2 / a^2]   (free-air)
    ``latitude_deg`` geodetic latitude, ``height_m`` above the ellipsoid (a map's height above sea level
    differs by the geoid, at most about 100 m: 3e-4 m/s^2, inside NORMAL_GRAVITY_U).
    """
    s2 = float(np.sin(np.radians(latitude_deg))) ** 2
    gamma = _WGS84_GAMMA_E * (1.0 + _WGS84_K * s2) / np.sqrt(1.0 - _WGS84_E2 * s2)
    h = float(height_m)
    return float(gamma * (1.0 - 2.0 / _WGS84_A * (1.0 + _WGS84_F + _WGS84_M - 2.0 * _WGS84_F * s2) * h
                          + 3.0 * h * h / _WGS84_A**2))


TYPED_G_SOURCE = "given (--g); u is its rounding as typed"


@dataclass
class LocalGravity:
    """The g a calibration uses, its standard uncertainty and where it came from."""

    value: float
    u: float
    source: str

    def to_dict(self) -> dict:
        return {"g": self.value, "g_u": self.u, "g_source": self.source}

    @property
    def warning(self) -> str | None:
        """A g typed with many digits gets a tiny u by the documented rule (its rounding as typed): 9.81744 gives
        2.9e-6 m/s^2, 300 times below what a g can honestly have without a survey (NORMAL_GRAVITY_U, the normal
        gravity formula's own accuracy for a latitude and height); the gains' u would shrink with it and such a
        device would dominate a weighted mean.  Said, with the way to state u(g); the rule stays."""
        if not self.source.startswith(TYPED_G_SOURCE) or self.u >= NORMAL_GRAVITY_U:
            return None
        return (f"u(g) {self.u:.2g} m/s^2 comes from the digits of g {self.value:g} as typed, below the "
                f"{NORMAL_GRAVITY_U:g} m/s^2 a g can have without a survey (the accuracy of the normal gravity "
                "formula for a latitude and height): the gains' u rests on it; unless g was surveyed that well, "
                f"state u(g) itself (--g-u, e.g. {NORMAL_GRAVITY_U:g}), or give the latitude and height instead")


def _typed_rounding_u(value: float) -> float:
    """u of a number as typed: half a unit of its last decimal, rectangular (9.81 -> 0.005 / sqrt(3))."""
    text = repr(float(value))
    decimals = len(text.split(".")[1]) if "." in text and "e" not in text else 6
    return 0.5 * 10.0 ** -decimals / 3**0.5


def local_gravity(g: float | None = None, latitude: float | None = None, height: float | None = None,
                  g_u: float | None = None) -> LocalGravity:
    """The one way a procedure's g settings become g and u(g) (the settings in accelrig.settings.GRAVITY_SETTINGS).

    latitude (and height, default 0 m) -> normal_gravity, u NORMAL_GRAVITY_U;
    g standard gravity (the default)   -> u STANDARD_GRAVITY_U (it stands for anywhere on Earth);
    another g                           -> u its rounding as typed (half a unit of the last decimal);
    g_u, when given, replaces the u.
    """
    given_g = g is not None and float(g) != STANDARD_GRAVITY
    if height is not None and latitude is None:
        raise DataError("--height needs --latitude: the height changes g only with the latitude's normal gravity",
                        "give --latitude DEG too, or give the local g itself with --g")
    if latitude is not None and given_g:
        raise DataError(f"both --g {g} and --latitude {latitude} give local gravity",
                        "give one: --g M/S2, or --latitude DEG with --height M")
    if latitude is not None:
        h = 0.0 if height is None else float(height)
        value = normal_gravity(float(latitude), h)
        u, source = NORMAL_GRAVITY_U, (f"WGS-84 normal gravity at latitude {float(latitude):g} deg, height {h:g} m "
                                       "(Somigliana, free-air)")
    elif given_g:
        value = float(g)
        u, source = _typed_rounding_u(value), TYPED_G_SOURCE
    else:
        value = STANDARD_GRAVITY
        u, source = STANDARD_GRAVITY_U, ("standard gravity, standing for anywhere on Earth "
                                         f"({EARTH_GRAVITY_RANGE[0]:.3f}-{EARTH_GRAVITY_RANGE[1]:.3f} m/s^2, "
                                         "rectangular): give the local g, or the latitude and height, for 1e-4 "
                                         "(the local gravity settings: --g, --latitude, --height)")
    if g_u is not None:
        u, source = float(g_u), source.split(";")[0] + f"; u(g) {float(g_u):g} m/s^2 given (--g-u)"
    if not 9.76 <= value <= 9.84:
        raise DataError(f"local gravity {value:.5f} m/s^2 lies outside 9.76-9.84, the range accelrig accepts "
                        "for gravity on Earth", "check --latitude and --height (metres above sea level)")
    return LocalGravity(value, u, source)


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
    "mg": "mg",
    "milli-g": "mg",
    "millig": "mg",
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
            "use one of: m/s2, g, mg (milli-g), counts",
        ) from None


def to_si(values: np.ndarray, unit: str, scale: float | None = None, g: float = STANDARD_GRAVITY) -> np.ndarray:
    """Convert accelerations in ``unit`` to m/s^2.

    ``scale`` (m/s^2 per count) is needed only for counts.  g and mg (milli-g) are units of standard
    gravity, as a datasheet's are; a local g is only the size of the reference, never a unit.
    """
    unit = normalise_unit(unit)
    values = np.asarray(values, dtype=float)
    if unit == "m/s^2":
        return values
    if unit == "g":
        return values * g
    if unit == "mg":
        return values * (g / 1000.0)
    if scale is None or not np.isfinite(scale) or scale <= 0:
        raise DataError(
            "data are in counts but the counts-to-m/s^2 scale is unknown",
            "give the sensor's range (--range-g G), or convert the file to m/s^2",
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
