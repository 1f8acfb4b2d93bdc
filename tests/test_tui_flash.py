"""f on the results flashes firmware devices (serial, BLE) as `accelrig flash` does: the stream stops, the device
is opened afresh, the plan is shown and asked, written and read back, and the stream opens again."""

import numpy as np
import pytest

from accelrig.acquisition.session import State
from accelrig.result import CalibrationResult, Correction
from accelrig.tui.app import AccelrigApp
from accelrig.tui.screens.dialogs import ChoiceScreen, ConfirmScreen, PathScreen
from accelrig.tui.screens.results import ResultsScreen
from tui_support import async_test, choose, wait_for


def small_result() -> CalibrationResult:
    """A result with a small correction, standing in for a wizard's (the flash needs only its correction)."""
    rng = np.random.default_rng(5)
    correction = Correction(np.eye(3) + rng.normal(0, 0.01, (3, 3)), rng.normal(0, 0.1, 3),
                            np.diag(rng.uniform(1e-8, 1e-6, 12)))
    return CalibrationResult("static", "test", "C (raw - b)", correction, {}, quality={"residual_rms": 0.03})


def status(app) -> str:
    return str(app.screen.query_one("#results-status").render())


# real-time sources that run on for as long as the test takes: the stream cannot end under the test's keys
@pytest.mark.parametrize("url", ["ble-sim://still?seed=3", "serial-sim://still?seed=5"])
@async_test
async def test_flash_from_the_results_stops_the_stream_flashes_a_fresh_open_and_streams_again(tmp_path, url):
    app = AccelrigApp(device=url, refresh_interval=0.05, profile_dir=tmp_path)
    async with app.run_test(size=(80, 24)) as pilot:
        await wait_for(pilot, lambda: app.session is not None and app.session.stats().samples > 0)
        streaming = app.session
        app.push_screen(ResultsScreen(small_result(), None, streaming))
        await wait_for(pilot, lambda: isinstance(app.screen, ResultsScreen) and app.screen.profile is not None)
        results = app.screen
        assert results.check_action("flash", ()) is True

        # the profile is not saved: asked first; saved, then the flash goes on
        await pilot.press("f")
        await choose(pilot, "save")
        await wait_for(pilot, lambda: isinstance(app.screen, PathScreen))
        await pilot.press("enter")
        # the stream stopped for a fresh open: the plan is read from it and shown before anything is written
        await wait_for(pilot, lambda: isinstance(app.screen, ConfirmScreen), timeout=60)
        assert results.saved_path is not None and results.saved_path.exists()
        assert streaming.stats().state == State.STOPPED
        plan = str(app.screen.query_one("#details-text").render())
        assert "Flash plan for" in plan and "record: matrix row x" in plan
        await pilot.press("y")
        await wait_for(pilot, lambda: "streaming again" in status(app), timeout=60)
        assert "written and verified" in status(app), status(app)
        assert "cannot flash" not in status(app)
        # the stream is open again: a new session, delivering
        assert app.session is not streaming and results.session is app.session
        await wait_for(pilot, lambda: app.session.stats().samples > 0)
        assert app.session.stats().state == State.STREAMING

        # a second f plans from the device as it is now: it holds the record just written; cancel writes nothing
        await pilot.press("f")
        await wait_for(pilot, lambda: isinstance(app.screen, ConfirmScreen), timeout=60)
        await pilot.press("n")
        await wait_for(pilot, lambda: "streaming again" in status(app) and "nothing was written" in status(app),
                       timeout=60)


@async_test
async def test_flash_can_be_declined_before_the_stream_stops(tmp_path):
    app = AccelrigApp(device="serial-sim://still?seed=5", refresh_interval=0.05, profile_dir=tmp_path)
    async with app.run_test(size=(80, 24)) as pilot:
        await wait_for(pilot, lambda: app.session is not None)
        streaming = app.session
        app.push_screen(ResultsScreen(small_result(), None, streaming))
        await wait_for(pilot, lambda: isinstance(app.screen, ResultsScreen) and app.screen.profile is not None)
        await pilot.press("f")
        await wait_for(pilot, lambda: isinstance(app.screen, ChoiceScreen))
        await choose(pilot, "stay")
        await wait_for(pilot, lambda: "not flashed" in status(app))
        assert app.session is streaming and streaming.stats().state == State.STREAMING


@async_test
async def test_the_last_step_s_note_is_cleared_before_the_plan_is_shown(tmp_path):
    """A step's note is posted (notify is a message): clearing at once left it over the plan on a loaded machine
    (CI); the clear is queued behind it."""
    app = AccelrigApp(device="serial-sim://still?seed=5", refresh_interval=0.05, profile_dir=tmp_path)
    async with app.run_test(size=(80, 24)) as pilot:
        await wait_for(pilot, lambda: app.session is not None)
        app.push_screen(ResultsScreen(small_result(), None, app.session))
        await wait_for(pilot, lambda: isinstance(app.screen, ResultsScreen) and app.screen.profile is not None)
        results = app.screen
        await pilot.pause(0.2)
        app.clear_notifications()
        results.set_status("reading the device to plan the flash ...")
        await results.clear_notifications()
        await pilot.pause(0.2)
        assert not app._notifications
