"""A first-time operator's safety nets, with Pilot: a device of the wrong kind, quitting with unsaved data,
the setup forms remembered between runs."""

import yaml

from accelrig.tui.app import AccelrigApp, settings_file
from accelrig.tui.rigs import NEEDS
from accelrig.tui.screens.calibrate import CalibrateMenu
from accelrig.tui.screens.connect import ConnectScreen
from accelrig.tui.screens.dialogs import ChoiceScreen, ConfirmScreen, PathScreen, SettingsForm
from test_tui_wizard import MeanWizard
from tui_support import async_test, wait_for


async def pick(pilot, options, key):
    options.highlighted = [options.get_option_at_index(i).id for i in range(options.option_count)].index(key)
    await pilot.press("enter")


@async_test
async def test_a_wheel_wizard_on_a_static_rig_says_so_and_offers_the_simulated_wheel():
    app = AccelrigApp(device="sim://static?seed=1&pace=fast", refresh_interval=0.05)
    async with app.run_test(size=(80, 24)) as pilot:
        await wait_for(pilot, lambda: app.session is not None)
        await pilot.press("k")
        await wait_for(pilot, lambda: isinstance(app.screen, CalibrateMenu))
        await pick(pilot, app.screen.query_one("#wizards"), "wheel")
        await wait_for(pilot, lambda: isinstance(app.screen, ChoiceScreen))
        assert "simulated static rig: it lacks rotation" in str(app.screen.query_one("#question").render())
        # the connect list puts what fits the wheel first: its simulated rig, then emulated chips on a wheel
        await pick(pilot, app.screen.query_one("#choices"), "connect")
        await wait_for(pilot, lambda: isinstance(app.screen, ConnectScreen))
        found = app.screen.query_one("#found")
        await wait_for(pilot, lambda: found.option_count > 3)
        ids = [found.get_option_at_index(i).id for i in range(found.option_count)]
        assert ids[0] == NEEDS["wheel"].demo_url and "i2c-sim://mpu9250?rig=wheel" in ids[:4]
        await pilot.press("escape")   # nothing picked: asked again
        await wait_for(pilot, lambda: isinstance(app.screen, ChoiceScreen))
        await pick(pilot, app.screen.query_one("#choices"), "demo")
        await wait_for(pilot, lambda: isinstance(app.screen, SettingsForm))
        assert app.session.url == NEEDS["wheel"].demo_url
        assert app.screen.field("radius").value == "0.28"   # settings that fit the simulated wheel
        await pilot.press("escape")


@async_test
async def test_quitting_with_unsaved_captures_asks_and_after_writing_does_not(tmp_path):
    # a source that ends soon: the app falls idle, so Pilot's key presses stay quick
    app = AccelrigApp(device="sim://still?seed=4&pace=fast&seconds=5", refresh_interval=0.05, profile_dir=tmp_path)
    async with app.run_test(size=(80, 24)) as pilot:
        await wait_for(pilot, lambda: app.session is not None)
        wizard = MeanWizard(app.session, values={"seconds": 600, "label": "sensor"})
        app.push_screen(wizard)
        await wait_for(pilot, lambda: wizard.recorder is not None and wizard.recorder.samples > 500)
        for key in ("q", "ctrl+q"):
            await pilot.press(key)
            await wait_for(pilot, lambda: isinstance(app.screen, ConfirmScreen))
            question = str(app.screen.query_one("#question").render())
            assert "are not written" in question and f"on disk in {wizard.capture_path}" in question
            await pilot.press("n")   # stay: nothing lost
            await wait_for(pilot, lambda: app.screen is wizard)
        assert app.return_code is None
        await wait_for(pilot, lambda: wizard.source_ended)   # no more samples: the file will hold them all
        await pilot.press("w")
        await wait_for(pilot, lambda: isinstance(app.screen, PathScreen))
        await pilot.press("enter")
        await wait_for(pilot, lambda: wizard.written_samples == wizard.recorder.samples > 500)
        assert (tmp_path / "mean-capture.csv").exists()
        await pilot.press("q")
        await wait_for(pilot, lambda: app.return_code is not None)
    # quitting finished the capture's segments: none is left open (an open one is only for a crash)
    assert wizard.capture_path is not None and any(wizard.capture_path.iterdir())
    assert not list(wizard.capture_path.glob("*.seg")), list(wizard.capture_path.iterdir())


@async_test
async def test_the_setup_form_is_remembered_in_the_accelrig_home_between_runs():
    for run in range(2):
        app = AccelrigApp(device="sim://still?seed=6&pace=fast&seconds=1", refresh_interval=0.05)
        async with app.run_test(size=(80, 24)) as pilot:
            await wait_for(pilot, lambda app=app: app.session is not None)
            app.push_screen(MeanWizard(app.session))
            await wait_for(pilot, lambda app=app: isinstance(app.screen, SettingsForm))
            if run == 0:
                await pilot.press(*"42", "down", *"bench", "enter")
                await wait_for(pilot, lambda: settings_file().exists())
            else:
                assert app.screen.field("seconds").value == "42" and app.screen.field("label").value == "bench"
                await pilot.press("escape")
    assert yaml.safe_load(settings_file().read_text())["mean"] == {"seconds": "42", "label": "bench"}
