"""Settings declared once (ground floor), rendered as CLI flags, TUI form fields and checked one way.

A procedure (or a driver) lists its settings as :class:`Setting` objects: name,
unit, kind, bounds, default, help.  ``add_arguments`` turns them into argparse
flags, the TUI turns them into form fields, and both hand the person's text to
``Setting.parse``, so a value means the same and is refused with the same words
wherever it is typed.  (The shape follows harlequin's options, which render
themselves both as click options and as Textual widgets.)
"""

from __future__ import annotations

import argparse
import math
from dataclasses import dataclass

from accelrig.errors import DataError


class _Required:
    def __repr__(self) -> str:
        return "REQUIRED"


REQUIRED = _Required()   # default of a setting the person must give

KINDS = ("float", "int", "text", "choice", "floats", "path", "flag")


@dataclass(frozen=True)
class Setting:
    """One value a person sets.

    name     python identifier, also the flag (``crank_radius`` -> ``--crank-radius``)
    help     one line for operators: what it is, in their words
    unit     SI unit of the value ('' for none); shown beside the field and in --help
    kind     float | int | text | choice | floats (comma-separated numbers) | path | flag (on/off)
    default  the value when left blank; None: "not given" is a valid answer; REQUIRED: must be given
    low, high  inclusive bounds for numbers (each item of ``floats``); ``low_open`` makes low exclusive
    choices  the allowed words of a ``choice``
    label    short form label (default: the help text)
    example  placeholder text for an empty field
    hint     what to do when the value is refused (e.g. "give it in metres")
    remembered  offered again in the next session's form (False for an override such as ``force``, which
             must be a decision about this run, not inherited by the next operator)
    """

    name: str
    help: str
    unit: str = ""
    kind: str = "float"
    default: object = None
    low: float | None = None
    high: float | None = None
    low_open: bool = False
    choices: tuple[str, ...] = ()
    label: str = ""
    example: str = ""
    hint: str | None = None
    remembered: bool = True

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ValueError(f"setting {self.name}: kind {self.kind!r} is not one of {KINDS}")
        if self.kind == "choice" and not self.choices:
            raise ValueError(f"setting {self.name}: a choice needs choices")

    @property
    def flag(self) -> str:
        return "--" + self.name.replace("_", "-")

    @property
    def required(self) -> bool:
        return self.default is REQUIRED

    @property
    def title(self) -> str:
        return self.label or self.help

    def default_text(self) -> str:
        """The default as a person would type it ('' for none)."""
        if self.default is None or self.default is REQUIRED:
            return ""
        if self.kind == "floats":
            return ",".join(f"{v:g}" for v in self.default)
        if self.kind == "flag":
            return "yes" if self.default else "no"
        if isinstance(self.default, float):
            return f"{self.default:g}"
        return str(self.default)

    def describe(self, text: str | None = None) -> str:
        """``text`` (default: the help) with unit, choices and default, for --help and form labels."""
        parts = [text or self.help]
        extra = []
        if self.unit:
            extra.append(self.unit)
        if self.kind == "choice":
            extra.append("|".join(self.choices))
        default = self.default_text()
        if default:
            extra.append(f"default {default}")
        elif self.required:
            extra.append("required")
        if extra:
            parts.append("(" + "; ".join(extra) + ")")
        return " ".join(parts)

    # ------------------------------------------------------------- parsing
    def parse(self, value, where: str | None = None):
        """The typed value of ``value`` (text from a flag, a form or a URL, or an already typed value).

        Blank or None gives the default (None for an optional setting); anything
        refused raises DataError naming ``where`` (default: the flag) and the unit.
        """
        where = where or self.flag
        if value is None or (isinstance(value, str) and not value.strip()):
            if self.required:
                raise DataError(f"{where} is needed: {self.help}", self.hint)
            return self.default
        if self.kind == "flag":
            return self._parse_flag(value, where)
        if self.kind in ("text", "path"):
            return str(value).strip()
        if self.kind == "choice":
            text = str(value).strip()
            if text not in self.choices:
                raise DataError(f"{where} {text!r} is not one of {', '.join(self.choices)}", self.hint)
            return text
        if self.kind == "floats":
            items = value if isinstance(value, (list, tuple)) else str(value).replace(" ", ",").split(",")
            numbers = [self._number(item, where) for item in items if str(item).strip()]
            if not numbers:
                raise DataError(f"{where} needs at least one number", self.hint)
            return numbers
        return self._number(value, where)

    def _number(self, value, where: str):
        text = str(value).strip()
        try:
            number = float(text) if not isinstance(value, (int, float)) else float(value)
        except ValueError:
            raise DataError(f"{where} {text!r} is not a number", self.hint) from None
        if not math.isfinite(number):
            raise DataError(f"{where} {text} is not a finite number", self.hint)
        if self.kind == "int":
            if number != int(number):
                raise DataError(f"{where} {text} is not a whole number", self.hint)
            number = int(number)
        unit = f" {self.unit}" if self.unit else ""
        too_low = self.low is not None and (number <= self.low if self.low_open else number < self.low)
        too_high = self.high is not None and number > self.high
        if too_high and self.unit == "m" and number / 1000 <= self.high and (self.low is None or number / 1000 > self.low):
            # in range once read as millimetres: say so, the likeliest slip with a caliper in hand
            raise DataError(f"{where} {number:g} m is not a plausible {self.help} (at most {self.high:g} m): "
                            "did you give millimetres?", self.hint)
        if too_low or too_high:
            low = "" if self.low is None else f"{'>' if self.low_open else '>='} {self.low:g}"
            high = "" if self.high is None else f"<= {self.high:g}"
            bounds = " and ".join(b for b in (low, high) if b)
            raise DataError(f"{where} {number:g}{unit} is out of range: it must be {bounds}{unit}", self.hint)
        return number

    def _parse_flag(self, value, where: str) -> bool:
        if isinstance(value, bool):
            return value
        text = str(value).strip().lower()
        if text in ("1", "yes", "y", "true", "on"):
            return True
        if text in ("0", "no", "n", "false", "off"):
            return False
        raise DataError(f"{where} {value!r} is not yes or no", self.hint)


