"""Settings declared once: the same value means the same and is refused with the same words everywhere."""

import argparse

import pytest

from accelrig.errors import DataError
from accelrig.settings import REQUIRED, Setting, add_arguments, values_from_args, values_from_texts

RADIUS = Setting("crank_radius", "caliper crank radius", unit="m", default=REQUIRED, low=1e-4, high=1.0,
                 hint="give it in metres")
STEPS = Setting("steps", "motor speed steps", unit="Hz", kind="floats", default=(2.5, 4.0), low=0, low_open=True)
MODEL = Setting("model", "model", kind="choice", choices=("paper", "affine", "auto"), default="auto")
SETTINGS = (RADIUS, STEPS, MODEL)


def test_flags_and_form_parse_alike():
    parser = argparse.ArgumentParser()
    add_arguments(parser, SETTINGS)
    args = parser.parse_args(["--crank-radius", "0.00635", "--steps", "3,6"])
    assert values_from_args(SETTINGS, args) == {"crank_radius": 0.00635, "steps": [3.0, 6.0], "model": "auto"}
    assert values_from_texts(SETTINGS, {"crank_radius": "0.00635", "steps": "3 6", "model": ""}) == {
        "crank_radius": 0.00635, "steps": [3.0, 6.0], "model": "auto"}


def test_refusals_name_the_field_the_unit_and_what_to_do():
    with pytest.raises(DataError, match=r"--crank-radius 6.35 m is not a plausible caliper crank radius \(at most 1 m\): "
                       r"did you give millimetres\? \(give it in metres\)"):
        RADIUS.parse("6.35")
    with pytest.raises(DataError, match=r"--crank-radius 6000 m is out of range: it must be >= 0.0001 and <= 1 m"):
        RADIUS.parse("6000")   # not millimetres either
    with pytest.raises(DataError, match="caliper crank radius 'abc' is not a number"):
        values_from_texts(SETTINGS, {"crank_radius": "abc"})
    with pytest.raises(DataError, match="--crank-radius is needed"):
        RADIUS.parse("")
    with pytest.raises(DataError, match="must be > 0 Hz"):
        STEPS.parse("2,0")
    with pytest.raises(DataError, match="not a finite number"):
        RADIUS.parse("nan")
    with pytest.raises(DataError, match="not one of paper, affine, auto"):
        MODEL.parse("cubic")


def test_help_shows_unit_choices_and_default():
    assert STEPS.describe() == "motor speed steps (Hz; default 2.5,4)"
    assert MODEL.describe() == "model (paper|affine|auto; default auto)"
    assert RADIUS.describe() == "caliper crank radius (m; required)"


def test_shared_gravity_setting_defaults_to_standard_gravity_and_refuses_implausible_values():
    from accelrig.settings import GRAVITY
    from accelrig.units import STANDARD_GRAVITY

    assert GRAVITY.default == STANDARD_GRAVITY and GRAVITY.parse("") == STANDARD_GRAVITY
    with pytest.raises(DataError, match=r"--g 98.1 m/s\^2 is out of range: it must be >= 9.76 and <= 9.84 m/s\^2 "
                       r"\(Earth's gravity lies within 9.76-9.84 m/s\^2; give it in m/s\^2, e.g. 9.81\)"):
        GRAVITY.parse("98.1")


def test_a_percent_sign_in_help_reaches_argparse_intact():
    parser = argparse.ArgumentParser()
    add_arguments(parser, (Setting("sd", "prior sd, the datasheet +-2 % as a uniform bound"),))
    assert "+-2 % as a uniform bound" in parser.format_help()
