"""Figures for a profile: re-run its calibration on the recording it names, when that file is still there.

A profile keeps the numbers, not the per-pose tables or per-sample arrays.  When
``provenance.recording_source`` names a file (or ``Source.recording_path``, the
command's --recording, gives one) whose hash is the profile's
``recording_hash``, the calibration is run again with the profile's settings;
its arrays are used for the figures only if it reproduces the certified
correction.  Otherwise the certificate says why the figures are missing.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from accelrig.errors import AccelrigError
from accelrig.report.source import Source

RECOMPUTABLE = ("static", "wheel")
# The re-run must give the certified correction back to rounding (same code, same data, same settings).
REPRODUCE_RTOL = 1e-6


def _recording_path(src: Source) -> Path | None:
    """The file the profile names: beside the profile or from here, the one whose hash is the profile's
    (a relative name can find another file of that name from another folder); else the first found (its
    hash is then said to differ).  A file given with --recording is the one."""
    if src.recording_path:
        return Path(src.recording_path)
    name = src.provenance.get("recording_source")
    if not name:
        return None
    found = [c for c in dict.fromkeys((Path(src.path or ".").parent / name, Path(name)))
             if c.is_file() or c.is_dir()]
    if len(found) > 1:
        from accelrig.recording import load_recording

        for candidate in found:
            try:
                if load_recording(candidate).content_hash() == src.provenance.get("recording_hash"):
                    return candidate
            except AccelrigError:
                continue
    return found[0] if found else None


def _rerun(src: Source, rec):
    settings = src.result["settings"]
    if src.procedure == "static":
        from accelrig.procedures.static.procedure import calibrate_static
        from accelrig.procedures.static.settings import SETTINGS

        values = {s.name: settings[s.name] for s in SETTINGS if settings.get(s.name) is not None}
        values["model"] = settings.get("model_requested", values.get("model", "auto"))
        return calibrate_static(rec, skip_poses=settings.get("skip_poses", ()), **values)
    from accelrig.procedures.wheel.procedure import calibrate_wheel

    rig = src.provenance.get("rig") or {}
    return calibrate_wheel(rec, radius=rig.get("radius") if rig.get("radius_given") else None,
                           tilt_deg=rig.get("tilt_deg") if rig.get("tilt_given") else None,
                           method=src.result["method"], g=settings.get("g", 9.80665),
                           cross_axis_sd=settings.get("cross_axis_sd", 0.0115))


def needs_recording(src: Source) -> bool:
    """Whether this source's figures come from re-running its calibration on its recording."""
    return src.kind == "profile" and not src.arrays and src.procedure in RECOMPUTABLE


def missing_recording(src: Source) -> str:
    """Why the calibrated recording is not at hand, in the certificate's words."""
    name = src.provenance.get("recording_source")
    named = (f"the profile names it {name!r}, which is no file beside the profile or in the folder the "
             "certificate was written from" if name else "the profile names no file")
    return (f"the calibrated recording ({src.provenance.get('recording_hash') or 'no hash recorded'}) was not at "
            f"hand ({named}), so the figures drawn from it were not recomputed")


def recording_hint(src: Source) -> str | None:
    """What the operator can do when the figures need a recording that is not found (for the command's
    stderr, never the certificate), else None."""
    if not needs_recording(src) or _recording_path(src) is not None:
        return None
    return (f"{missing_recording(src)}; give the calibrated recording with --recording FILE "
            "(its sha256 is checked against the profile's)")


def add_arrays_from_recording(src: Source) -> str | None:
    """Fill ``src.result['arrays']`` (and the per-pose table) by re-running the calibration; return why not,
    or None when done or not needed."""
    if not needs_recording(src):
        return None
    path = _recording_path(src)
    if path is None:
        return missing_recording(src)
    from accelrig.recording import load_recording

    try:
        rec = load_recording(path)
    except AccelrigError as exc:
        return f"the recording {path} could not be read again ({exc})"
    if rec.content_hash() != src.provenance.get("recording_hash"):
        return f"the recording {path} is not the one calibrated (its hash differs from the profile's)"
    try:
        again = _rerun(src, rec)
    except AccelrigError as exc:
        return f"re-running the calibration on {path} failed ({exc})"
    corr = src.result["correction"]
    if not (np.allclose(again.correction.matrix, corr["matrix"], rtol=REPRODUCE_RTOL, atol=1e-12)
            and np.allclose(again.correction.bias, corr["bias"], rtol=REPRODUCE_RTOL, atol=1e-9)):
        return (f"re-running the calibration on {path} did not reproduce the certified correction (another "
                "accelrig version or other settings?), so its figures are not shown")
    plain = again.to_json_dict(include_arrays=True)
    src.result["arrays"] = plain.get("arrays", {})
    src.result["details"] = plain.get("details", {})
    return None
