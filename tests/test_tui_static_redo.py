"""The static wizard's 'redo a face' dialog at 80x24 leaves the face grid it asks about in sight."""

from accelrig.procedures.static.settings import SETTINGS
from accelrig.settings import values_from_texts
from accelrig.tui.app import AccelrigApp
from accelrig.tui.screens.static_wizard import RedoScreen, StaticWizard
from tui_support import async_test, wait_for

SIX = ["+x", "-x", "+y", "-y", "+z", "-z"]


def overlap(a, b) -> bool:
    return a.x < b.right and b.x < a.right and a.y < b.bottom and b.y < a.bottom


@async_test
async def test_the_redo_dialog_leaves_the_face_grid_in_sight_at_80x24(tmp_path):
    app = AccelrigApp(device="sim://static?seed=3", refresh_interval=0.05, profile_dir=tmp_path)
    async with app.run_test(size=(80, 24)) as pilot:
        await wait_for(pilot, lambda: app.session is not None)
        app.push_screen(StaticWizard(app.session, values=values_from_texts(SETTINGS, {})))   # the form's defaults
        await wait_for(pilot, lambda: isinstance(app.screen, StaticWizard) and app.screen.query_one("#faces").region)
        grid = app.screen.query_one("#faces").region
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
