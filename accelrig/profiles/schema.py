"""Profile schema v1: ONE description drives both the validator and the published JSON Schema.

The validator is plain Python (no jsonschema dependency in the core).  Each
node of the description knows how to check a value (raising ProfileError with
the dotted path of the field and what was wrong) and how to describe itself as
JSON Schema; ``profiles/schema-v1.json`` is generated from it by
``python profiles/make_examples.py`` and a test checks the committed file
equals the generated one.

Checks that JSON Schema cannot express (a covariance that is not symmetric,
uncertainties that disagree with the covariance, an estimate whose value and
uncertainty differ in shape) run after the structural pass, in
``cross_checks``.
"""

from __future__ import annotations

import json
import math
import re
from dataclasses import dataclass, field
from datetime import datetime, timezone

from accelrig.errors import ProfileError

SCHEMA_VERSION = 1
SCHEMA_ID = "https://accelrig.invalid/profiles/schema-v1.json"


# ----------------------------------------------------------------- describing values


def describe(value) -> str:
    """How a wrong value looks, for messages: '3x2', 'a string', 'null'..."""
    if value is None:
        return "null"
    if isinstance(value, bool):
        return f"a boolean ({value})"
    if isinstance(value, (int, float)):
        return f"the number {value!r}"
    if isinstance(value, str):
        shown = value if len(value) <= 40 else value[:37] + "..."
        return f"the string {shown!r}"
    if isinstance(value, dict):
        return "a mapping"
    if isinstance(value, list):
        shape = _list_shape(value)
        return shape if shape else f"a list of {len(value)}"
    return f"a {type(value).__name__}"


def _list_shape(value: list) -> str | None:
    """'3', '3x2' for rectangular lists of numbers, else None."""
    if all(_is_number(v) for v in value):
        return f"a list of {len(value)} numbers"
    if all(isinstance(v, list) for v in value) and value:
        widths = {len(v) for v in value}
        if len(widths) == 1 and all(_is_number(x) for v in value for x in v):
            return f"{len(value)}x{widths.pop()}"
        return f"{len(value)} rows of lengths {'/'.join(str(len(v)) for v in value)}"
    return None


def _is_number(value) -> bool:
    # bool is an int in Python but never a number in a profile.
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _join(path: str, key) -> str:
    if isinstance(key, int):
        return f"{path}[{key}]"
    return f"{path}.{key}" if path else str(key)


def _fail(path: str, problem: str) -> None:
    raise ProfileError(f"{path or '(top level)'}: {problem}")


# ----------------------------------------------------------------- value kinds


class Spec:
    """A node of the schema description."""

    description: str = ""

    def check(self, value, path: str) -> None:  # pragma: no cover - abstract
        raise NotImplementedError

    def json_schema(self) -> dict:  # pragma: no cover - abstract
        raise NotImplementedError

    def _with_description(self, schema: dict) -> dict:
        if self.description:
            schema["description"] = self.description
        return schema


@dataclass
class Number(Spec):
    description: str = ""
    minimum: float | None = None
    exclusive_minimum: float | None = None
    maximum: float | None = None

    def check(self, value, path: str) -> None:
        if not _is_number(value):
            _fail(path, f"expected a number, got {describe(value)}")
        if not math.isfinite(value):
            _fail(path, f"expected a finite number, got {value}")
        if self.minimum is not None and value < self.minimum:
            _fail(path, f"expected a number >= {self.minimum:g}, got {value!r}")
        if self.exclusive_minimum is not None and value <= self.exclusive_minimum:
            _fail(path, f"expected a number > {self.exclusive_minimum:g}, got {value!r}")
        if self.maximum is not None and value > self.maximum:
            _fail(path, f"expected a number <= {self.maximum:g}, got {value!r}")

    def json_schema(self) -> dict:
        s: dict = {"type": "number"}
        if self.minimum is not None:
            s["minimum"] = self.minimum
        if self.exclusive_minimum is not None:
            s["exclusiveMinimum"] = self.exclusive_minimum
        if self.maximum is not None:
            s["maximum"] = self.maximum
        return self._with_description(s)


