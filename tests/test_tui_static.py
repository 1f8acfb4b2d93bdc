"""The static wizard end to end on a simulated rig, keyboard only: the saved profile matches the truth."""


from pathlib import Path

import numpy as np

from accelrig.profiles import load_profile  # noqa: E402
from accelrig.tui.app import AccelrigApp  # noqa: E402
from accelrig.tui.screens.calibrate import CalibrateMenu  # noqa: E402
from accelrig.tui.screens.dialogs import ConfirmScreen, PathScreen, SettingsForm  # noqa: E402
from accelrig.tui.screens.results import ResultsScreen  # noqa: E402
from accelrig.tui.screens.static_wizard import StaticWizard  # noqa: E402
from tui_support import async_test, choose, screen_lines, wait_for  # noqa: E402

DEVICE = "sim://static?seed=3&pace=fast"


def status(app):
    return str(app.screen.query_one("#results-status").render())


async def default_settings_to_results(app, pilot, timeout=90.0):
    """The operator's keys from the live view to the results: k, the first wizard (static), its settings as
    they are; the wizard computes on its own."""
    await wait_for(pilot, lambda: app.session is not None)
    await pilot.press("k")
    await wait_for(pilot, lambda: isinstance(pilot.app.screen, CalibrateMenu))   # enter goes to its list
    await pilot.press("enter")
    await wait_for(pilot, lambda: isinstance(app.screen, SettingsForm))
    await pilot.press("enter")
    await wait_for(pilot, lambda: isinstance(app.screen, ResultsScreen) and bool(app.screen.query("#results-warnings")),
                   timeout=timeout)   # pushed and composed (composing is slow on a loaded host)


@async_test
async def test_static_wizard_to_saved_profile_matches_the_truth(tmp_path):
    app = AccelrigApp(device=DEVICE, refresh_interval=0.05, profile_dir=tmp_path)
    async with app.run_test(size=(80, 24)) as pilot:
        await wait_for(pilot, lambda: app.session is not None)
        await pilot.press("k")
        await wait_for(pilot, lambda: isinstance(app.screen, CalibrateMenu))   # enter goes to its list
        await pilot.press("enter")  # the first wizard: static
        await wait_for(pilot, lambda: isinstance(app.screen, SettingsForm))
        assert app.screen.field("g").placeholder == "9.80665"   # a blank field takes the default shown
        assert app.screen.field("latitude").placeholder == "e.g. 48.1"   # an example, not a default
        await pilot.press("enter")  # the settings as they are: the defaults
        await wait_for(pilot, lambda: isinstance(app.screen, ResultsScreen))
        wizard = app.screen_stack[-2]
        assert isinstance(wizard, StaticWizard)
        assert wizard.procedure.faces_done == ["+x", "-x", "+y", "-y", "+z", "-z"]
        # computed on its own after the drift check's three rounds: fifteen holds
        assert wizard.procedure.complete and wizard.procedure.faces["n_poses"] == 15
        grid = {face: str(wizard.query_one(f"#face-{face.replace('+', 'p').replace('-', 'm')}").render())
                for face in ("+z", "-z")}
        assert "✓✓✓ done" in grid["+z"] and "✓✓ done" in grid["-z"]   # held three times; its opposite twice
        assert "holds 15 of 15" in str(wizard.query_one("#pose-state").render())
        # the opposite faces and the last round were asked for with their reasons, each in one line of the log
        logged = " ".join(" ".join(line.text.split()) for line in wizard.query_one("#events").lines)
        assert ("drift check, round 2 of 3: now put -z, -x and -y down once more (the opposite faces), so the "
                "fit can test the drift between the holds") in logged
        assert ("drift check, last round: now put +z, +x and +y down a third time, so their holds, spread over "
                "the run, show the drift's shape") in logged
        assert wizard.recorder.reader.lost_total == 0
        results = app.screen
        await wait_for(pilot, lambda: bool(results.query("#results-warnings")))   # composed (as in the helper above)
        assert "drift not checked" not in str(results.query_one("#results-warnings").render())
        await wait_for(pilot, lambda: results.profile is not None)
        assert results.query_one("#parameters").row_count == len(results.result.parameters)

        await pilot.press("s")
        await wait_for(pilot, lambda: isinstance(app.screen, PathScreen))
        await pilot.press("enter")
        path = tmp_path / "sim-random-3-static.yaml"
        await wait_for(pilot, lambda: "profile saved" in status(app))
        assert path.exists()

        # saving again asks before overwriting; "keep it" writes nothing
        before = path.read_text()
        await pilot.press("s")
        await wait_for(pilot, lambda: isinstance(app.screen, PathScreen))
        await pilot.press("enter")
        await wait_for(pilot, lambda: isinstance(app.screen, ConfirmScreen))
        await pilot.press("n")
        await wait_for(pilot, lambda: "kept as it was" in status(app))
        assert path.read_text() == before

        # a simulated device cannot store a calibration: flash is not offered
        assert results.check_action("flash", ()) is False and "f flashes" not in status(app)

        truth = app.session.info.truth["sensor"]["correction"]

        # back in the wizard: the scripted source has ended, so a face cannot be taken again. The wizard
        # says so at once (rather than wait for samples that never come) and drops nothing
        await pilot.press("escape")
        assert app.screen is wizard
        await pilot.press("r")
        await wait_for(pilot, lambda: "source has ended" in str(wizard.query_one("#instruction").render()))
        assert wizard.procedure.faces_done == ["+x", "-x", "+y", "-y", "+z", "-z"]

    profile = load_profile(path)
    corr = profile.correction
    z_matrix = (corr.matrix - np.array(truth["matrix"])) / corr.matrix_uncertainty
    z_bias = (corr.bias - np.array(truth["bias"])) / corr.bias_uncertainty
    # within the procedure's stated (k = 1) uncertainty: |z| < 4 for all 12 parameters
    assert np.all(np.abs(z_matrix) < 4), z_matrix
    assert np.all(np.abs(z_bias) < 4), z_bias
    assert profile.device["identity"] == "sim-random-3"
    assert profile.data["provenance"]["recording_samples"] > 4000


