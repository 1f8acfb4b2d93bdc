"""The one saturation rule: int16 rails within one count, in counts and in m/s^2."""

import numpy as np

from accelrig.units import COUNT_MAX, COUNT_MIN, SATURATION_MARGIN, saturated, scale_for_range


def test_both_rails_and_one_count_inside_them_are_saturated():
    counts = np.array([COUNT_MIN, -32767, -32766, 0, 32765, 32766, COUNT_MAX], dtype=np.int16)
    assert SATURATION_MARGIN == 1
    assert saturated(counts).tolist() == [True, True, False, False, False, True, True]


def test_m_s2_with_a_known_scale_follow_the_same_rule():
    scale = scale_for_range(8.0)
    counts = np.array([[COUNT_MIN, 0, 12], [-32767, 5, 0], [-32766, 0, 0], [32766, 0, 0], [COUNT_MAX, 0, 0]])
    flags = saturated(counts * scale, scale)
    assert flags.shape == counts.shape
    np.testing.assert_array_equal(flags, saturated(counts))
    assert flags.any(axis=1).tolist() == [True, True, False, True, True]


def test_a_margin_can_be_stated():
    assert saturated(np.array([32760, -32761]), margin=7).tolist() == [True, True]
    assert saturated(np.array([32760, -32761]), margin=6).tolist() == [False, False]


def test_local_gravity_joins_what_the_procedure_says_u_holds_under_its_own_key():
    """The wheel says what u holds under quality.uncertainty, static under uncertainty_source: u(g) is
    appended to that one sentence (it once went to a second key the wheel's report never showed)."""
    from accelrig.result import CalibrationResult, Correction
    from accelrig.units import LocalGravity

    gravity = LocalGravity(9.80665, 0.015, "standard gravity")
    for key in ("uncertainty", "uncertainty_source"):
        result = CalibrationResult("p", "m", "model", Correction.identity(), {}, quality={key: "white noise"})
        result.with_local_gravity(gravity)
        assert list(result.quality) == [key]
        assert result.quality[key].startswith("white noise; + local gravity u(g) 0.015")
        assert np.allclose(result.correction.matrix_uncertainty, np.eye(3) * 0.015 / 9.80665)


def test_local_gravity_enters_the_parameters_that_scale_with_it():
    """The wheel's gains (g is their reference) and radius (read in the gains' scale) carry u(g) too, fully
    correlated and in opposite directions; the others do not."""
    from accelrig.result import CalibrationResult, Correction, Estimate
    from accelrig.units import LocalGravity

    params = {"gain": Estimate([2.0, 1.0, 0.5], [0.0, 0.0, 0.0], "1"), "radius": Estimate(0.1, 0.0, "m"),
              "offset": Estimate([0.1, 0.2, 0.3], [0.01, 0.01, 0.01], "m/s^2")}
    names = ["radius", "gain_x", "gain_y", "gain_z", "offset_x"]
    result = CalibrationResult("wheel", "joint", "m", Correction.identity(), params, covariance=np.zeros((5, 5)),
                               parameter_names=names)
    result.with_local_gravity(LocalGravity(9.8, 0.0098, "test"), {"gain": 1, "radius": -1})
    assert np.allclose(result.parameters["gain"].uncertainty, [2e-3, 1e-3, 5e-4])
    assert np.isclose(result.parameters["radius"].uncertainty, 1e-4)
    assert result.parameters["offset"].uncertainty == [0.01, 0.01, 0.01]
    cov = result.covariance
    assert np.isclose(cov[1, 1], 4e-6) and np.isclose(cov[0, 1], -2e-7) and cov[4, 4] == 0.0


def test_a_g_typed_with_many_digits_keeps_its_rule_but_warns_how_to_state_u():
    """--g 9.81744 gives u(g) 2.9e-6 by the documented rule (its rounding as typed): 300 times below what a g
    has without a survey, so the gains' u drops 10x and such a device dominates a batch's mean. Said."""
    from accelrig.result import CalibrationResult, Correction
    from accelrig.units import NORMAL_GRAVITY_U, local_gravity

    typed = local_gravity(9.81744)
    assert typed.u == 0.5e-5 / 3**0.5 and typed.u < NORMAL_GRAVITY_U   # the rule stays
    result = CalibrationResult("p", "m", "model", Correction.identity(), {}).with_local_gravity(typed)
    (warning,) = result.warnings
    assert "9.81744 as typed" in warning and "--g-u" in warning and "without a survey" in warning
    # u(g) stated, a coarse g, the formula or standard gravity: nothing to say
    for honest in (local_gravity(9.81744, g_u=1e-5), local_gravity(9.81), local_gravity(latitude=48.0),
                   local_gravity()):
        assert honest.warning is None
