"""Independent oracles (test-only dependencies): allantools for the Allan deviation,
jsonschema for the published profile schema.

Allan deviation.  accelrig and ``allantools.oadev`` compute the same estimator
(NIST SP 1065 eq. 11, overlapping, stride 1) by the same route: the samples,
mean removed, are integrated into N = n + 1 "phase" points (a leading 0), and
sigma^2(m tau0) = sum (x[i+2m] - 2 x[i+m] + x[i])^2 / (2 (m tau0)^2 (N - 2m)).
So they must agree to rounding.  The conventions to line up:

* allantools defaults to ``data_type="phase"``; accelerations are "frequency"
  data (averaged, not differenced), so ``data_type="freq"`` is required.
  allantools' fractional frequency is dimensionless; the estimator is linear in
  the data, so m/s^2 pass through unchanged.
* ``rate`` is the sample rate in Hz in both; tau = m / rate in both.
* Tau grid: allantools' "octave" grid is m = 1, 2, ..., 2**floor(log2(n + 1)),
  then drops the points with fewer than 2 terms (N - 2m <= 1).  That is
  accelrig's rule 2m < n exactly, so the grids coincide for every n.
* Error bars differ by design: allantools' ``ade`` is sigma / sqrt(N - 2m);
  accelrig uses the equivalent degrees of freedom (SP 1065 Table 5).  The edf
  formulas are checked against ``allantools.ci.edf_simple``, whose N is the
  number of phase points (accelrig's functions take the sample count n and use
  n + 1).  One known divergence: for flicker FM at m = 1 allantools (2024.6)
  returns 2 (N - 2) / (2.3 N - 4.9), which tends to 0.87 whatever N is;
  accelrig uses 2 (N - 2)^2 / (2.3 N - 4.9) ~ 0.87 N, which matches the m >= 2
  branch 5 N^2 / (4 m (N + 3 m)) in order of magnitude, as an edf of
  N - 2 nearly independent terms must.  That point is checked for plausibility
  only.

Profile schema.  ``profiles/schema-v1.json`` is the contract published for
other tools.  It must be a valid Draft 2020-12 schema, every example profile
must satisfy it, and every malformed profile accelrig refuses (the table in
test_profile_io.py) must be refused by it too, for the right field, unless the
rule is one JSON Schema cannot state; those are listed in NOT_EXPRESSIBLE with
the reason, and accelrig must refuse them itself.
"""

from __future__ import annotations

import json
from pathlib import Path

import allantools
import jsonschema
import numpy as np
import pytest
import yaml
from allantools import ci as allantools_ci

from accelrig.errors import ProfileError
from accelrig.estimation.allan import allan_deviation, flicker_edf, random_walk_edf, white_edf
from accelrig.profiles import load_profile, parse_profile_text, profile_from_result
from test_profile_io import _DELETE, MALFORMED, _edit, make_result

REPO = Path(__file__).resolve().parents[1]
RATE = 200.0
N_SAMPLES = 2**15 + 1  # odd on purpose: no neat power-of-two coincidences
# Measured: 2e-16 (one ulp) for white and flicker noise, 5e-13 for a random walk,
# whose small-tau second differences cancel large cumulative sums.
RTOL = 1e-10


# ------------------------------------------------------------------- Allan deviation


def _white(rng, n):
    return 9.80665 + 0.02 * rng.standard_normal(n)  # on a 1 g axis: the mean must not leak in


def _random_walk(rng, n):
    return np.cumsum(1e-4 * rng.standard_normal(n))


def _flicker(rng, n):
    """1/f power spectrum by shaping white noise in the frequency domain (flicker-ish)."""
    f = np.fft.rfftfreq(n, 1.0 / RATE)
    spectrum = rng.standard_normal(f.size) + 1j * rng.standard_normal(f.size)
    spectrum[0] = 0.0
    spectrum[1:] /= np.sqrt(f[1:])
    return 1e-3 * np.fft.irfft(spectrum, n)


def _mixture(rng, n):
    return _white(rng, n) + _random_walk(rng, n) + _flicker(rng, n)


