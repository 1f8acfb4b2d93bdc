"""The static wizard's any-orientation flow (multi-position) end to end on sim://static?orientations=N."""

import numpy as np

from accelrig.estimation.gravity_fit import MULTI_MIN_DISTINCT, upper_gauge
from accelrig.tui.app import AccelrigApp
from accelrig.tui.screens.calibrate import CalibrateMenu
from accelrig.tui.screens.dialogs import SettingsForm
from accelrig.tui.screens.results import ResultsScreen
from accelrig.tui.screens.static_wizard import StaticWizard
from tui_support import async_test, wait_for

DEVICE = "sim://static?orientations=12&hold=3&seed=4&pace=fast"


@async_test
async def test_any_orientation_counts_distinct_orientations_maps_them_and_fits_multi_position():
    app = AccelrigApp(device=DEVICE, refresh_interval=0.05)
    async with app.run_test(size=(100, 40)) as pilot:
        await wait_for(pilot, lambda: app.session is not None)
        await pilot.press("k")
        await wait_for(pilot, lambda: isinstance(pilot.app.screen, CalibrateMenu))   # enter goes to its list
        await pilot.press("enter")
        await wait_for(pilot, lambda: isinstance(app.screen, SettingsForm))
        form = app.screen
        form.field("model").value = "multi-position"   # "hold it still in any orientation"
        assert "any orientation" in str(form.query(".setting-label").first().render())
        await pilot.press("enter")
        await wait_for(pilot, lambda: isinstance(app.screen, ResultsScreen))
        wizard = app.screen_stack[-2]
        assert isinstance(wizard, StaticWizard) and wizard.procedure.any_orientation
        assert not wizard.query_one("#faces").display and wizard.query_one("#sphere").display
        orientations = wizard.procedure.orientations
        assert orientations["n_distinct"] >= MULTI_MIN_DISTINCT and orientations["more"] == 0
        sphere = str(wizard.query_one("#sphere").render())
        assert f"distinct orientations {orientations['n_distinct']}, 9 needed (enough" in sphere
        assert sphere.count("●") + sphere.count("◉") >= 1 and "+z up" in sphere
        # the scripted rig ended before the 12 asked: the line under the map no longer asks to turn the sensor
        assert wizard.source_ended
        await wait_for(pilot, lambda: "the source ended: no more poses will come" in str(
            wizard.query_one("#pose-state").render()))
        assert "turn it" not in str(wizard.query_one("#pose-state").render())
        log = "\n".join(line.text for line in wizard.query_one("#events").lines)
        assert "1 distinct orientation, 8 more needed" in log and "faces" not in log
        result = app.screen.result
        assert result.model == "multi-position"
        truth = app.session.info.truth["sensor"]["correction"]

    corr = result.correction
    c_true = upper_gauge(np.array(truth["matrix"]))
    free = np.triu_indices(3)
    z_c = (corr.matrix - c_true)[free] / corr.matrix_uncertainty[free]
    z_b = (corr.bias - np.array(truth["bias"])) / corr.bias_uncertainty
    assert np.all(np.abs(z_c) < 4), z_c
    assert np.all(np.abs(z_b) < 4), z_b


@async_test
async def test_any_orientation_before_enough_says_how_many_more():
    app = AccelrigApp(device="sim://static?orientations=4&hold=3&seed=5&pace=fast", refresh_interval=0.05)
    async with app.run_test(size=(100, 40)) as pilot:
        await wait_for(pilot, lambda: app.session is not None)
        await pilot.press("k")
        await wait_for(pilot, lambda: isinstance(pilot.app.screen, CalibrateMenu))   # enter goes to its list
        await pilot.press("enter")
        await wait_for(pilot, lambda: isinstance(app.screen, SettingsForm))
        app.screen.field("model").value = "multi-position"
        await pilot.press("enter")
        await wait_for(pilot, lambda: isinstance(app.screen, StaticWizard) and app.screen.source_ended)
        wizard = app.screen
        await wait_for(pilot, lambda: wizard.procedure.orientations["n_poses"] == 4)
        await pilot.press("c")
        text = str(wizard.query_one("#instruction").render())
        assert "4 distinct orientations: 5 more needed" in text
        assert "5 more needed" in str(wizard.query_one("#sphere").render())


@async_test
async def test_multi_position_on_the_six_face_rig_offers_the_rig_that_has_the_orientations():
    """sim://static plays six faces (6 distinct orientations of the 9 needed): multi-position there would end
    in 'the source ended'; the wizard says so before it starts and offers the any-orientation rig."""
    from accelrig.tui.rigs import ORIENTATIONS_DEMO_URL
    from accelrig.tui.screens.dialogs import ChoiceScreen

    app = AccelrigApp(device="sim://static?seed=5&pace=fast", refresh_interval=0.05)
    async with app.run_test(size=(80, 24)) as pilot:
        await wait_for(pilot, lambda: app.session is not None)
        await pilot.press("k")
        await wait_for(pilot, lambda: isinstance(pilot.app.screen, CalibrateMenu))   # enter goes to its list
        await pilot.press("enter")
        await wait_for(pilot, lambda: isinstance(app.screen, SettingsForm))
        app.screen.field("model").value = "multi-position"
        await pilot.press("enter")
        await wait_for(pilot, lambda: isinstance(app.screen, ChoiceScreen))
        assert "6 distinct orientations" in str(app.screen.query_one("#question").render())
        options = app.screen.query_one("#choices")
        assert options.get_option_at_index(0).id == "demo"
        options.highlighted = 0
        await pilot.press("enter")
        await wait_for(pilot, lambda: isinstance(app.screen, ResultsScreen))   # the rig plays fast
        wizard = app.screen_stack[-2]
        assert isinstance(wizard, StaticWizard) and wizard.url == ORIENTATIONS_DEMO_URL
        assert wizard.sub_title == "multi-position static calibration"
        assert wizard.check_action("procedure_action", ("redo",)) is False   # no face to redo: not in the keys
        assert app.screen.result.model == "multi-position"
