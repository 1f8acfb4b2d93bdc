"""The wheel wizard end to end on sim://wheel, keyboard only: the saved profile matches the truth."""


import numpy as np

from accelrig.profiles import load_profile  # noqa: E402
from accelrig.tui.app import AccelrigApp  # noqa: E402
from accelrig.tui.screens.dialogs import PathScreen  # noqa: E402
from accelrig.tui.screens.results import ResultsScreen  # noqa: E402
from accelrig.tui.screens.wheel_wizard import WheelWizard  # noqa: E402
from tui_support import async_test, open_wizard, wait_for  # noqa: E402

DEVICE = "sim://wheel?seed=5&pace=fast&seconds=40&noise=0.05"


@async_test
async def test_wheel_wizard_to_saved_profile_matches_the_truth(tmp_path):
    app = AccelrigApp(device=DEVICE, refresh_interval=0.05, profile_dir=tmp_path)
    async with app.run_test(size=(80, 24)) as pilot:
        await open_wizard(pilot, "wheel")
        # neither radius nor tilt: refused while the form is open, saying one is needed
        await pilot.press("enter")
        assert "needs the radius or the tilt" in str(app.screen.query_one("#setup-status").render())
        # a bad radius is refused on the spot
        await pilot.press("x", "enter", "enter")
        assert "is not a number" in str(app.screen.query_one("#setup-status").render())
        await pilot.press("backspace", *"0.28", "enter", "enter")  # radius measured, tilt estimated
        await wait_for(pilot, lambda: isinstance(app.screen, ResultsScreen))
        wizard = app.screen_stack[-2]
        assert isinstance(wizard, WheelWizard)
        assert wizard.procedure.done and wizard.recorder.reader.lost_total == 0
        assert "turns, need" in str(wizard.query_one("#wheel-turns").render())
        assert "rad/s" in str(wizard.query_one("#wheel-speed").render())
        # the speed plot holds the procedure's trace: a coast-down over the run, one point per half turn
        (trace,) = wizard.query_one("#speed-plot").series
        times, speeds = wizard.procedure.speed_trace()
        assert np.array_equal(trace.x, times) and np.array_equal(trace.y, speeds)
        assert speeds.size >= 40 and times[-1] > 25.0
        assert np.polyfit(times, speeds, 1)[0] < 0 and speeds[-1] < 0.9 * speeds[0]
        results = app.screen
        # the method's cross-axis limit is said with the checks: the warnings hold only what this run showed
        assert "cross-axis" not in str(results.query_one("#results-warnings").render())
        assert "cross-axis:" in str(results.query_one("#results-checks").render())
        # each axis's row is named by its axis as the table draws it (a str cell was read as markup: "gain[x]"
        # showed as "gain", three times)
        from textual.widgets._data_table import default_cell_formatter

        table = results.query_one("#parameters")
        shown = [default_cell_formatter(table.get_row_at(i)[0]).plain for i in range(table.row_count)]
        assert shown[:6] == ["gain[x]", "gain[y]", "gain[z]", "offset[x]", "offset[y]", "offset[z]"]
        await wait_for(pilot, lambda: results.profile is not None)
        await pilot.press("s")
        await wait_for(pilot, lambda: isinstance(app.screen, PathScreen))
        await pilot.press("enter")
        path = tmp_path / "sim-random-5-wheel.yaml"
        await wait_for(pilot, lambda: path.exists())
        truth = app.session.info.truth["sensor"]

    parameters = load_profile(path).data["calibration"]["parameters"]
    for name in ("gain", "offset"):
        value = np.array(parameters[name]["value"])
        u = np.array(parameters[name]["uncertainty"])
        assert np.all(np.abs(value - np.array(truth[name])) < 4 * u), (name, value, truth[name], u)


@async_test
async def test_wheel_wizard_result_says_the_link_lost_samples(tmp_path):
    """The status line's drop count is gone once the results are up: heavy link loss must be in the result's
    warnings (and so in the profile), as every command line calibration says it."""
    app = AccelrigApp(device=DEVICE + "&drop=0.05&block=4", refresh_interval=0.05, profile_dir=tmp_path)
    async with app.run_test(size=(80, 24)) as pilot:
        await open_wizard(pilot, "wheel")
        await pilot.press(*"0.28", "enter", "enter")
        await wait_for(pilot, lambda: isinstance(app.screen, ResultsScreen), timeout=80)
        warnings = str(app.screen.query_one("#results-warnings").render())
        await wait_for(pilot, lambda: app.screen.profile is not None)
        profile_warnings = app.screen.profile.data["warnings"]
    assert "the link lost" in warnings and "check the cable or radio link" in warnings
    assert any("the link lost" in w for w in profile_warnings)
