"""The static wizard at 80x24: the 'redo a face' dialog leaves the face grid it asks about in sight, and the
event log never cuts a line short when its scrollbar appears."""

from accelrig.procedures.static.settings import SETTINGS
from accelrig.settings import values_from_texts
from accelrig.tui.app import AccelrigApp
from accelrig.tui.screens.static_wizard import RedoScreen, StaticWizard
from tui_support import async_test, wait_for

SIX = ["+x", "-x", "+y", "-y", "+z", "-z"]


def overlap(a, b) -> bool:
    return a.x < b.right and b.x < a.right and a.y < b.bottom and b.y < a.bottom


@async_test
async def test_the_redo_dialog_leaves_the_face_grid_in_sight_and_the_log_keeps_whole_lines(tmp_path):
    app = AccelrigApp(device="sim://static?seed=3", refresh_interval=0.05, profile_dir=tmp_path)
    async with app.run_test(size=(80, 24)) as pilot:
        await wait_for(pilot, lambda: app.session is not None)
        wizard = StaticWizard(app.session, values=values_from_texts(SETTINGS, {}))   # the form's defaults
        app.push_screen(wizard)
        await wait_for(pilot, lambda: app.screen is wizard and wizard.query_one("#faces").region)
        grid = wizard.query_one("#faces").region

        # a line a little wider than the log (76 columns at 80x24) is wrapped to the log's width, not cut: the
        # log rendered at least 78 columns and cropped the rest, so "± 0.00093 mm" read "± 0.00"
        log = wizard.query_one("#events")
        line = "step 3: 9.000 Hz, first harmonic 20.304 ± 0.003 m/s², radius 6.3495 ± 0.00093 mm"
        wizard.log_event(line)
        await pilot.pause()
        log.scroll_end(animate=False)
        await pilot.pause()
        shown = [''.join(segment.text for segment in log.render_line(y)).rstrip() for y in range(log.size.height)]
        at = next(i for i, row in enumerate(shown) if row.startswith("step 3:"))   # the wizard logs on after it
        assert " ".join(shown[at:at + 2]).split()[:len(line.split())] == line.split(), shown
        assert not log.show_horizontal_scrollbar

        picked = []
        # the most it can list: every face done (the wizard asks with the faces done so far)
        app.push_screen(RedoScreen(SIX), picked.append)
        await wait_for(pilot, lambda: isinstance(app.screen, RedoScreen) and app.screen.query_one(".dialog").region)
        dialog = app.screen.query_one(".dialog").region
        faces = app.screen.query_one("#redo-faces")
        assert not overlap(dialog, grid), (dialog, grid)
        assert dialog.bottom <= 23   # the key footer's row stays free
        assert faces.region.height >= len(SIX)   # every face on the list without scrolling
        await pilot.press("down", "enter")
        await wait_for(pilot, lambda: picked)
        assert picked == ["-x"]