SIGNALS = {"white": _white, "random_walk": _random_walk, "flicker": _flicker, "mixture": _mixture}


def _allantools_oadev(y, taus):
    taus_used, adev, _, _ = allantools.oadev(y, rate=RATE, data_type="freq", taus=taus)
    return taus_used, adev


@pytest.mark.parametrize("kind", SIGNALS)
def test_overlapping_adev_matches_allantools(kind):
    y = SIGNALS[kind](np.random.default_rng(7), N_SAMPLES)
    curve = allan_deviation(y, RATE)
    taus, adev = _allantools_oadev(y, curve.tau)
    np.testing.assert_array_equal(taus, curve.tau)
    np.testing.assert_allclose(curve.adev, adev, rtol=RTOL, atol=0)


def test_adev_at_arbitrary_factors_matches_allantools():
    y = _mixture(np.random.default_rng(8), N_SAMPLES)
    m = np.array([1, 3, 10, 37, 100, 1000, 5000])
    curve = allan_deviation(y, RATE, m=m)
    taus, adev = _allantools_oadev(y, m / RATE)
    np.testing.assert_array_equal(taus, curve.tau)
    np.testing.assert_allclose(curve.adev, adev, rtol=RTOL, atol=0)


@pytest.mark.parametrize("n", [64, 65, 127, 128, 129, 1000, 1023, 1024, 1025])
def test_octave_grid_is_allantools_octave_grid(n):
    y = np.random.default_rng(n).standard_normal(n)
    curve = allan_deviation(y, RATE)
    taus, adev = _allantools_oadev(y, "octave")
    np.testing.assert_array_equal(np.round(taus * RATE).astype(np.int64), curve.m)
    np.testing.assert_allclose(curve.adev, adev, rtol=RTOL, atol=0)


@pytest.mark.parametrize("m", [1, 2, 3, 4, 16, 256, 4096, 16000])
def test_edf_formulas_match_allantools(m):
    n = N_SAMPLES
    big_n = n + 1  # allantools counts phase points
    assert white_edf(n, np.array([m]))[0] == pytest.approx(allantools_ci.edf_simple(big_n, m, 0), rel=1e-12)
    assert random_walk_edf(n, m) == pytest.approx(allantools_ci.edf_simple(big_n, m, -2), rel=1e-12)
    if m >= 2:
        assert flicker_edf(n, m) == pytest.approx(allantools_ci.edf_simple(big_n, m, -1), rel=1e-12)
    else:  # see the module docstring: allantools' m = 1 branch lacks the square
        assert 0.5 * n < flicker_edf(n, 1) < n
        assert flicker_edf(n, 1) > flicker_edf(n, 2)


# ------------------------------------------------------------------- profile schema

SCHEMA = json.loads((REPO / "profiles" / "schema-v1.json").read_text())
EXAMPLES = sorted((REPO / "profiles").glob("example-*.yaml"))


def _label(dotted, value) -> str:
    return f"{dotted}=(deleted)" if value is _DELETE else f"{dotted}={value!r}"


# Rules accelrig enforces that JSON Schema (2020-12) cannot state, with the reason.
NOT_EXPRESSIBLE = {
    "calibration.parameters.offset.uncertainty=[0.001, 0.001]":
        "uncertainty must have the shape of value: a relation between two sibling fields",
    "calibration.parameter_covariance=[[1.0]]":
        "the covariance must be len(parameter_names) square: a size taken from another field",
    "calibration.correction.bias_uncertainty=[1.0, 1.0, 1.0]":
        "must equal the square root of the covariance diagonal: arithmetic across fields",
    "calibration.correction.matrix=[[1, 0, 0], [0, 1, 0], [0, 0, 0]]":
        "C must be invertible (det != 0): arithmetic",
    "quality.residual_rms=nan":
        "JSON has no NaN; jsonschema takes float('nan') for a number and every comparison with NaN is "
        "false, so 'minimum: 0' cannot fail; only a strict JSON encoder refuses it (test_nan_is_not_json)",
}


