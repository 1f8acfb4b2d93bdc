"""What an operator in the field met: times from the capture's start (not a board's uptime), a long compute
that counts its seconds, the help's words."""

import re
import threading

import numpy as np

from accelrig.tui.app import AccelrigApp
from accelrig.tui.screens.dialogs import SettingsForm
from accelrig.tui.screens.results import ResultsScreen
from tui_support import async_test, wait_for

# a firmware board whose clock does not start at 0 (its uptime), its static script played fast
DEVICE = "serial-sim://static?seed=5&pace=fast&order=+z,-z,+x,-x,+y,-y,+z,+x,+y&hold=3"


@async_test
async def test_static_results_on_a_board_with_an_uptime_clock_give_times_from_the_capture_start(tmp_path):
    app = AccelrigApp(device=DEVICE, refresh_interval=0.05, profile_dir=tmp_path)
    async with app.run_test(size=(80, 24)) as pilot:
        await wait_for(pilot, lambda: app.session is not None)
        await pilot.press("k", "enter")
        await wait_for(pilot, lambda: isinstance(app.screen, SettingsForm))
        await pilot.press("enter")
        await wait_for(pilot, lambda: isinstance(app.screen, ResultsScreen) and bool(app.screen.query("#poses")),
                       timeout=120)
        results = app.screen
        run = results.recording.duration
        poses = results.query_one("#poses")
        starts = [float(poses.get_row_at(i)[1]) for i in range(poses.row_count)]
        stops = [float(poses.get_row_at(i)[2]) for i in range(poses.row_count)]
        assert 0 <= min(starts) and max(stops) <= run + 1, (starts, stops, run)
        # the pose plot's x axis too, and the time the pose means are referred to
        x = np.concatenate([s.x for s in results.plots[0].series])
        assert 0 <= x.min() and x.max() <= run + 1
        middle = results.result.quality["uncertainty_source"].split("(t = ")[1].split(" s)")[0]
        assert 0 < float(middle) < run


@async_test
async def test_a_long_compute_counts_its_seconds_on_the_headline(tmp_path, monkeypatch):
    from accelrig.procedures.static.procedure import StaticProcedure

    # the fit waits until the test has seen the seconds counted (a slow fit on a loaded machine, made certain)
    seen = threading.Event()
    fit = StaticProcedure.result

    def slow_fit(self):
        assert seen.wait(120), "the headline never counted the seconds"
        return fit(self)

    monkeypatch.setattr(StaticProcedure, "result", slow_fit)
    app = AccelrigApp(device="sim://static?seed=3&pace=fast&order=+z,-z,+x,-x,+y,-y&hold=3", refresh_interval=0.05,
                      profile_dir=tmp_path)
    async with app.run_test(size=(80, 24)) as pilot:
        await wait_for(pilot, lambda: app.session is not None)
        await pilot.press("k", "enter")
        await wait_for(pilot, lambda: isinstance(app.screen, SettingsForm))
        await pilot.press("enter")
        await wait_for(pilot, lambda: getattr(app.screen, "computing", False), timeout=90)
        wizard = app.screen

        def headline():
            return str(wizard.query_one("#instruction").render())

        await wait_for(pilot, lambda: re.search(r"computing the .* \.\.\. [1-9]\d* s", headline()))
        seen.set()
        await wait_for(pilot, lambda: isinstance(app.screen, ResultsScreen), timeout=90)
        assert wizard._compute_clock is None   # stopped with the results
        logged = [line.text for line in wizard.query_one("#events").lines]
        assert not any(re.search(r"\.\.\. \d+ s", text) for text in logged)   # the log keeps the line once


@async_test
async def test_help_names_the_key_that_works_in_a_form_and_the_results_help_says_whose_they_are(tmp_path):
    from accelrig.tui.screens.help import HelpScreen
    from tui_support import screen_lines

    # the static rig at its own pace: its 90 s script outlasts the test
    app = AccelrigApp(device="sim://static?seed=1", refresh_interval=0.05, profile_dir=tmp_path)
    async with app.run_test(size=(80, 24)) as pilot:
        await wait_for(pilot, lambda: app.session is not None and app.session.stats().samples > 0)
        # the live view labels its magnitude bars, the two rows above the status line
        await wait_for(pilot, lambda: "highest" in str(app.screen.query_one("#magnitude-label").render()))
        assert "|a| over the last 5 s (m/s²)" in str(app.screen.query_one("#magnitude-label").render())

        await pilot.press("k", "enter")
        await wait_for(pilot, lambda: isinstance(app.screen, SettingsForm))
        # in a field ? types itself: the footer and the help name F1, the key that opens the help there
        assert "f1 Help" in screen_lines(app)[-1] and "? Help" not in screen_lines(app)[-1]
        await pilot.press("f1")
        await wait_for(pilot, lambda: isinstance(app.screen, HelpScreen))
        keys = str(app.screen.query_one("#help-keys").render())
        assert re.search(r"f1\s+Help", keys) and not re.search(r"\?\s+Help", keys), keys
        await pilot.press("escape")
        await pilot.press("escape")
        await wait_for(pilot, lambda: not isinstance(app.screen, SettingsForm))

        from test_tui_flash import small_result

        app.push_screen(ResultsScreen(small_result(), None, None))
        await wait_for(pilot, lambda: isinstance(app.screen, ResultsScreen) and app.screen.profile is not None)
        await pilot.press("question_mark")
        await wait_for(pilot, lambda: isinstance(app.screen, HelpScreen))
        intro = str(app.screen.query_one("#help-intro").render())
        assert intro.startswith("Results of the static calibration (method test"), intro