@dataclass
class Integer(Spec):
    description: str = ""
    minimum: int | None = None
    maximum: int | None = None

    def check(self, value, path: str) -> None:
        if not isinstance(value, int) or isinstance(value, bool):
            _fail(path, f"expected an integer, got {describe(value)}")
        if self.minimum is not None and value < self.minimum:
            _fail(path, f"expected an integer >= {self.minimum}, got {value}")
        if self.maximum is not None and value > self.maximum:
            _fail(path, f"expected an integer <= {self.maximum}, got {value}")

    def json_schema(self) -> dict:
        s: dict = {"type": "integer"}
        if self.minimum is not None:
            s["minimum"] = self.minimum
        if self.maximum is not None:
            s["maximum"] = self.maximum
        return self._with_description(s)


@dataclass
class String(Spec):
    description: str = ""
    enum: tuple[str, ...] | None = None
    pattern: str | None = None
    min_length: int = 0

    def check(self, value, path: str) -> None:
        if not isinstance(value, str):
            _fail(path, f"expected a string, got {describe(value)}")
        if self.enum is not None and value not in self.enum:
            _fail(path, f"expected one of {', '.join(repr(e) for e in self.enum)}, got {value!r}")
        if len(value) < self.min_length:
            _fail(path, "expected a non-empty string")
        if self.pattern is not None and not re.fullmatch(self.pattern, value):
            _fail(path, f"{value!r} does not match the pattern {self.pattern}")

    def json_schema(self) -> dict:
        s: dict = {"type": "string"}
        if self.enum is not None:
            s["enum"] = list(self.enum)
        if self.min_length:
            s["minLength"] = self.min_length
        if self.pattern is not None:
            s["pattern"] = f"^(?:{self.pattern})$"
        return self._with_description(s)


@dataclass
class DateTime(Spec):
    """A UTC date-time string, 2026-11-22T03:25:00Z (kept a string so YAML never makes it a datetime)."""

    description: str = ""

    PATTERN = r"\d{4}-\d{2}-\d{2}T\d{2}:\d{2}:\d{2}(\.\d+)?Z"

    def check(self, value, path: str) -> None:
        if not isinstance(value, str) or not re.fullmatch(self.PATTERN, value):
            _fail(path, f"expected a UTC date-time like 2026-11-22T03:25:00Z, got {describe(value)}")
        try:
            parse_datetime(value)
        except ValueError as exc:
            _fail(path, f"not a valid date-time ({exc})")

    def json_schema(self) -> dict:
        return self._with_description({"type": "string", "pattern": f"^{self.PATTERN}$"})


def parse_datetime(text: str) -> datetime:
    """A profile date-time (or a plain date, or any ISO form) as an aware UTC datetime."""
    value = datetime.fromisoformat(text.replace("Z", "+00:00"))
    if value.tzinfo is None:
        value = value.replace(tzinfo=timezone.utc)
    return value.astimezone(timezone.utc)


