"""What a certificate is made from: a profile, a saved result, or a rotary campaign, as one plain form.

Every source becomes a ``Source``: the result as the plain dict of
``CalibrationResult.to_json_dict`` (arrays included when the source carries
them), the device's identity and the provenance.  A profile keeps no per-step
tables or arrays, so its certificate says which figures it cannot show rather
than inventing them.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path

import yaml

from accelrig import __version__
from accelrig.errors import DataError
from accelrig.files import read_text_file
from accelrig.recording import Recording
from accelrig.result import CalibrationResult, to_plain

# The papers each procedure follows (full text in ../shared/papers/, README there).
METHOD_REFERENCES = {
    "static": "Six-orientation static calibration by variable projection: Sensors & Transducers 252(5), 2021, "
              "pp. 1-11 (paper 000)",
    "wheel": "Tilted, freely rotating wheel: F. Pedersini, IEEE Sensors J. 22(10), 2022 (paper 002)",
    "slider-crank": "Dynamic verification on a slider-crank test stand: Sensors & Transducers 252(5), 2021, "
                    "pp. 1-11 (paper 000)",
    "rotary": "Encoder-driven oscillating rotary bench with a GUM budget: Chiominto et al., Sensors 25(7) 2120, "
              "2025 (paper 001)",
}

# What a result's method code means, for a reader who does not know the program's names
ESTIMATOR_WORDS = {
    ("static", "map"): "maximum a posteriori fit: each pose's tilt from its face a nuisance with the flatness prior",
    ("static", "lm"): "Levenberg-Marquardt least squares of |C (raw − b)| = g over the orientations",
    ("static", "vp"): "variable projection with Levenberg-Marquardt (exact faces)",
    ("static", "paper"): "the paper's Nelder-Mead search over the angles (exact faces)",
    ("wheel", "joint"): "joint maximum-likelihood fit of the whole coast",
    ("wheel", "paper"): "the paper's four steps",
}

RESULT_KEYS = ("procedure", "method", "model", "parameters")


@dataclass
class Source:
    """A certificate's input: ``result`` is a plain result dict, ``kind`` says where it came from."""

    kind: str                       # "profile", "result" or "campaign"
    result: dict
    device: dict = field(default_factory=dict)
    provenance: dict = field(default_factory=dict)
    noise: dict | None = None
    path: str | None = None
    recording_path: str | None = None   # the calibrated recording, when given (report --recording)

    @property
    def procedure(self) -> str:
        return self.result["procedure"]

    @property
    def arrays(self) -> dict:
        return self.result.get("arrays") or {}

    @property
    def details(self) -> dict:
        return self.result.get("details") or {}

    @property
    def is_campaign(self) -> bool:
        return self.result.get("method") == "campaign"


def from_result(result: CalibrationResult, recording: Recording | None = None, device: dict | None = None,
                noise: dict | None = None) -> Source:
    """A source from a result in memory (arrays included: every figure can be drawn).

    The device's facts and the provenance (hash, file, start) come from ``recording``'s metadata as a
    profile's would; ``device`` overrides them."""
    from accelrig.profiles.io import DEVICE_FIELDS

    plain = result.to_json_dict(include_arrays=True)
    plain["parameter_names"] = list(result.parameter_names)
    kind = "campaign" if result.method == "campaign" else "result"
    meta = recording.meta if recording is not None else {}
    dev = {key: to_plain(meta.get(name)) for key, name in DEVICE_FIELDS.items()}
    dev.update({k: v for k, v in (device or {}).items() if v is not None})
    provenance = {"software_version": __version__}
    if recording is not None:
        provenance.update({"recording_hash": recording.content_hash(),
                           "recording_source": meta.get("file") or meta.get("source"),
                           "recording_samples": len(recording), "recording_start": meta.get("start_time"),
                           "temperature_c": meta.get("temperature_c")})
    return Source(kind, plain, dev, to_plain(provenance), noise)


def _parse(path: Path) -> object:
    text = read_text_file(path, what="a profile, saved result or campaign")
    try:
        if path.suffix.lower() == ".json":
            return json.loads(text)
        return yaml.safe_load(text)
    except (json.JSONDecodeError, yaml.YAMLError) as exc:
        raise DataError(f"{path}: not valid {'JSON' if path.suffix.lower() == '.json' else 'YAML'} ({exc})",
                        "give a profile (.yaml), a result saved with --json, or a rotary campaign") from None


def load_source(path: str | os.PathLike) -> Source:
    """Read SOURCE: a device profile, a result saved from ``--json`` (JSON or YAML), a campaign report
    written by ``calibrate rotary --campaign -o X.yaml``, or a campaign file (its tests are analysed)."""
    path = Path(path)
    if not path.exists():
        raise DataError(f"{path}: no such file", "give a profile, a saved result (--json) or a rotary campaign")
    data = _parse(path)
    if not isinstance(data, dict):
        raise DataError(f"{path}: " + ("the file is empty" if data is None else
                                       f"expected a mapping at the top level, got {type(data).__name__}"),
                        "give a profile, a saved result (--json) or a rotary campaign")
    if "schema_version" in data and "calibration" in data:
        from accelrig.profiles import load_profile

        return _from_profile(load_profile(path).data, str(path))
    if all(k in data for k in RESULT_KEYS):
        if not isinstance(data["parameters"], dict):
            raise DataError(f"{path}: 'parameters' must be a mapping of name to estimate")
        kind = "campaign" if data.get("method") == "campaign" else "result"
        return Source(kind, data, dict(data.get("device") or {}), dict(data.get("provenance") or {}),
                      data.get("noise"), str(path))
    if "tests" in data:
        from accelrig.procedures.rotary.campaign import run_campaign

        source = from_result(run_campaign(path))
        source.path = str(path)
        return source
    raise DataError(f"{path}: neither a profile (schema_version, calibration), a saved result (procedure, method, "
                    "model, parameters) nor a rotary campaign (tests)",
                    "save a result with --json, or give the profile the calibration wrote")


def _from_profile(data: dict, path: str) -> Source:
    cal = data["calibration"]
    result = {
        "procedure": cal["procedure"],
        "method": cal["method"],
        "model": cal["model"],
        "correction": cal["correction"],
        "parameters": cal["parameters"],
        "parameter_meaning": cal.get("parameter_meaning", ""),
        "parameter_names": cal["parameter_names"],
        "quality": data["quality"],
        "settings": {**cal["settings"], "g": cal["g"]},
        "warnings": data["warnings"],
    }
    return Source("profile", to_plain(result), dict(data["device"]), dict(data["provenance"]), data["noise"], path)


def load_noise(path: str | os.PathLike, stored: dict | None) -> dict:
    """The output of ``accelrig noise REC --json`` (figures and Allan curves), checked against the noise
    figures the source already holds: a curve of another recording would contradict the certified figures."""
    path = Path(path)
    if not path.exists():
        raise DataError(f"{path}: no such file", "write it with: accelrig noise REC --json > NOISE.json")
    data = _parse(path)
    if not isinstance(data, dict) or "axes" not in data or "tau" not in (data.get("arrays") or {}):
        raise DataError(f"{path}: not the JSON of 'accelrig noise --json' (axes and arrays.tau)",
                        "write it with: accelrig noise REC --json > NOISE.json")
    if stored and stored.get("recording_hash") and data.get("recording_hash") != stored["recording_hash"]:
        raise DataError(f"{path}: its recording ({data.get('recording_hash')}) is not the one of the noise figures "
                        f"in the source ({stored['recording_hash']})", "give the curves of the same still recording")
    return data
