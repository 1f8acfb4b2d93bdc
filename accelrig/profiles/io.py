"""Profiles in memory and on disk: build from a calibration result, save atomically, load safely.

Read only through ``accelrig.safe_yaml`` (plain data; a tag, an alias, deep
nesting or a huge number is refused with the line it is on); written with
``yaml.safe_dump``.  Every load and every save validates against schema v1
(accelrig/profiles/schema.py); a problem is one ProfileError naming the file
and the field.
"""

from __future__ import annotations

import copy
import math
import os
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
import yaml

from accelrig import __version__
from accelrig.errors import ProfileError
from accelrig.files import atomic_write
from accelrig.profiles.schema import SCHEMA_VERSION, validate
from accelrig.recording import Recording
from accelrig.result import CalibrationResult, Correction, to_plain
from accelrig.safe_yaml import load_yaml, load_yaml_file
from accelrig.spec import format_datetime, parse_datetime
from accelrig.units import STANDARD_GRAVITY, scale_for_range

HEADER = (
    "# accelrig device profile (schema v1, profiles/schema-v1.json).\n"
    "# calibrated = C @ (raw - b); raw = counts x nominal scale, m/s^2. Uncertainties are k = 1.\n"
)

# The device fields a profile keeps, and where they come from in a recording's metadata.
DEVICE_FIELDS = {
    "identity": "identity",
    "driver": "driver",
    "chip": "chip",
    "who_am_i": "who_am_i",
    "url": "device",
    "range_g": "range_g",
    "scale": "scale",
    "rate": "nominal_rate",
    "delivered_rate": "delivered_rate",
}


@dataclass
class Profile:
    """A validated device profile.  ``data`` is exactly the plain dict written as YAML."""

    data: dict
    path: Path | None = None

    @property
    def correction(self) -> Correction:
        c = self.data["calibration"]["correction"]
        return Correction(np.array(c["matrix"]), np.array(c["bias"]), np.array(c["covariance"]))

    @property
    def device(self) -> dict:
        return self.data["device"]

    @property
    def units(self) -> str:
        """Units of the raw samples the correction applies to (always m/s^2 in v1)."""
        return self.data["units"]

    @property
    def identity(self) -> str | None:
        return self.data["device"]["identity"]

    @property
    def created(self) -> datetime:
        return parse_datetime(self.data["provenance"]["created"])

    @property
    def procedure(self) -> str:
        return self.data["calibration"]["procedure"]

    @property
    def method(self) -> str:
        return self.data["calibration"]["method"]

    @property
    def noise(self) -> dict | None:
        return self.data["noise"]

    def copy(self) -> Profile:
        return Profile(copy.deepcopy(self.data), self.path)

    def validate(self) -> None:
        validate(self.data)


def utc_now() -> str:
    return format_datetime(datetime.now(UTC))


def profile_from_result(
    result: CalibrationResult,
    recording: Recording | None = None,
    device: dict | None = None,
    created: str | None = None,
) -> Profile:
    """The profile a calibration leaves behind.

    Device identity comes from ``device`` (keys as in the profile's ``device``
    section, or a DeviceInfo.to_dict()) and else from the recording's metadata;
    what is not known is null, never guessed.  The rig geometry is taken from
    ``result.settings['rig']`` (or ``['geometry']``) into ``provenance.rig``;
    the other settings go to ``calibration.settings``.
    """
    if result.correction is None:
        raise ProfileError(
            f"the {result.procedure} result has no correction to keep",
            "only a calibration that produced a correction can become a profile",
        )
    meta = recording.meta if recording is not None else {}
    dev = {key: to_plain(meta.get(src)) for key, src in DEVICE_FIELDS.items()}
    if device:
        given = dict(device)
        # accept DeviceInfo.to_dict() spellings too
        if "nominal_rate" in given and "rate" not in given:
            given["rate"] = given.get("nominal_rate")
        if "device" in given and "url" not in given:
            given["url"] = given.get("device")
        for key in DEVICE_FIELDS:
            if given.get(key) is not None:
                dev[key] = to_plain(given[key])
    for key in ("range_g", "scale", "rate", "delivered_rate"):
        if dev[key] is not None:
            dev[key] = float(dev[key])
    if dev["identity"] is not None:
        dev["identity"] = str(dev["identity"])
    if dev["who_am_i"] is not None:
        dev["who_am_i"] = int(dev["who_am_i"])
    if dev["scale"] is None and dev["range_g"] is not None:
        dev["scale"] = scale_for_range(dev["range_g"])

    settings = {k: _known(to_plain(v)) for k, v in result.settings.items()}
    rig = settings.pop("rig", None)
    if rig is None:
        rig = settings.pop("geometry", None)
    if rig is not None and not isinstance(rig, dict):
        rig = {"description": rig}
    g = float(settings.get("g", meta.get("g", STANDARD_GRAVITY)))

    quality = {k: _known(to_plain(v)) for k, v in result.quality.items()}
    quality.setdefault("residual_rms", None)
    names = [str(n) for n in result.parameter_names]
    pcov = None
    if result.covariance is not None and np.size(result.covariance):
        pcov = np.asarray(result.covariance, dtype=float).tolist()

    corr = result.correction
    warnings = [str(w) for w in result.warnings]
    removed = meta.get("hardware_bias_removed")
    if removed is not None:
        # The data came from a chip with flashed offsets; a profile describes the
        # sensor as it powers up, so the bias the chip removed is added back.
        corr = Correction(corr.matrix, corr.bias + np.asarray(removed, dtype=float), corr.covariance)
        warnings.append("recorded with flashed offsets removing " + ", ".join(f"{v:.4g}" for v in removed)
                        + " m/s^2 in hardware; the profile's bias is for the sensor at power-up")
    data = {
        "schema_version": SCHEMA_VERSION,
        "device": dev,
        "units": "m/s^2",
        "calibration": {
            "procedure": result.procedure,
            "method": result.method,
            "model": result.model,
            "g": g,
            "settings": settings,
            "correction": corr.to_dict(),
            "parameters": {k: v.to_dict() for k, v in result.parameters.items()},
            **({"parameter_meaning": result.parameter_meaning} if result.parameter_meaning else {}),
            "parameter_names": names,
            "parameter_covariance": pcov,
        },
        "quality": quality,
        "noise": None,
        "warnings": warnings,
        "provenance": {
            "created": created or utc_now(),
            "software_version": __version__,
            "recording_hash": recording.content_hash() if recording is not None else None,
            # the file it was read from (a header's own "source" is a description, not a path), else that
            "recording_source": to_plain(meta.get("file") or meta.get("source")),
            "recording_samples": len(recording) if recording is not None else None,
            "recording_start": _normal_datetime(meta.get("start_time")),
            "temperature_c": to_plain(meta.get("temperature_c")),
            "rig": rig,
        },
    }
    data = to_plain(data)
    try:
        validate(data)
    except ProfileError as exc:
        raise ProfileError(
            f"the {result.procedure} result does not make a valid profile: {exc}",
            "this is a bug in the procedure or in accelrig.profiles; please report it",
        ) from None
    return Profile(data)