@async_test
async def test_static_through_an_emulated_chip_then_flash_shows_the_plan_and_asks(tmp_path):
    """i2c-sim: the real I2C driver over a register-level MPU-9250 emulator; the flash is real."""
    app = AccelrigApp(device="i2c-sim://mpu9250?rig=static&pace=fast&rate=200&seed=3", refresh_interval=0.05,
                      profile_dir=tmp_path)
    async with app.run_test(size=(80, 24)) as pilot:
        # nine holds through the emulated bus (six faces, three again): slower than the plain simulator
        await default_settings_to_results(app, pilot, timeout=90)
        results = app.screen
        await wait_for(pilot, lambda: results.profile is not None)
        # the footer names every key at 80 columns, flash included ("q Quit" was cut to "q Qu"); drawn after the
        # screen (under load a dialog's footer was still blank when the dialog was up)
        await wait_for(pilot, lambda: "Help" in screen_lines(app)[-1])
        assert screen_lines(app)[-1].rstrip().endswith("f Flash n Next plot c Certificate esc Close ? Help q Quit")
        before = app.session.driver.chip.read_offset_words()   # the factory trim
        await pilot.press("f")
        await choose(pilot, "flash")   # the profile is not saved: flash it without saving
        await wait_for(pilot, lambda: isinstance(app.screen, ConfirmScreen))
        assert not app._notifications, "a notification lies over the plan while it asks"
        plan = str(app.screen.query_one("#details-text").render())
        assert "Flash plan for" in plan and "OFFSET" in plan.upper()
        assert "Write to the device?" in str(app.screen.query_one("#question").render())
        await pilot.press("n")  # cancel: nothing written
        await wait_for(pilot, lambda: "nothing was written" in status(app) and "streaming again" in status(app))
        assert app.session.driver.chip.read_offset_words() == before
        # saved, then flashed: the chip's offsets are volatile, so the stream opens again with profile=PATH,
        # which writes them on this open and every later one
        await pilot.press("s")
        await wait_for(pilot, lambda: isinstance(app.screen, PathScreen))
        await pilot.press("enter")
        await wait_for(pilot, lambda: "profile saved" in status(app))
        await pilot.press("f")
        await wait_for(pilot, lambda: isinstance(app.screen, ConfirmScreen))
        await pilot.press("y")
        await wait_for(pilot, lambda: "streaming again" in status(app))
        assert "written and verified" in status(app)
        assert f"profile={results.saved_path}" in app.session.url
        assert app.session.driver.chip.read_offset_words() != before