# ------------------------------------------------------------------ rendering to argparse

def add_arguments(parser: argparse.ArgumentParser, settings: tuple[Setting, ...] | list[Setting]) -> None:
    """One flag per setting.  Values stay text until ``values_from_args`` so errors read the same everywhere."""
    for s in settings:
        if s.kind == "flag":
            parser.add_argument(s.flag, dest=s.name, action="store_true", default=None,
                                help=s.describe().replace("%", "%%"))
            continue
        # a choice's words are listed in its help (describe): the usage line names it, so it fits 80 columns
        metavar = {"float": "X", "int": "N", "floats": "X,Y,..", "path": "PATH", "text": "TEXT",
                   "choice": s.name.upper()}.get(s.kind)
        parser.add_argument(s.flag, dest=s.name, default=None, metavar=metavar,
                            choices=s.choices or None, help=s.describe().replace("%", "%%"))


def values_from_args(settings, args: argparse.Namespace) -> dict:
    """Parsed values of every setting from an argparse namespace (flags named in errors)."""
    return {s.name: s.parse(getattr(args, s.name, None)) for s in settings}


def values_from_texts(settings, texts: dict[str, str]) -> dict:
    """Parsed values of every setting from form text (labels named in errors)."""
    return {s.name: s.parse(texts.get(s.name), where=s.title) for s in settings}


# ------------------------------------------------------------------ settings several procedures declare

# The default is standard gravity, accelrig.units.STANDARD_GRAVITY, written out because units loads numpy
# and a command's --help must not (tests/test_settings.py checks the two agree).
# Earth's gravity runs from 9.780 (equator) to 9.832 m/s^2 (poles), a few mm/s^2 less on a mountain:
# outside 9.76 .. 9.84 the number is a slip (another unit, a typo), not a place.
GRAVITY = Setting("g", "local gravity (default standard gravity, which stands for anywhere on Earth: u 0.015; "
                  "or give --latitude)", unit="m/s^2", default=9.80665, low=9.76, high=9.84,
                  label="local gravity", hint="Earth's gravity lies within 9.76-9.84 m/s^2; give it in m/s^2, e.g. 9.81")
# Local gravity from where the rig stands: accelrig.units.local_gravity turns these into g and u(g).
LATITUDE = Setting("latitude", "latitude of the rig: g from the WGS-84 normal gravity formula (u 0.001)",
                   unit="deg", low=-90.0, high=90.0, label="latitude", example="48.1")
HEIGHT = Setting("height", "height of the rig above sea level, with --latitude (default 0)", unit="m",
                 low=-500.0, high=6000.0, label="height", example="520")
GRAVITY_U = Setting("g_u", "standard uncertainty of g, replacing the default one (e.g. a surveyed g)",
                    unit="m/s^2", low=0.0, high=0.05, label="u(g)")
GRAVITY_SETTINGS = (GRAVITY, LATITUDE, HEIGHT, GRAVITY_U)