def _known(value):
    """NaN or infinite figures in the open maps (settings, quality) mean 'not known': keep them as null."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, list):
        return [_known(v) for v in value]
    if isinstance(value, dict):
        return {k: _known(v) for k, v in value.items()}
    return value


def _normal_datetime(value) -> str | None:
    if value in (None, ""):
        return None
    try:
        return format_datetime(parse_datetime(str(value)))
    except ValueError:
        return None


def dump_yaml(data: dict) -> str:
    """The exact text a profile is saved as (stable: key order as built, one matrix row per line)."""
    # allow_unicode=False: PyYAML would emit some characters (U+0085 NEL) raw that read back as a
    # line break; escaped, every string round-trips exactly.
    return HEADER + yaml.safe_dump(data, sort_keys=False, default_flow_style=None, width=4096, allow_unicode=False)


def save_profile(profile: Profile, path: str | os.PathLike, overwrite: bool = True, inputs=(),
                 mode: int = 0o666) -> None:
    """Validate, then write atomically (temp file + rename): never half a profile on disk.

    ``overwrite``, ``inputs`` and ``mode`` as in files.atomic_write: without ``overwrite`` the file
    is created exclusively (files.OutputExists if the name is taken)."""
    path = Path(path)
    try:
        validate(profile.data)
    except ProfileError as exc:
        raise ProfileError(f"not saving {path}: {exc}") from None
    text = dump_yaml(profile.data)
    atomic_write(path, lambda fh: fh.write(text), text=True, overwrite=overwrite, inputs=inputs, mode=mode)
    profile.path = path


def parse_profile_text(text: str, source: str = "<profile>") -> dict:
    """YAML text -> validated v1 data.  Refuses aliases, deep nesting, huge numbers, duplicate keys,
    object tags (accelrig.safe_yaml), other versions, bad fields."""
    return _checked(load_yaml(text, source, ProfileError, "a profile"), source)


def _checked(data, source: str) -> dict:
    if not isinstance(data, dict):
        raise ProfileError(f"{source}: not a profile (" + ("the file is empty" if data is None else
                           f"expected a mapping at the top level, got {type(data).__name__}") + ")")
    _check_version(data, source)
    try:
        validate(data)
    except ProfileError as exc:
        raise ProfileError(f"{source}: {exc.message}", exc.hint) from None
    return data


def _check_version(data: dict, source: str) -> None:
    if "schema_version" not in data:
        raise ProfileError(f"{source}: schema_version: missing", "is this an accelrig profile?")
    version = data["schema_version"]
    if not isinstance(version, int) or isinstance(version, bool):
        raise ProfileError(f"{source}: schema_version: expected an integer, got {version!r}")
    if version > SCHEMA_VERSION:
        raise ProfileError(
            f"{source}: schema_version: {version} is newer than this accelrig reads (up to {SCHEMA_VERSION})",
            "upgrade accelrig to read it",
        )
    if version < SCHEMA_VERSION:
        # There is no older released version: refuse rather than guess at its meaning.
        raise ProfileError(
            f"{source}: schema_version: {version} is not a version accelrig ever wrote (this one reads {SCHEMA_VERSION})",
        )


def load_profile(path: str | os.PathLike) -> Profile:
    """Read and validate a profile; one ProfileError naming the file and the field on any problem."""
    path = Path(path)
    return Profile(_checked(load_yaml_file(path, ProfileError, "a YAML profile"), str(path)), path)