def format_datetime(value: datetime) -> str:
    return value.astimezone(timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")


@dataclass
class Const(Spec):
    value: object = None
    description: str = ""

    def check(self, value, path: str) -> None:
        if value != self.value or isinstance(value, bool) != isinstance(self.value, bool):
            _fail(path, f"expected {self.value!r}, got {describe(value)}")

    def json_schema(self) -> dict:
        return self._with_description({"const": self.value})


@dataclass
class Array(Spec):
    """Numbers of a fixed shape: (n,) vector or (rows, cols) matrix; None = any length."""

    shape: tuple[int | None, ...] = (None,)
    description: str = ""
    minimum: float | None = None

    def _expected(self) -> str:
        if len(self.shape) == 1:
            n = self.shape[0]
            return f"expected a list of {n} numbers" if n is not None else "expected a list of numbers"
        if self.shape[0] is None:
            return "expected a square matrix of numbers"
        return f"expected {self.shape[0]}x{self.shape[1]} numbers"

    def check(self, value, path: str) -> None:
        expected = self._expected()
        if not isinstance(value, list):
            _fail(path, f"{expected}, got {describe(value)}")
        rows = self.shape[0]
        if rows is not None and len(value) != rows:
            _fail(path, f"{expected}, got {describe(value)}")
        if len(self.shape) == 1:
            for i, v in enumerate(value):
                self._check_number(v, _join(path, i))
            return
        cols = self.shape[1] if self.shape[1] is not None else len(value)  # None: square
        if not all(isinstance(row, list) and len(row) == cols for row in value):
            _fail(path, f"{expected}, got {describe(value)}")
        for i, row in enumerate(value):
            for j, v in enumerate(row):
                self._check_number(v, f"{path}[{i}][{j}]")

    def _check_number(self, v, path: str) -> None:
        if not _is_number(v):
            _fail(path, f"expected a number, got {describe(v)}")
        if not math.isfinite(v):
            _fail(path, f"expected a finite number, got {v}")
        if self.minimum is not None and v < self.minimum:
            _fail(path, f"expected a number >= {self.minimum:g}, got {v!r}")

    def json_schema(self) -> dict:
        item: dict = {"type": "number"}
        if self.minimum is not None:
            item["minimum"] = self.minimum
        for size in reversed(self.shape):
            node: dict = {"type": "array", "items": item}
            if size is not None:
                node["minItems"] = size
                node["maxItems"] = size
            item = node
        return self._with_description(item)


@dataclass
class ListOf(Spec):
    item: Spec = None
    description: str = ""

    def check(self, value, path: str) -> None:
        if not isinstance(value, list):
            _fail(path, f"expected a list, got {describe(value)}")
        for i, v in enumerate(value):
            self.item.check(v, _join(path, i))

    def json_schema(self) -> dict:
        return self._with_description({"type": "array", "items": self.item.json_schema()})


@dataclass
class Nullable(Spec):
    inner: Spec = None

    @property
    def description(self) -> str:  # type: ignore[override]
        return self.inner.description

    def check(self, value, path: str) -> None:
        if value is not None:
            self.inner.check(value, path)

    def json_schema(self) -> dict:
        inner = self.inner.json_schema()
        description = inner.pop("description", None)
        s: dict = {"anyOf": [inner, {"type": "null"}]}
        if description:
            s["description"] = description
        return s


@dataclass
class OneOf(Spec):
    """The first option whose check passes; the message names all options."""

    options: tuple[Spec, ...] = ()
    description: str = ""
    expected: str = ""

    def check(self, value, path: str) -> None:
        for option in self.options:
            try:
                option.check(value, path)
                return
            except ProfileError:
                continue
        _fail(path, f"expected {self.expected}, got {describe(value)}")

    def json_schema(self) -> dict:
        return self._with_description({"anyOf": [o.json_schema() for o in self.options]})


@dataclass
class Plain(Spec):
    """Free-form plain data (settings, extra quality figures): mappings with string
    keys, lists, strings, finite numbers, booleans, null.  Never dates, bytes or sets."""

    description: str = ""
    mapping: bool = False   # the value itself must be a mapping

    def check(self, value, path: str) -> None:
        if self.mapping and not isinstance(value, dict):
            _fail(path, f"expected a mapping, got {describe(value)}")
        self._check_plain(value, path)

    def _check_plain(self, value, path: str) -> None:
        if value is None or isinstance(value, (bool, str)):
            return
        if _is_number(value):
            if not math.isfinite(value):
                _fail(path, f"expected a finite number, got {value}")
            return
        if isinstance(value, list):
            for i, v in enumerate(value):
                self._check_plain(v, _join(path, i))
            return
        if isinstance(value, dict):
            for k, v in value.items():
                if not isinstance(k, str):
                    _fail(path, f"keys must be strings, got {describe(k)}")
                self._check_plain(v, _join(path, k))
            return
        _fail(path, f"expected plain data (number, string, list, mapping), got {describe(value)}")

    def json_schema(self) -> dict:
        return self._with_description({"type": "object"} if self.mapping else {})


@dataclass
class Field:
    spec: Spec
    required: bool = True


@dataclass
class Object(Spec):
    """A mapping with known keys.  Unknown keys are refused unless ``additional``
    gives a spec for them (open maps such as method settings)."""

    fields: dict[str, Field] = field(default_factory=dict)
    description: str = ""
    additional: Spec | None = None
    key_pattern: str | None = None

    def check(self, value, path: str) -> None:
        if not isinstance(value, dict):
            _fail(path, f"expected a mapping, got {describe(value)}")
        for key in value:
            if not isinstance(key, str):
                _fail(path, f"keys must be strings, got {describe(key)}")
        for name, f in self.fields.items():
            if name not in value and f.required:
                _fail(_join(path, name), "missing (required field)")
        for key, v in value.items():
            if key in self.fields:
                self.fields[key].spec.check(v, _join(path, key))
            elif self.additional is None:
                known = ", ".join(self.fields)
                _fail(_join(path, key), f"unknown key (known here: {known})")
            else:
                if self.key_pattern is not None and not re.fullmatch(self.key_pattern, key):
                    _fail(_join(path, key), f"key does not match the pattern {self.key_pattern}")
                self.additional.check(v, _join(path, key))

    def json_schema(self) -> dict:
        s: dict = {"type": "object"}
        if self.fields:
            s["properties"] = {k: f.spec.json_schema() for k, f in self.fields.items()}
            required = [k for k, f in self.fields.items() if f.required]
            if required:
                s["required"] = required
        if self.additional is None:
            s["additionalProperties"] = False
        else:
            s["additionalProperties"] = self.additional.json_schema()
            if self.key_pattern is not None:
                s["propertyNames"] = {"pattern": f"^(?:{self.key_pattern})$"}
        return self._with_description(s)


def _opt(spec: Spec) -> Field:
    return Field(spec, required=False)


# ----------------------------------------------------------------- the v1 description

NAME = r"[A-Za-z_][A-Za-z0-9_.\-]*"

ESTIMATE = Object(
    {
        "value": Field(OneOf((Number(), Array((None,))), expected="a number or a list of numbers")),
        "uncertainty": Field(
            OneOf((Number(minimum=0), Array((None,), minimum=0)),
                  expected="a number >= 0 or a list of numbers >= 0"),
        ),
        "unit": Field(String(description="unit of value and uncertainty, SI ('1' for dimensionless)")),
    },
    description="a value with its standard uncertainty (k = 1)",
)

NOISE_AXIS = Object(
    {
        "density": Field(Object(ESTIMATE.fields, description="white-noise density, one-sided, (m/s^2)/sqrt(Hz)")),
        "bias_instability": Field(Nullable(Object(
            ESTIMATE.fields,
            description="bias instability, m/s^2: minimum of the Allan deviation / 0.664 (IEEE 952); "
                        "null when the record is too short to reach the minimum"))),
        "bias_instability_tau": Field(Nullable(Number(exclusive_minimum=0, description="tau of the minimum, s"))),
        "random_walk": Field(Nullable(Object(
            ESTIMATE.fields,
            description="rate random walk K, (m/s^2)/sqrt(s), read on the tau^+1/2 line at tau = 3 s; "
                        "null when the record is too short to show it"))),
    },
    description="noise figures of one axis",
)

CORRECTION = Object(
    {
        "matrix": Field(Array((3, 3), description="C in calibrated = C @ (raw - b)")),
        "bias": Field(Array((3,), description="b, m/s^2")),
        "matrix_uncertainty": Field(Array((3, 3), minimum=0, description="sqrt of the covariance diagonal for C")),
        "bias_uncertainty": Field(Array((3,), minimum=0, description="sqrt of the covariance diagonal for b, m/s^2")),
        "covariance": Field(Array((12, 12), description="covariance of [C row-major, b] (SI)")),
    },
    description="the canonical correction: calibrated = C @ (raw - b), raw = counts x nominal scale, in m/s^2",
)

PROFILE_V1 = Object(
    {
        "schema_version": Field(Const(SCHEMA_VERSION, description="profile schema version")),
        "device": Field(Object(
            {
                "identity": Field(Nullable(String(min_length=1, description=(
                    "serial number, BLE address, bus/address or sim seed; null when unknown")))),
                "driver": Field(Nullable(String(description="driver (URL scheme) that read the device"))),
                "chip": Field(Nullable(String(description="e.g. mpu9250, icm20948, sim"))),
                "who_am_i": Field(Nullable(Integer(minimum=0, maximum=255, description="WHO_AM_I register"))),
                "url": Field(Nullable(String(description="device URL used for the calibration recording"))),
                "range_g": Field(Nullable(Number(exclusive_minimum=0, description="full scale, +-g"))),
                "scale": Field(Nullable(Number(exclusive_minimum=0, description="nominal m/s^2 per count"))),
                "rate": Field(Nullable(Number(exclusive_minimum=0, description="nominal sample rate, Hz"))),
                "delivered_rate": Field(Nullable(Number(exclusive_minimum=0, description="measured rate, Hz"))),
            },
            description="which device the profile belongs to",
        )),
        "units": Field(String(enum=("m/s^2",), description=(
            "units of the raw samples the correction applies to (raw = counts x nominal scale)"))),
        "calibration": Field(Object(
            {
                "procedure": Field(String(min_length=1, description="static_faces, wheel, slider_crank, rotary_bench, ...")),
                "method": Field(String(min_length=1, description="estimator used")),
                "model": Field(String(description="sensor model fitted")),
                "g": Field(Number(exclusive_minimum=0, description="local gravity used, m/s^2")),
                "settings": Field(Plain(mapping=True, description="the method's settings")),
                "correction": Field(CORRECTION),
                "parameters": Field(Object(
                    additional=ESTIMATE, key_pattern=NAME,
                    description="the method's parameters by name, with standard uncertainties and units",
                )),
                "parameter_names": Field(ListOf(String(pattern=NAME), description=(
                    "free parameters in the order of parameter_covariance"))),
                "parameter_covariance": Field(Nullable(Array((None, None), description=(
                    "covariance of the free parameters (SI), square, in parameter_names order")))),
            },
            description="the method, its settings, the correction and the method's parameters",
        )),
        "quality": Field(Object(
            {
                "residual_rms": Field(Nullable(Number(minimum=0, description="RMS of the fit residuals, m/s^2"))),
                "n_samples": _opt(Nullable(Integer(minimum=0, description="samples used"))),
                "sd_over_crb": _opt(Plain(description="standard deviation over Cramer-Rao bound, where known")),
            },
            additional=Plain(), key_pattern=NAME,
            description="quality figures; further method-specific figures by name",
        )),
        "noise": Field(Nullable(Object(
            {
                "method": Field(String(description="how the figures were computed")),
                "convention": Field(String(description="density convention")),
                "rate": Field(Number(exclusive_minimum=0, description="sample rate of the still recording, Hz")),
                "duration": Field(Number(exclusive_minimum=0, description="length of the still recording, s")),
                "n_samples": Field(Integer(minimum=2)),
                "recording_hash": Field(Nullable(String(pattern=r"sha256:[0-9a-f]{64}"))),
                "date": Field(DateTime(description="when the figures were computed")),
                "axes": Field(Object({"x": Field(NOISE_AXIS), "y": Field(NOISE_AXIS), "z": Field(NOISE_AXIS)})),
            },
            description="noise figures from the Allan deviation of a still recording (accelrig noise)",
        ))),
        "warnings": Field(ListOf(String(), description="what the operator was told during calibration")),
        "provenance": Field(Object(
            {
                "created": Field(DateTime(description="when the profile was made (UTC)")),
                "software_version": Field(String(description="accelrig version that made it")),
                "recording_hash": Field(Nullable(String(pattern=r"sha256:[0-9a-f]{64}", description=(
                    "sha256 of the calibration recording's numbers")))),
                "recording_source": Field(Nullable(String(description="file the recording came from"))),
                "recording_samples": Field(Nullable(Integer(minimum=0))),
                "recording_start": Field(Nullable(DateTime(description="when the recording started"))),
                "temperature_c": Field(Nullable(Number(description="sensor temperature, degC, where known"))),
                "rig": Field(Nullable(Plain(mapping=True, description="rig geometry used"))),
            },
            description="where the profile came from",
        )),
    },
    description="accelrig device profile, schema version 1",
)


# ----------------------------------------------------------------- checks beyond structure


def _check_square_symmetric(matrix: list, path: str) -> None:
    n = len(matrix)
    scale = max((abs(matrix[i][i]) for i in range(n)), default=0.0)
    tol = 1e-9 * scale + 1e-300
    for i in range(n):
        if matrix[i][i] < 0:
            _fail(f"{path}[{i}][{i}]", f"a variance cannot be negative, got {matrix[i][i]!r}")
        for j in range(i + 1, n):
            if abs(matrix[i][j] - matrix[j][i]) > tol:
                _fail(path, f"not symmetric: [{i}][{j}] = {matrix[i][j]!r} but [{j}][{i}] = {matrix[j][i]!r}")


def _check_uncertainty_matches(uncertainty: list[float], variances: list[float], path: str) -> None:
    for i, (u, var) in enumerate(zip(uncertainty, variances)):
        expected = math.sqrt(max(var, 0.0))
        if abs(u - expected) > 1e-6 * max(expected, 1e-300) + 1e-15:
            _fail(f"{path}[{i}]", f"{u!r} disagrees with the covariance diagonal (sqrt = {expected!r})")


def _check_estimate(est: dict, path: str) -> None:
    value, unc = est["value"], est["uncertainty"]
    if isinstance(value, list) != isinstance(unc, list) or (isinstance(value, list) and len(value) != len(unc)):
        _fail(f"{path}.uncertainty", f"expected the shape of value ({describe(value)}), got {describe(unc)}")


def cross_checks(data: dict) -> None:
    """Consistency checks the structure alone cannot express (run after PROFILE_V1.check)."""
    corr = data["calibration"]["correction"]
    cov = corr["covariance"]
    _check_square_symmetric(cov, "calibration.correction.covariance")
    diag = [cov[i][i] for i in range(12)]
    _check_uncertainty_matches(
        [u for row in corr["matrix_uncertainty"] for u in row], diag[:9], "calibration.correction.matrix_uncertainty"
    )
    _check_uncertainty_matches(corr["bias_uncertainty"], diag[9:], "calibration.correction.bias_uncertainty")
    det = _det3(corr["matrix"])
    if abs(det) < 1e-6:
        _fail("calibration.correction.matrix", f"singular (determinant {det:.3g}): no sensor has this correction")

    cal = data["calibration"]
    for name, est in cal["parameters"].items():
        _check_estimate(est, f"calibration.parameters.{name}")
    names = cal["parameter_names"]
    if len(set(names)) != len(names):
        dup = next(n for n in names if names.count(n) > 1)
        _fail("calibration.parameter_names", f"{dup!r} appears twice")
    pcov = cal["parameter_covariance"]
    if pcov is not None:
        if len(pcov) != len(names):
            _fail("calibration.parameter_covariance",
                  f"expected {len(names)}x{len(names)} numbers (one per parameter name), got {describe(pcov)}")
        _check_square_symmetric(pcov, "calibration.parameter_covariance")

    noise = data["noise"]
    if noise is not None:
        for axis, figures in noise["axes"].items():
            for key in ("density", "bias_instability", "random_walk"):
                if figures[key] is not None:
                    _check_estimate(figures[key], f"noise.axes.{axis}.{key}")
            if (figures["bias_instability"] is None) != (figures["bias_instability_tau"] is None):
                _fail(f"noise.axes.{axis}.bias_instability_tau", "must be given exactly when bias_instability is")

    device = data["device"]
    if device["range_g"] is not None and device["scale"] is not None:
        # scale = range_g * g / 2^15 for a 16-bit part; other widths are fine, but the two
        # must not disagree by more than the spread of real parts (12 to 20 bits).
        ratio = device["range_g"] * 9.80665 / device["scale"]
        if not 2 ** 11 * 0.99 <= ratio <= 2 ** 19 * 1.01:
            _fail("device.scale", f"{device['scale']!r} m/s^2 per count does not fit range_g {device['range_g']!r}")


def _det3(m: list) -> float:
    return (m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]))


def validate(data) -> None:
    """Raise ProfileError naming the first bad field; return None when ``data`` is a valid v1 profile."""
    PROFILE_V1.check(data, "")
    cross_checks(data)


def json_schema() -> dict:
    """The published JSON Schema (draft 2020-12) of profile v1."""
    schema = {"$schema": "https://json-schema.org/draft/2020-12/schema", "$id": SCHEMA_ID,
              "title": "accelrig device profile v1"}
    schema.update(PROFILE_V1.json_schema())
    return schema


def json_schema_text() -> str:
    return json.dumps(json_schema(), indent=2) + "\n"

