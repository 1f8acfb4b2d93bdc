"""Helpers shared by the Pilot tests of the TUI (imported by tests/test_tui*.py)."""

import asyncio
import functools

from textual.css.query import NoMatches


def async_test(fn):
    """Run an async test with asyncio.run (no pytest-asyncio needed)."""

    @functools.wraps(fn)
    def run(*args, **kwargs):
        return asyncio.run(fn(*args, **kwargs))

    return run


def holds(condition) -> bool:
    """``condition()``, where a widget not found (the screen it queries is not up yet) means "not yet"."""
    try:
        return bool(condition())
    except NoMatches:
        return False


async def wait_for(pilot, condition, timeout=90.0):
    """Let the app run until ``condition()`` holds; fail after ``timeout`` seconds (generous: only a failing test
    waits it out, and under load 30 on 2 cores a Pilot test runs 3-5 times slower than on an idle machine)."""
    loop = asyncio.get_running_loop()
    deadline = loop.time() + timeout
    while not holds(condition):
        if loop.time() > deadline:
            raise AssertionError("timed out waiting for the app")
        await pilot.pause(0.05)
    # the condition may hold on a screen pushed during the last pause: let that screen and its widgets take
    # their first events (Textual's Header sets its title on a queued callback that fails with NoMatches when
    # the app exits before it runs, as a test does right after its last wait)
    await pilot.pause(0)


def drawn(app) -> bool:
    """The screen in front has been laid out for the terminal's size and has nothing waiting to be drawn (after
    a resize or a change, a fixed pause before reading ``screen_lines`` can come before the redraw on a loaded
    host)."""
    screen = app.screen
    return (screen._compositor.size == app.size and not screen._dirty_widgets
            and not (screen._layout_required or screen._repaint_required or screen._scroll_required
                     or screen._recompose_required))


def screen_lines(app) -> list[str]:
    """The terminal's text as drawn now, one string per row (dialogs over the screens below them, as an
    operator sees it; what App.export_screenshot draws, as text)."""
    import io

    from rich.console import Console

    width, height = app.size
    console = Console(width=width, height=height, file=io.StringIO(), force_terminal=True, record=True,
                      legacy_windows=False, safe_box=False)
    console.print(app.screen._compositor.render_update(full=True, screen_stack=app._background_screens))
    return console.export_text().splitlines()


async def choose(pilot, choice: str, timeout=90.0):
    """Pick the option ``choice`` (its id) of the ChoiceScreen that is open or about to open, as the arrows and
    enter would."""
    from textual.widgets import OptionList

    from accelrig.tui.screens.dialogs import ChoiceScreen

    app = pilot.app
    await wait_for(pilot, lambda: isinstance(app.screen, ChoiceScreen), timeout)
    options = app.screen.query_one(OptionList)
    options.highlighted = options.get_option_index(choice)
    await pilot.press("enter")
    await wait_for(pilot, lambda: not isinstance(app.screen, ChoiceScreen), timeout)


async def open_wizard(pilot, name: str):
    """From the start screen: wait for the device, open the calibrate menu, pick wizard ``name`` and wait for its
    settings form."""
    from accelrig.tui.screens.calibrate import CalibrateMenu
    from accelrig.tui.screens.dialogs import SettingsForm

    app = pilot.app
    await wait_for(pilot, lambda: app.session is not None)
    await pilot.press("k")
    await wait_for(pilot, lambda: isinstance(app.screen, CalibrateMenu))
    menu = app.screen.query_one("#wizards")
    menu.highlighted = [menu.get_option_at_index(i).id for i in range(menu.option_count)].index(name)
    await pilot.press("enter")
    await wait_for(pilot, lambda: isinstance(app.screen, SettingsForm))
