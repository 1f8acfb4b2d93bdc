"""Plausibility of every number a person types or a file carries: URL options, flags, geometry, profiles."""

from __future__ import annotations

import numpy as np
import pytest

from accelrig.profiles import load_profile
from accelrig.profiles.io import dump_yaml
from hostile.support import EXAMPLE_PROFILE, assert_refused, snapshot

URL_CASES = {
    "sim://still?pace=fast&drop=2": "option drop .* must be >= 0 and <= 0.99",
    "sim://still?pace=fast&drop=1": "option drop",
    "sim://still?pace=fast&drop=nan": "not a finite number",
    "sim://still?pace=fast&rate_error=-2": "option rate_error",
    "sim://still?pace=fast&rate_error=-1": "option rate_error",
    "sim://still?pace=fast&seed=-1": "option seed",
    "sim://still?pace=fast&seed=1" + "0" * 40: "too large",
    "sim://still?pace=fast&block=0": "option block",
    "sim://still?pace=fast&jitter=-1": "option jitter",
    "sim://still?pace=fast&jitter=5": "option jitter",
    "sim://still?pace=fast&noise=-1": "option noise",
    "sim://still?pace=fast&rate=0": "option rate",
    "sim://still?pace=fast&rate=nan": "not a finite number",
    "sim://still?pace=fast&rate=1e9": "option rate",
    "sim://still?pace=fast&range=3": "not a MEMS range",
    "sim://still?pace=fast&seconds=nan": "not a finite number",
    "sim://still?pace=fast&seconds=-5": "option seconds",
    "sim://still?pace=fast&disconnect_after=0": "option disconnect_after",
    "sim://wheel?pace=fast&radius=280": "did you give millimetres",
    "sim://wheel?pace=fast&tilt_deg=400": "tilt_deg",
    "sim://rotary?pace=fast&frequency=0": "option frequency",
    "sim://slider-crank?pace=fast&radius=6.35": "did you give millimetres",
    "sim://static?pace=fast&hold=inf": "not a finite number",
    "serial-sim://still?pace=fast&drop=1.5": "option drop",
    "serial-sim://still?pace=fast&corrupt=-0.1": "option corrupt",
    "serial-sim://still?pace=fast&stall=0": "option stall",
    "ble-sim://still?pace=fast&reorder=2": "option reorder",
    "ble-sim://still?pace=fast&refuse_connects=-1": "option refuse_connects",
    "i2c-sim://mpu9250?pace=fast&rate_error=9": "option rate_error",
    "sim://still?pace=fast&seed=x": "not an integer",
}


@pytest.mark.parametrize("url", sorted(URL_CASES))
def test_implausible_url_options_are_refused(url, guarded, tmp_path):
    before = snapshot(tmp_path)
    assert_refused(guarded("record", url, "--samples", "50", "-o", tmp_path / "out.csv"), URL_CASES[url])
    assert snapshot(tmp_path) == before


@pytest.fixture
def still_csv(tmp_path, cli):
    path = tmp_path / "still.csv"
    assert cli("record", "sim://still?pace=fast&seed=1&seconds=2", "-o", path).returncode == 0
    return path


REPLAY_CASES = {
    "block=0": "option block",
    "block=-5": "option block",
    "loop=2": "option loop",
    "rate=0": "option rate",
}


@pytest.mark.parametrize("option", sorted(REPLAY_CASES))
def test_implausible_replay_options_are_refused(option, guarded, tmp_path, still_csv):
    before = snapshot(tmp_path)
    result = guarded("record", f"replay://{still_csv}?pace=fast&{option}", "--samples", "50",
                     "-o", tmp_path / "out.csv")
    assert_refused(result, REPLAY_CASES[option])
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize("flag, value, cause", [
    ("--seconds", "nan", "not a finite number"), ("--seconds", "inf", "not a finite number"),
    ("--seconds", "-1", "must be > 0"), ("--seconds", "1e12", "out of range"), ("--samples", "0", "must be >= 1"),
])
def test_implausible_record_lengths_are_refused(flag, value, cause, guarded, tmp_path):
    before = snapshot(tmp_path)
    assert_refused(guarded("record", "sim://still?pace=fast", flag, value, "-o", tmp_path / "o.csv"), cause)
    assert snapshot(tmp_path) == before


def test_a_g_off_earth_is_accepted_when_the_profile_says_why(guarded, tmp_path):
    """The band is the rule on Earth; a profile that states why its g lies outside (a centrifuge) passes."""
    path = tmp_path / "p.yaml"
    path.write_text(_profile_with(lambda d: d["calibration"].update(g=19.6, g_outside_earth="centrifuge at 2 g")))
    result = guarded("profile", "validate", path)
    assert result.returncode == 0, result.stderr


