"""Profiles: build, save, load, validate.  Malformed files are refused with one line naming the field."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from accelrig.errors import ProfileError
from accelrig.files import OutputExists
from accelrig.profiles import Profile, json_schema, load_profile, profile_from_result, save_profile
from accelrig.profiles.io import dump_yaml
from accelrig.result import CalibrationResult, Correction, Estimate
from accelrig.sim.device import simulate
from accelrig.sim.rigs.still import StillRig
from accelrig.sim.sensor import SensorModel, SimClock

REPO = Path(__file__).resolve().parents[1]


def make_result(matrix=None, bias=None, cov=None, procedure="static_faces") -> CalibrationResult:
    rng = np.random.default_rng(1)
    matrix = np.eye(3) + 0.01 * rng.standard_normal((3, 3)) if matrix is None else matrix
    bias = rng.uniform(-0.3, 0.3, 3) if bias is None else bias
    if cov is None:
        a = 1e-4 * rng.standard_normal((12, 12))
        cov = a @ a.T
    return CalibrationResult(
        procedure=procedure,
        method="test-method",
        model="C (raw - b)",
        correction=Correction(matrix, bias, cov),
        parameters={
            "gain_x": Estimate(1.01, 2e-4, "1"),
            "offset": Estimate([0.1, -0.2, 0.05], [1e-3, 1e-3, 2e-3], "m/s^2"),
        },
        covariance=np.diag([4e-8, 1e-6]),
        parameter_names=["gain_x", "offset_x"],
        quality={"residual_rms": 0.031, "n_samples": 1200, "sd_over_crb": {"gain_x": 1.02}},
        settings={"faces": 6, "rig": {"table": "level"}},
        warnings=["face +z was held only 1.8 s"],
    )


@pytest.fixture
def recording():
    return simulate(StillRig(), SensorModel(), SimClock(), seconds=1.0, seed=3)


@pytest.fixture
def profile(recording):
    return profile_from_result(make_result(), recording, device={"identity": "sim-test-3", "who_am_i": 0x71})


def test_profile_from_result_fills_the_contract(profile, recording):
    assert isinstance(profile, Profile)
    assert profile.units == "m/s^2"
    assert profile.device["identity"] == "sim-test-3"
    assert profile.device["who_am_i"] == 0x71
    assert profile.device["range_g"] == 2.0
    assert profile.device["scale"] == pytest.approx(2 * 9.80665 / 32768)
    res = make_result()
    np.testing.assert_array_equal(profile.correction.matrix, res.correction.matrix)
    np.testing.assert_array_equal(profile.correction.covariance, res.correction.covariance)
    prov = profile.data["provenance"]
    assert prov["recording_hash"] == recording.content_hash()
    assert prov["recording_samples"] == len(recording)
    assert prov["rig"] == {"table": "level"}  # rig geometry goes to provenance
    assert "rig" not in profile.data["calibration"]["settings"]


def test_save_load_round_trip_is_identical(tmp_path, profile):
    path = tmp_path / "p.yaml"
    save_profile(profile, path)
    loaded = load_profile(path)
    assert loaded.data == profile.data
    save_profile(loaded, tmp_path / "q.yaml")
    assert (tmp_path / "q.yaml").read_text() == path.read_text()


def test_save_refuses_to_overwrite_when_asked(tmp_path, profile):
    path = tmp_path / "p.yaml"
    save_profile(profile, path)
    with pytest.raises(OutputExists, match="exists"):   # a DataError: the output, not the profile, is the problem
        save_profile(profile, path, overwrite=False)


def test_save_of_invalid_profile_writes_nothing(tmp_path, profile):
    path = tmp_path / "p.yaml"
    save_profile(profile, path)
    before = path.read_text()
    bad = profile.copy()
    bad.data["calibration"]["correction"]["bias"] = [0.0, 0.0]
    with pytest.raises(ProfileError, match=r"calibration\.correction\.bias: expected a list of 3 numbers"):
        save_profile(bad, path)
    assert path.read_text() == before
    assert [p.name for p in tmp_path.iterdir()] == ["p.yaml"]  # no temp file left behind


def test_result_without_correction_is_refused():
    res = make_result()
    res.correction = None
    with pytest.raises(ProfileError, match="no correction"):
        profile_from_result(res)


def test_non_finite_quality_figures_are_kept_as_unknown():
    res = make_result()
    res.quality["sd_over_crb"] = {"gain_x": float("nan")}
    p = profile_from_result(res)
    assert p.data["quality"]["sd_over_crb"] == {"gain_x": None}


def test_non_finite_estimate_is_a_bug_reported_in_one_line():
    res = make_result()
    res.parameters["gain_x"] = Estimate(float("nan"), 1e-4, "1")
    with pytest.raises(ProfileError, match=r"calibration\.parameters\.gain_x\.value: expected a number or a list"):
        profile_from_result(res)


def test_unknown_device_fields_are_null_not_guessed():
    p = profile_from_result(make_result())
    assert p.device["identity"] is None and p.device["range_g"] is None
    assert p.data["provenance"]["recording_hash"] is None


# ------------------------------------------------------------------- malformed profiles


def _edit(data: dict, dotted: str, value) -> dict:
    keys = dotted.split(".")
    node = data
    for k in keys[:-1]:
        node = node[k]
    if value is _DELETE:
        del node[keys[-1]]
    else:
        node[keys[-1]] = value
    return data


class _Deleted:
    """The edit that removes a key; a fixed repr keeps the test ids the same in every process (pytest-xdist)."""

    def __repr__(self) -> str:
        return "(deleted)"


_DELETE = _Deleted()

# (edit, expected message fragment): each must be refused naming the field.
MALFORMED = [
    ("calibration.correction.matrix", [[1, 0], [0, 1], [0, 0]],
     "calibration.correction.matrix: expected 3x3 numbers, got 3x2"),
    ("calibration.correction.bias", "zero", "calibration.correction.bias: expected a list of 3 numbers, got the string 'zero'"),
    ("calibration.correction.covariance", [[0.0] * 12] * 11, "calibration.correction.covariance: expected 12x12 numbers, got 11x12"),
    ("device.range_g", "2g", "device.range_g: expected a number, got the string '2g'"),
    ("device.range_g", -2.0, "device.range_g: expected a number > 0"),
    ("device.who_am_i", True, "device.who_am_i: expected an integer, got a boolean"),
    ("calibration.method", _DELETE, "calibration.method: missing (required field)"),
    ("provenance", _DELETE, "provenance: missing (required field)"),
    ("device.colour", "blue", "device.colour: unknown key"),
    ("surprise", 1, "surprise: unknown key"),
    ("units", "g", "units: expected one of 'm/s^2', got 'g'"),
    ("calibration.parameters.gain_x.uncertainty", -1.0, "calibration.parameters.gain_x.uncertainty: expected a number >= 0"),
    ("calibration.parameters.offset.uncertainty", [1e-3, 1e-3], "calibration.parameters.offset.uncertainty: expected the shape of value"),
    ("calibration.parameter_covariance", [[1.0]], "calibration.parameter_covariance: expected 2x2 numbers"),
    ("provenance.created", "yesterday", "provenance.created: expected a UTC date-time"),
    ("calibration.correction.bias_uncertainty", [1.0, 1.0, 1.0], "calibration.correction.bias_uncertainty[0]: 1.0 disagrees with the covariance"),
    ("calibration.correction.matrix", [[1, 0, 0], [0, 1, 0], [0, 0, 0]], "calibration.correction.matrix: singular"),
    ("quality.residual_rms", float("nan"), "quality.residual_rms: expected a finite number"),
    ("schema_version", 2, "schema_version: 2 is newer than this accelrig reads"),
    ("schema_version", 0, "schema_version: 0 is not a version accelrig ever wrote"),
    ("schema_version", _DELETE, "schema_version: missing"),
]


@pytest.mark.parametrize("dotted,value,message", MALFORMED, ids=[f"{m[0]}={m[1]!r}"[:50] for m in MALFORMED])
def test_malformed_profile_is_refused_naming_the_field(tmp_path, profile, dotted, value, message):
    data = _edit(json.loads(json.dumps(profile.data)), dotted, value)
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    with pytest.raises(ProfileError) as err:
        load_profile(path)
    text = str(err.value)
    assert text.startswith(f"{path}: ")
    assert message in text
    assert "\n" not in text


def test_covariance_not_symmetric_is_refused(tmp_path, profile):
    data = json.loads(json.dumps(profile.data))
    data["calibration"]["correction"]["covariance"][0][1] += 1e-3
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(ProfileError, match=r"calibration\.correction\.covariance: not symmetric: \[0\]\[1\]"):
        load_profile(path)


def test_python_object_tag_is_refused_with_its_line(tmp_path, profile):
    text = dump_yaml(profile.data).replace("warnings: [", "warnings: [!!python/object/apply:os.system ['echo pwned'], ", 1)
    path = tmp_path / "evil.yaml"
    path.write_text(text)
    lineno = next(i for i, line in enumerate(text.splitlines(), 1) if "python/object" in line)
    with pytest.raises(ProfileError) as err:
        load_profile(path)
    msg = str(err.value)
    assert msg.startswith(f"{path}:{lineno}: could not determine a constructor for the tag")
    assert "python/object/apply:os.system" in msg


def test_yaml_timestamp_and_binary_are_not_plain_data(tmp_path, profile):
    text = dump_yaml(profile.data).replace("created: '", "created: ", 1)
    text = text.replace("Z'\n  software_version", "Z\n  software_version", 1)
    path = tmp_path / "date.yaml"
    path.write_text(text)
    with pytest.raises(ProfileError, match="provenance.created: expected a UTC date-time.*got a datetime"):
        load_profile(path)
    data = json.loads(json.dumps(profile.data))
    data["calibration"]["settings"]["blob"] = b"\x00\x01"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(ProfileError, match=r"calibration\.settings\.blob: expected plain data.*got a bytes"):
        load_profile(path)


@pytest.mark.parametrize(
    "text,message",
    [
        ("", "not a profile (the file is empty)"),
        ("- 1\n- 2\n", "not a profile (expected a mapping at the top level, got list)"),
        ("schema_version: 1\ndevice: {identity: [\n", "not valid YAML"),
        ("schema_version: '1'\n", "schema_version: expected an integer, got '1'"),
        ("schema_version: 1\n", "device: missing (required field)"),
    ],
)
def test_not_a_profile(tmp_path, text, message):
    path = tmp_path / "x.yaml"
    path.write_text(text)
    with pytest.raises(ProfileError, match=message.replace("(", r"\(").replace(")", r"\)")):
        load_profile(path)


def test_duplicate_key_is_refused_with_its_line(tmp_path, profile):
    text = dump_yaml(profile.data)
    text = text.replace("  g: 9.80665\n", "  g: 9.80665\n  g: 9.81\n", 1)
    lineno = text.splitlines().index("  g: 9.81") + 1
    path = tmp_path / "dup.yaml"
    path.write_text(text)
    with pytest.raises(ProfileError, match=f"dup.yaml:{lineno}: calibration.g: key given twice"):
        load_profile(path)


def test_missing_and_binary_files(tmp_path):
    with pytest.raises(ProfileError, match="none.yaml: no such file"):
        load_profile(tmp_path / "none.yaml")
    (tmp_path / "bin.yaml").write_bytes(b"\xff\xfe\x00")
    with pytest.raises(ProfileError, match="not a text file"):
        load_profile(tmp_path / "bin.yaml")


# ------------------------------------------------------------------- schema file


def test_committed_json_schema_is_the_generated_one():
    committed = json.loads((REPO / "profiles" / "schema-v1.json").read_text())
    assert committed == json_schema(), "regenerate with: python profiles/make_examples.py --schema-only"


def test_json_schema_refuses_unknown_keys_everywhere_but_open_maps():
    def walk(node, path=""):
        if isinstance(node, dict):
            if node.get("type") == "object" and "properties" in node:
                assert "additionalProperties" in node, path
            for k, v in node.items():
                walk(v, f"{path}/{k}")
        elif isinstance(node, list):
            for v in node:
                walk(v, path)

    schema = json_schema()
    walk(schema)
    assert schema["additionalProperties"] is False


# ------------------------------------------------------------------- property test

finite = st.floats(min_value=-1e6, max_value=1e6, allow_nan=False, allow_infinity=False)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    matrix=st.lists(st.lists(finite, min_size=3, max_size=3), min_size=3, max_size=3),
    bias=st.lists(finite, min_size=3, max_size=3),
    scale=st.floats(min_value=1e-12, max_value=1e3),
    names=st.lists(st.from_regex(r"[a-z][a-z0-9_]{0,8}", fullmatch=True), min_size=0, max_size=4, unique=True),
    warnings=st.lists(st.text(max_size=30), max_size=3),
    seed=st.integers(0, 2**32 - 1),
)
def test_round_trip_property(tmp_path, matrix, bias, scale, names, warnings, seed):
    m = np.eye(3) + np.array(matrix, dtype=float) * 1e-7  # within the plausible gain band (schema.GAIN_BAND)
    rng = np.random.default_rng(seed)
    a = scale * rng.standard_normal((12, 12))
    cov = a @ a.T
    res = make_result(matrix=m, bias=np.array(bias), cov=cov)
    res.parameters = {n: Estimate(float(rng.standard_normal()), float(abs(rng.standard_normal())), "m/s^2") for n in names}
    res.parameter_names = list(names)
    b = rng.standard_normal((len(names), len(names)))
    res.covariance = b @ b.T if names else None
    res.warnings = warnings
    profile = profile_from_result(res, device={"identity": "dev-" + str(seed)})
    path = tmp_path / f"p{seed}.yaml"
    save_profile(profile, path)
    loaded = load_profile(path)
    assert loaded.data == profile.data
    np.testing.assert_array_equal(loaded.correction.matrix, m)
    np.testing.assert_array_equal(loaded.correction.covariance, res.correction.covariance)


# ------------------------------------------------------------------- example profiles

EXAMPLE_FILES = sorted((REPO / "profiles").glob("example-*.yaml"))


@pytest.mark.parametrize("path", EXAMPLE_FILES, ids=[p.name for p in EXAMPLE_FILES])
def test_example_profile_round_trips(tmp_path, path):
    profile = load_profile(path)
    assert path.read_text() == dump_yaml(profile.data), "examples are written by profiles/make_examples.py"
    save_profile(profile, tmp_path / path.name)
    again = load_profile(tmp_path / path.name)
    assert again.data == profile.data
    assert (tmp_path / path.name).read_text() == path.read_text()
    assert profile.noise is not None and profile.data["provenance"]["recording_hash"]


def test_examples_exist_for_the_installed_methods():
    """One example per calibration method installed; none for a method that is not (regenerate with
    python profiles/make_examples.py)."""
    import importlib.util
    import runpy

    examples = runpy.run_path(str(REPO / "profiles" / "make_examples.py"))["EXAMPLES"]
    installed = {name for name, (module, _, _) in examples.items() if importlib.util.find_spec(module) is not None}
    present = {p.name[len("example-"):-len(".yaml")] for p in EXAMPLE_FILES}
    assert present <= set(examples), f"stale example files: {present - set(examples)}"
    assert installed <= present, f"regenerate: python profiles/make_examples.py (missing {installed - present})"