@async_test
async def test_a_source_that_ends_after_six_faces_computes_without_the_drift_check_and_the_results_say_so(tmp_path):
    # the scripted rig holds each face once and ends: with six faces in and nothing more to come, the wizard
    # computes (live it would wait for the drift check, or c) and the results screen shows the warning first
    app = AccelrigApp(device="sim://static?seed=4&pace=fast&order=+z,-z,+x,-x,+y,-y&hold=3", refresh_interval=0.05,
                      profile_dir=tmp_path)
    async with app.run_test(size=(80, 24)) as pilot:
        await default_settings_to_results(app, pilot, timeout=90)
        wizard = app.screen_stack[-2]
        assert wizard.procedure.done and not wizard.procedure.complete and wizard.source_ended
        shown = str(app.screen.query_one("#results-warnings").render())
        assert "offset drift not checked along x, y and z" in shown


@async_test
async def test_results_read_their_checks_and_a_second_save_offers_the_first_file():
    """The results say what u holds and whether the model fits in sentences, name the parameters' form, show
    angles in degrees; a second s offers the file saved first (replaced after asking), not a new name."""
    from textual.widgets import Input

    from accelrig.acquisition.driver import driver_for
    from accelrig.acquisition.recorder import record
    from accelrig.procedures.static.procedure import calibrate_static

    # twelve holds (an older wizard's file: three faces three times, their opposites once): every degree of
    # freedom is taken
    with driver_for(DEVICE + "&order=+z,-z,+x,-x,+y,-y,+z,+x,+y,+z,+x,+y") as driver:
        recording = record(driver)
    result = calibrate_static(recording)
    app = AccelrigApp(device="sim://still?seed=1&pace=fast&seconds=2", refresh_interval=0.05)
    async with app.run_test(size=(120, 40)) as pilot:
        await wait_for(pilot, lambda: app.session is not None)
        app.push_screen(ResultsScreen(result, recording, None))
        await wait_for(pilot, lambda: isinstance(app.screen, ResultsScreen) and app.screen.profile is not None)
        results = app.screen
        checks = str(results.query_one("#results-checks").render())
        assert "uncertainty:" in checks and "lack of fit:" in checks and "gravity: g = 9.80665" in checks
        assert "pose tilts:" in checks and "within it" in checks   # the six-face model's own test of fit
        # twelve numbers from twelve holds: no chi-square p, and the raw figures say so rather than "nan"
        quality = str(results.query_one("#quality").render())
        assert "p_value not computed" in quality and "nan" not in quality
        assert "calibrated = G R(angle) raw + c" in str(results.query_one("#parameters-title").render())
        table = results.query_one("#parameters")
        angle_row = table.get_row_at(0)
        assert angle_row[0] == "angle_x" and angle_row[3] == "deg"
        # rounded with its u (GUM 7.2.6: u to two significant digits, the value to the same digit)
        assert abs(float(angle_row[1]) - np.degrees(result.parameters["angle_x"].value)) <= 0.005 + 1e-9
        assert float(angle_row[2]) == float(f"{np.degrees(result.parameters['angle_x'].uncertainty):.2g}")
        # every pose found, as the text report lists them
        poses = results.query_one("#poses")
        assert poses.row_count == len(result.details["poses"]) and poses.get_row_at(0)[6] == "used"

        await pilot.press("s")
        await wait_for(pilot, lambda: isinstance(app.screen, PathScreen))
        first = app.screen.query_one(Input).value
        await pilot.press("enter")
        await wait_for(pilot, lambda: "profile saved" in status(app))
        await pilot.press("s")
        await wait_for(pilot, lambda: isinstance(app.screen, PathScreen))
        assert app.screen.query_one(Input).value == first
        await pilot.press("enter")
        await wait_for(pilot, lambda: isinstance(app.screen, ConfirmScreen))
        await pilot.press("y")
        await wait_for(pilot, lambda: "profile saved" in status(app))
    saved = list(Path(first).parent.glob("*.yaml"))
    assert saved == [Path(first)]
