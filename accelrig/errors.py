"""One hierarchy for every expected failure.

The CLI prints ``str(error)`` as one line and exits non-zero; a traceback is
shown only with ``--debug``.  Anything that is *not* an AccelrigError is a bug.
A message says what was wrong; ``hint`` says what the person should do.
"""

from __future__ import annotations


class AccelrigError(Exception):
    """Base of all expected failures."""

    exit_code = 2

    def __init__(self, message: str, hint: str | None = None):
        super().__init__(message)
        self.message = message
        self.hint = hint

    def __str__(self) -> str:
        if self.hint:
            return f"{self.message} ({self.hint})"
        return self.message


class DeviceError(AccelrigError):
    """Opening, reading or writing a device failed (unknown URL, disconnect, ...)."""

    exit_code = 3


class DeviceStalled(DeviceError):
    """A connected device sent no data for longer than its stall limit (``seconds``): the link is up, the
    device silent.  Drivers that watch for it raise this, so whoever reports it says "stalled", not
    "disconnected"."""

    def __init__(self, message: str, hint: str | None = None, seconds: float | None = None):
        super().__init__(message, hint)
        self.seconds = seconds


class MissingExtraError(DeviceError):
    """A driver or feature needs an optional dependency that is not installed."""

    def __init__(self, feature: str, module: str, extra: str):
        super().__init__(
            f"{feature} needs the Python package '{module}', which is not installed",
            f"install it with: pip install 'accelrig[{extra}]'",
        )
        self.module = module
        self.extra = extra


def require_extra(module: str, feature: str, package: str, extra: str):
    """Import an optional dependency, or raise MissingExtraError naming the pip extra.

    Drivers call this inside open()/discover(), never at module import, so every
    driver module imports (and ``accelrig devices`` lists it) without its extra.
    """
    import importlib

    try:
        return importlib.import_module(module)
    except ImportError:
        raise MissingExtraError(feature, package, extra) from None


class DataError(AccelrigError):
    """Input data are unusable: wrong file, wrong units, malformed rows, moved poses."""

    exit_code = 4


class CalibrationError(AccelrigError):
    """A calibration could not be computed from otherwise readable data."""

    exit_code = 5


class ProfileError(AccelrigError):
    """A device profile is malformed, of another schema version, or for another device."""

    exit_code = 6


class StorageError(AccelrigError):
    """Recorded data could not be written: an unwritable directory, an I/O error, a full disk."""

    exit_code = 7


class StorageFull(StorageError):
    """The disk (or quota) is full.  The writer that raised it stays consistent: the block is
    wholly in the open segment or not at all, so the caller counts it as a "disk full" gap and
    writes again once space returns."""


# Characters a terminal acts on rather than shows: C0 and C1 controls (ESC starts a sequence that can
# move the cursor, retitle the window or rewrite the screen), DEL, and the bidirectional overrides that
# reorder what is shown.
_UNSAFE = {*range(0x00, 0x20), 0x7F, *range(0x80, 0xA0), 0x061C, 0x200E, 0x200F, *range(0x202A, 0x202F),
           *range(0x2066, 0x206A)}


def printable(text) -> str:
    """``text`` safe to write to a terminal: every control character shown escaped (\\x1b, \\n, \\u202e).

    Strings from files (a profile's identity, a recording's metadata, a file name) pass through this
    before they reach a terminal, so a file can never rewrite the operator's screen.
    """
    text = str(text)
    if not any(ord(c) in _UNSAFE for c in text):
        return text
    out = []
    for c in text:
        code = ord(c)
        if code in _UNSAFE:
            out.append(f"\\x{code:02x}" if code < 0x100 else f"\\u{code:04x}")
        else:
            out.append(c)
    return "".join(out)
