"""One rounding convention on every face (accelrig.result.format_value): a value beside its u is rounded with
it, a count is an integer. The places a first-time user found printing their own way."""

from types import SimpleNamespace

import numpy as np

from accelrig.result import CalibrationResult, Correction, format_value


def test_profile_show_rounds_a_value_with_its_u():
    from accelrig.commands.profile import _fmt

    assert _fmt(0.987265, 0.0016) == "0.9873 +- 0.0016"            # was "0.987265 +- 0.0016"
    assert _fmt([0.987265, -0.32], [0.0016, 0.00051]) == "[0.9873 +- 0.0016, -0.32000 +- 0.00051]"


def test_noise_table_rounds_each_figure_with_its_u():
    from accelrig.commands.noise import UG, noise_table
    from accelrig.result import Estimate

    density = Estimate(213.2 / UG, 22.4 / UG, "(m/s^2)/sqrt(Hz)")
    axis = SimpleNamespace(density=density, bias_instability=None, random_walk=None, notes=[])
    report = SimpleNamespace(n_samples=11000, duration=55.0, rate=200.0, still_segment=None,
                             axes={a: axis for a in "xyz"})
    table = noise_table(report)
    assert " 213 +- 22 " in table and "213.2 +- 22.4" not in table
    assert " +- ".join(format_value(density.value, density.uncertainty)) in table


def test_flash_plan_says_numbers_without_a_u_to_six_digits():
    from accelrig.acquisition.flash import FlashPlan
    from accelrig.profiles.flash import format_plan

    plan = FlashPlan("dev", residual={"bias_remaining_m_s2": [-0.0020423482931097026, 0.5],
                                      "register_step_m_s2": 0.009576806640625, "meaning": "words"})
    text = format_plan(plan)
    assert "[-0.00204235, 0.5]" in text and "0.00957681" in text and "0.0020423482931" not in text


def test_results_screen_prints_a_count_as_an_integer():
    from accelrig.tui.screens.results import ResultsScreen

    result = CalibrationResult("static", "lm", "m", Correction.identity(), {},
                               quality={"n_samples": 11177, "chi2": 3.2591, "n_poses": np.int64(15)})
    text = ResultsScreen.quality_text(SimpleNamespace(result=result))
    assert "n_samples 11177" in text and "n_poses 15" in text and "chi2 3.259" in text   # was "1.118e+04"