@pytest.mark.parametrize("argv, cause", [
    (("calibrate", "wheel", "{rec}", "--radius", "0.28", "--method", "paper", "--bootstrap", "1000000"),
     "--bootstrap 1e\\+06 is out of range: it must be >= 5 and <= 1000"),
    (("calibrate", "wheel", "{rec}", "--radius", "280"), "280 m is not a plausible distance .*millimetres"),
    (("calibrate", "wheel", "{rec}", "--radius", "0.28", "--g", "98.1"), "9.76-9.84"),
    (("calibrate", "static", "{rec}", "--g", "1"), "--g 1 m/s\\^2 is out of range"),
    (("calibrate", "static", "{rec}", "--g", "nan"), "not a finite number"),
    (("verify", "slider-crank", "{rec}", "--crank-radius", "6.35", "--rod-length", "0.0353"),
     "6.35 m is not a plausible caliper crank radius.*did you give millimetres"),
    (("verify", "slider-crank", "{rec}", "--crank-radius", "0.00635", "--rod-length", "35.3"),
     "35.3 m is not a plausible connecting rod length"),
    (("calibrate", "rotary", "--mems", "{rec}", "--radius", "170", "--tangential", "x", "--radial", "y",
      "--nominal-rate", "200"), "170 m is not a plausible sensor distance"),
])
def test_implausible_geometry_and_settings_are_refused_naming_the_unit(argv, cause, guarded, tmp_path, still_csv):
    before = snapshot(tmp_path)
    assert_refused(guarded(*(a.format(rec=still_csv) for a in argv)), cause)
    assert snapshot(tmp_path) == before


def _profile_with(change) -> str:
    profile = load_profile(EXAMPLE_PROFILE)
    change(profile.data)
    return dump_yaml(profile.data)


def _scale_c(factor):
    def change(data):
        corr = data["calibration"]["correction"]
        corr["matrix"] = (np.asarray(corr["matrix"]) * factor).tolist()
        cov = np.asarray(corr["covariance"]) * factor ** 2
        cov[9:, 9:] /= factor ** 2
        corr["covariance"] = cov.tolist()
        corr["matrix_uncertainty"] = np.sqrt(np.diag(cov)[:9]).reshape(3, 3).tolist()
    return change


def _not_psd(data):
    corr = data["calibration"]["correction"]
    cov = np.asarray(corr["covariance"])
    c = 5 * np.sqrt(cov[0, 0] * cov[1, 1])
    cov[0, 1] = cov[1, 0] = c
    corr["covariance"] = cov.tolist()


PROFILE_CASES = {
    "C = 1e300 I": (lambda d: d["calibration"]["correction"].update(matrix=(np.eye(3) * 1e300).tolist()),
                    "calibration.correction.matrix: gains"),
    "C = 0.01 I": (_scale_c(0.01), "gains .* outside the plausible 0.5 .. 2"),
    "C = 100 I": (_scale_c(100.0), "gains .* outside the plausible"),
    "covariance not PSD": (_not_psd, "not positive semi-definite"),
    "g = 1e300": (lambda d: d["calibration"].update(g=1e300), "calibration.g: .* beyond the full scale"),
    "g = 1e300 with a reason": (lambda d: d["calibration"].update(g=1e300, g_outside_earth="centrifuge"),
                                "calibration.g: .* other units"),
    "g = 9.7 with an empty reason": (lambda d: d["calibration"].update(g=9.7, g_outside_earth=""),
                                     "calibration.g_outside_earth"),
    "g = 9.7": (lambda d: d["calibration"].update(g=9.7), "calibration.g: .* not gravity on Earth.*g_outside_earth"),
    "g = 1": (lambda d: d["calibration"].update(g=1.0), "calibration.g"),
}


@pytest.mark.parametrize("case", sorted(PROFILE_CASES))
def test_implausible_profile_contents_are_refused(case, guarded, tmp_path):
    change, cause = PROFILE_CASES[case]
    path = tmp_path / "p.yaml"
    path.write_text(_profile_with(change))
    before = snapshot(tmp_path)
    assert_refused(guarded("profile", "validate", path), cause)
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize("argv, cause", [
    (("calibrate", "static", "{bare}", "--rate", "nan"), "--rate nan is not a finite number"),
    (("calibrate", "static", "{bare}", "--rate", "-200"), "--rate -200 Hz is out of range"),
    (("calibrate", "static", "{rec}", "--range-g", "nan"), "--range-g nan is not a finite number"),
    (("calibrate", "static", "{rec}", "--range-g", "0"), "--range-g 0 g is out of range"),
    (("profile", "show", "sim-random-11", "--max-age-days", "nan"), "--max-age-days nan is not a finite number"),
    (("profile", "show", "sim-random-11", "--date", "yesterday"), "'yesterday' is not a date"),
])
def test_implausible_flags_elsewhere_are_refused(argv, cause, guarded, tmp_path, still_csv):
    bare = tmp_path / "bare.csv"
    bare.write_text("ax,ay,az\n" + "0,0,9.81\n" * 50)
    store_args = ("--store", tmp_path / "store") if argv[0] == "profile" else ()
    if store_args:
        assert guarded("profile", "add", EXAMPLE_PROFILE, *store_args).returncode == 0
    before = snapshot(tmp_path)
    assert_refused(guarded(*(a.format(rec=still_csv, bare=bare) for a in argv), *store_args), cause)
    assert snapshot(tmp_path) == before
