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

import numpy as np

from accelrig.errors import ProfileError
from accelrig.spec import (
    Array,
    Const,
    DateTime,
    Field,
    Integer,
    Invalid,
    ListOf,
    Nullable,
    Number,
    Object,
    OneOf,
    Plain,
    String,
    check,
    describe,
    fail,
    optional,
)

SCHEMA_VERSION = 1

# Plausibility of what a profile says (checked after the structure): a MEMS part's sensitivity is within a
# few percent of nominal and its axes within a degree or two of square, so C = inverse gains is near the
# identity; a factor of 2 either way is another unit or another device, not a calibration.  g: on Earth.
GAIN_BAND = (0.5, 2.0)
G_BAND = (9.76, 9.84)
G_MAX = 16 * 9.80665        # even a stated off-Earth g must be one a supported chip can read (+-16 g)
SCHEMA_ID = "https://accelrig.invalid/profiles/schema-v1.json"


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
                "g_outside_earth": optional(String(min_length=1, description=(
                    "why g lies outside 9.76 .. 9.84 m/s^2 (a centrifuge, another body, a deliberate "
                    "reference): its presence is what accepts such a g"))),
                "settings": Field(Plain(mapping=True, description="the method's settings")),
                "correction": Field(CORRECTION),
                "parameters": Field(Object(
                    additional=ESTIMATE, key_pattern=NAME,
                    description="the method's parameters by name, with standard uncertainties and units",
                )),
                "parameter_meaning": optional(String(description=(
                    "what the parameters are, in one sentence (static's gain and offset correct the reading; "
                    "the wheel's are the sensor's own): the correction is the same form for every procedure"))),
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
                "n_samples": optional(Nullable(Integer(minimum=0, description="samples used"))),
                "sd_over_crb": optional(Plain(description="standard deviation over Cramer-Rao bound, where known")),
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
                    "sha256 of the numbers of the samples calibrated")))),
                "recording_source": Field(Nullable(String(description="file the recording came from"))),
                "recording_samples": Field(Nullable(Integer(minimum=0, description=(
                    "samples calibrated: the first N of the recording (a TUI capture runs on after the compute)")))),
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
            fail(f"{path}[{i}][{i}]", f"a variance cannot be negative, got {matrix[i][i]!r}")
        for j in range(i + 1, n):
            if abs(matrix[i][j] - matrix[j][i]) > tol:
                fail(path, f"not symmetric: [{i}][{j}] = {matrix[i][j]!r} but [{j}][{i}] = {matrix[j][i]!r}")


def _check_positive_semidefinite(matrix: list, path: str) -> None:
    """A covariance has no negative variance along any direction (eigenvalues >= 0 up to rounding)."""
    eig = np.linalg.eigvalsh(np.asarray(matrix, dtype=float))
    if eig.min() < -1e-9 * max(eig.max(), 1e-300):
        fail(path, f"not positive semi-definite (an eigenvalue is {eig.min():.3g}): not a covariance")


def _check_uncertainty_matches(uncertainty: list[float], variances: list[float], path: str) -> None:
    for i, (u, var) in enumerate(zip(uncertainty, variances, strict=True)):
        expected = math.sqrt(max(var, 0.0))
        if abs(u - expected) > 1e-6 * max(expected, 1e-300) + 1e-15:
            fail(f"{path}[{i}]", f"{u!r} disagrees with the covariance diagonal (sqrt = {expected!r})")


def _check_estimate(est: dict, path: str) -> None:
    value, unc = est["value"], est["uncertainty"]
    if isinstance(value, list) != isinstance(unc, list) or (isinstance(value, list) and len(value) != len(unc)):
        fail(f"{path}.uncertainty", f"expected the shape of value ({describe(value)}), got {describe(unc)}")


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
        fail("calibration.correction.matrix", f"singular (determinant {det:.3g}): no sensor has this correction")
    gains = np.linalg.svd(np.asarray(corr["matrix"], dtype=float), compute_uv=False)
    if not (GAIN_BAND[0] <= gains.min() and gains.max() <= GAIN_BAND[1]):
        fail("calibration.correction.matrix",
             f"gains (singular values) {gains.min():.3g} .. {gains.max():.3g} lie outside the plausible "
             f"{GAIN_BAND[0]:g} .. {GAIN_BAND[1]:g}: raw is in m/s^2 at the nominal scale, so C is near the identity")
    _check_positive_semidefinite(cov, "calibration.correction.covariance")
    g = data["calibration"]["g"]
    if g > G_MAX:
        fail("calibration.g", f"{g!r} m/s^2 is beyond the full scale of every supported chip (16 g): "
             "was it given in other units?")
    if not G_BAND[0] <= g <= G_BAND[1] and not data["calibration"].get("g_outside_earth"):
        fail("calibration.g", f"{g!r} m/s^2 is not gravity on Earth ({G_BAND[0]:g} .. {G_BAND[1]:g} m/s^2): "
             "if it is meant (a centrifuge, another body), say why in calibration.g_outside_earth")

    cal = data["calibration"]
    for name, est in cal["parameters"].items():
        _check_estimate(est, f"calibration.parameters.{name}")
    names = cal["parameter_names"]
    if len(set(names)) != len(names):
        dup = next(n for n in names if names.count(n) > 1)
        fail("calibration.parameter_names", f"{dup!r} appears twice")
    pcov = cal["parameter_covariance"]
    if pcov is not None:
        if len(pcov) != len(names):
            fail("calibration.parameter_covariance",
                  f"expected {len(names)}x{len(names)} numbers (one per parameter name), got {describe(pcov)}")
        _check_square_symmetric(pcov, "calibration.parameter_covariance")

    noise = data["noise"]
    if noise is not None:
        for axis, figures in noise["axes"].items():
            for key in ("density", "bias_instability", "random_walk"):
                if figures[key] is not None:
                    _check_estimate(figures[key], f"noise.axes.{axis}.{key}")
            if (figures["bias_instability"] is None) != (figures["bias_instability_tau"] is None):
                fail(f"noise.axes.{axis}.bias_instability_tau", "must be given exactly when bias_instability is")

    device = data["device"]
    if device["range_g"] is not None and device["scale"] is not None:
        # scale = range_g * g / 2^15 for a 16-bit part; other widths are fine, but the two
        # must not disagree by more than the spread of real parts (12 to 20 bits).
        ratio = device["range_g"] * 9.80665 / device["scale"]
        if not 2 ** 11 * 0.99 <= ratio <= 2 ** 19 * 1.01:
            fail("device.scale", f"{device['scale']!r} m/s^2 per count does not fit range_g {device['range_g']!r}")


def _det3(m: list) -> float:
    return (m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]))


def validate(data) -> None:
    """Raise ProfileError naming the first bad field; return None when ``data`` is a valid v1 profile."""
    check(PROFILE_V1, data, ProfileError)
    try:
        cross_checks(data)
    except Invalid as exc:
        raise ProfileError(str(exc)) from None


def json_schema() -> dict:
    """The published JSON Schema (draft 2020-12) of profile v1."""
    schema = {"$schema": "https://json-schema.org/draft/2020-12/schema", "$id": SCHEMA_ID,
              "title": "accelrig device profile v1"}
    schema.update(PROFILE_V1.json_schema())
    return schema


def json_schema_text() -> str:
    return json.dumps(json_schema(), indent=2) + "\n"