def _validator():
    return jsonschema.Draft202012Validator(SCHEMA)


def _errors(data):
    return sorted(_validator().iter_errors(data), key=lambda e: list(e.absolute_path))


def _accelrig_refuses(data) -> bool:
    try:
        parse_profile_text(yaml.safe_dump(data, sort_keys=False), "<test>")
    except ProfileError:
        return True
    return False


@pytest.fixture(scope="module")
def base_profile() -> dict:
    """The fresh profile test_profile_io.py edits into its malformed cases (plain data)."""
    from accelrig.sim.device import simulate
    from accelrig.sim.rigs.still import StillRig
    from accelrig.sim.sensor import SensorModel, SimClock

    recording = simulate(StillRig(), SensorModel(), SimClock(), seconds=1.0, seed=3)
    profile = profile_from_result(make_result(), recording, device={"identity": "sim-test-3", "who_am_i": 0x71})
    return json.loads(json.dumps(profile.data))


def test_published_schema_is_a_valid_draft_2020_12_schema():
    assert SCHEMA["$schema"] == "https://json-schema.org/draft/2020-12/schema"
    assert jsonschema.validators.validator_for(SCHEMA) is jsonschema.Draft202012Validator
    jsonschema.Draft202012Validator.check_schema(SCHEMA)


@pytest.mark.parametrize("path", EXAMPLES, ids=[p.name for p in EXAMPLES])
def test_example_profiles_satisfy_the_published_schema(path):
    data = yaml.safe_load(path.read_text())
    assert [e.message for e in _errors(data)] == []
    load_profile(path)  # and accelrig agrees


def test_there_are_examples_to_check():
    assert len(EXAMPLES) >= 2


def test_a_fresh_profile_satisfies_the_published_schema(base_profile):
    # without this, every malformed case below would be "refused" vacuously
    assert [e.message for e in _errors(base_profile)] == []
    assert not _accelrig_refuses(base_profile)


@pytest.mark.parametrize(
    "dotted,value", [(d, v) for d, v, _ in MALFORMED], ids=[_label(d, v)[:50] for d, v, _ in MALFORMED]
)
def test_malformed_profile_is_refused_by_the_schema_where_it_can_say_so(base_profile, dotted, value):
    data = _edit(json.loads(json.dumps(base_profile)), dotted, value)
    assert _accelrig_refuses(data)
    errors = _errors(data)
    label = _label(dotted, value)
    if label in NOT_EXPRESSIBLE:
        assert errors == [], f"the schema now refuses {label}: move it out of NOT_EXPRESSIBLE"
        return
    assert errors, f"the published schema accepts {label}, which accelrig refuses"
    keys = dotted.split(".")
    for e in errors:  # at the edited field, inside it, or at the object missing it / given an unknown key
        path = [str(k) for k in e.absolute_path]
        assert path[: len(keys)] == keys[: len(path)], (path, e.message)


def test_not_expressible_list_names_real_cases():
    labels = {_label(d, v) for d, v, _ in MALFORMED}
    assert set(NOT_EXPRESSIBLE) <= labels, set(NOT_EXPRESSIBLE) - labels


def test_nan_is_not_json(base_profile):
    data = _edit(json.loads(json.dumps(base_profile)), "quality.residual_rms", float("nan"))
    with pytest.raises(ValueError):
        json.dumps(data, allow_nan=False)


def test_asymmetric_covariance_is_refused_by_accelrig_only(base_profile):
    # symmetry compares elements with each other: not expressible in JSON Schema
    data = json.loads(json.dumps(base_profile))
    data["calibration"]["correction"]["covariance"][0][1] += 1e-3
    assert _errors(data) == []
    assert _accelrig_refuses(data)


@pytest.mark.parametrize(
    "text", ["", "- 1\n- 2\n", "schema_version: '1'\n", "schema_version: 1\n", "schema_version: 2\n"]
)
def test_not_a_profile_is_refused_by_both(text):
    data = yaml.safe_load(text)
    assert _errors(data)
    with pytest.raises(ProfileError):
        parse_profile_text(text, "<test>")
