"""The TUI shell driven with Textual's Pilot: live view, help, connect, disconnect, errors."""




from accelrig.acquisition.session import State  # noqa: E402
from accelrig.tui.app import AccelrigApp  # noqa: E402
from accelrig.tui.screens.connect import ConnectScreen  # noqa: E402
from accelrig.tui.screens.help import HelpScreen  # noqa: E402
from accelrig.tui.screens.live import LiveScreen  # noqa: E402
from tui_support import async_test, wait_for  # noqa: E402

FINITE = "sim://still?seed=1&pace=fast&seconds=10"


def text_of(app, selector):
    return str(app.screen.query_one(selector).render())


@async_test
async def test_live_view_shows_device_rate_and_stats():
    app = AccelrigApp(device=FINITE, refresh_interval=0.05)
    async with app.run_test(size=(80, 24)) as pilot:
        await wait_for(pilot, lambda: app.session is not None and app.session.stats().state == State.ENDED)
        # drawn after the end (the view refreshes on a timer, which a loaded machine can hold back past a
        # fixed pause): every line below is from that same refresh
        await wait_for(pilot, lambda: "source ended" in text_of(app, "#stats-line"))
        assert isinstance(app.screen, LiveScreen)
        assert "sim-random-1" in text_of(app, "#device-line")
        stats = text_of(app, "#stats-line")
        assert "samples 2008" in stats and "drops 0" in stats and "200.8 Hz" in stats
        now = text_of(app, "#axes-now")
        assert "z   +9." in now or "z  +9." in now
        assert text_of(app, "#warning-line") == ""


@async_test
async def test_the_device_line_keeps_one_row_with_a_long_url():
    # "±2 / g  1000 Hz" wrapped onto a second row under a long URL and pushed the traces down
    url = "i2c-sim://mpu9250?rig=static&pace=fast&rate=200&seed=3"
    app = AccelrigApp(device=url, refresh_interval=0.05)
    async with app.run_test(size=(80, 24)) as pilot:
        await wait_for(pilot, lambda: app.session is not None and app.session.info is not None)
        line = app.screen.query_one("#device-line")
        await wait_for(pilot, lambda: "…" in str(line.render()))
        text = str(line.render())
        assert line.size.height == 1 and text.startswith("i2c-sim://mpu9250?rig=static")
        assert text.endswith("mpu9250  id i2c-sim-mpu9250-seed3  ±2 g  200 Hz")


@async_test
async def test_help_lists_the_keys_of_the_screen_below():
    app = AccelrigApp(device=FINITE)
    async with app.run_test(size=(80, 24)) as pilot:
        await pilot.press("question_mark")
        await wait_for(pilot, lambda: isinstance(app.screen, HelpScreen))
        keys = text_of(app, "#help-keys")
        for description in ("Connect", "Calibrate", "Pause view", "Quit", "Help"):
            assert description in keys
        await pilot.press("escape")
        await wait_for(pilot, lambda: isinstance(app.screen, LiveScreen))


@async_test
async def test_help_on_the_calibrate_menu_says_what_each_wizard_needs_and_not_the_lists_own_keys():
    from accelrig.tui.screens.calibrate import CalibrateMenu

    app = AccelrigApp(device=FINITE)
    async with app.run_test(size=(80, 24)) as pilot:
        await wait_for(pilot, lambda: app.session is not None)
        await pilot.press("k")
        await wait_for(pilot, lambda: isinstance(app.screen, CalibrateMenu))
        await pilot.press("question_mark")
        await wait_for(pilot, lambda: isinstance(app.screen, HelpScreen))
        guide = text_of(app, "#help-intro")
        assert "enter starts the wizard" in guide and "model multi-position" in guide
        assert "Tilted wheel" in guide and "needs rotation" in guide
        keys = text_of(app, "#help-keys")
        assert "Back" in keys and "Scroll Left" not in keys and "Page Right" not in keys


@async_test
async def test_help_reaches_a_dialog_and_tells_what_it_asks():
    from accelrig.tui.screens.calibrate import CalibrateMenu
    from accelrig.tui.screens.dialogs import ChoiceScreen, PathScreen
    from tui_support import screen_lines

    app = AccelrigApp(device=FINITE, refresh_interval=0.05)
    async with app.run_test(size=(80, 24)) as pilot:
        await wait_for(pilot, lambda: app.session is not None)
        # a dialog with a text field: ? types itself (a URL holds one), F1 opens the dialog's own help
        await pilot.press("m")
        await wait_for(pilot, lambda: isinstance(app.screen, PathScreen))
        dialog = app.screen
        # enter opens the broker's screen, and says so (it said "Save")
        # (the footer is drawn after the dialog: under load it was still blank when the dialog was up)
        await wait_for(pilot, lambda: "⏎ Open esc Cancel f1 Help" in screen_lines(app)[-1])
        await pilot.press("question_mark")
        assert dialog.query_one("#path").value.endswith("?") and app.screen is dialog
        await pilot.press("f1")
        await wait_for(pilot, lambda: isinstance(app.screen, HelpScreen))
        assert "MQTT broker of the fleet" in text_of(app, "#help-intro")
        assert "Open" in text_of(app, "#help-keys") and "Calibrate" not in text_of(app, "#help-keys")
        await pilot.press("escape")
        await wait_for(pilot, lambda: app.screen is dialog)
        await pilot.press("escape")
        await wait_for(pilot, lambda: isinstance(app.screen, LiveScreen))
        # a choice (the wheel wizard on the static rig offers the simulated wheel): ? works at once
        await pilot.press("k")
        await wait_for(pilot, lambda: isinstance(app.screen, CalibrateMenu))
        menu = app.screen.query_one("#wizards")
        menu.highlighted = [menu.get_option_at_index(i).id for i in range(menu.option_count)].index("wheel")
        await pilot.press("enter")
        await wait_for(pilot, lambda: isinstance(app.screen, ChoiceScreen))
        choice = app.screen
        await wait_for(pilot, lambda: "? Help" in screen_lines(app)[-1])   # drawn after the dialog (see above)
        await pilot.press("question_mark")
        await wait_for(pilot, lambda: isinstance(app.screen, HelpScreen))
        guide = text_of(app, "#help-intro")
        assert "Use the simulated wheel rig" in guide and "escape goes back without choosing" in guide
        await pilot.press("f1")   # F1 (or ?) again closes the help
        await wait_for(pilot, lambda: app.screen is choice)


@async_test
async def test_connect_screen_switches_device_and_shows_identity():
    app = AccelrigApp(device=FINITE, refresh_interval=0.05)
    async with app.run_test(size=(80, 24)) as pilot:
        await wait_for(pilot, lambda: app.session is not None)
        first = app.session
        await pilot.press("c")
        await wait_for(pilot, lambda: isinstance(app.screen, ConnectScreen))
        found = app.screen.query_one("#found")
        await wait_for(pilot, lambda: any(found.get_option_at_index(i).id == "sim://still"
                                          for i in range(found.option_count)))
        ids = [found.get_option_at_index(i).id for i in range(found.option_count)]
        # the flashable emulated chips are offered (calibrate on the static rig, then flash)
        assert "i2c-sim://mpu9250?rig=static" in ids
        # ? says how to connect and the URL forms (it gave the app's opening text)
        await pilot.press("question_mark")
        await wait_for(pilot, lambda: isinstance(app.screen, HelpScreen))
        assert "enter connects to the one highlighted" in text_of(app, "#help-intro")
        await pilot.press("escape")
        await wait_for(pilot, lambda: isinstance(app.screen, ConnectScreen))
        assert "Devices found (enter connects" in str(app.screen.query("Label").first().render())
        # one enter on a found device connects to it (it copied the URL into the field and waited for another)
        found.focus()
        found.highlighted = ids.index("sim://still")
        await pilot.press("enter")
        await wait_for(pilot, lambda: app.session is not first)
        assert app.session.url == "sim://still" and first.stats().state in (State.STOPPED, State.ENDED)
        await wait_for(pilot, lambda: "connected" in text_of(app, "#connect-status"))
        listed = app.session
        url_input = app.screen.query_one("#url")
        url_input.value = "sim://still?seed=9&pace=fast&seconds=3&range=4"
        url_input.focus()
        await pilot.press("enter")
        await wait_for(pilot, lambda: app.session is not listed)
        # the device's line once the screen's timer has drawn the new session (not after a fixed pause)
        await wait_for(pilot, lambda: "sim-random-9" in text_of(app, "#connected-device")
                       and "delivered" in text_of(app, "#connected-device"))
        shown = text_of(app, "#connected-device")
        assert "sim-random-9" in shown and "±4 g" in shown and "delivered" in shown
        await pilot.press("escape")
        await wait_for(pilot, lambda: isinstance(app.screen, LiveScreen))


@async_test
async def test_connect_rescans_with_f5_in_the_url_field_where_r_types_itself():
    # r was the only rescan key: in the URL field it typed an r, and the footer still offered it
    app = AccelrigApp(device=FINITE)
    async with app.run_test(size=(80, 24)) as pilot:
        await pilot.press("c")
        await wait_for(pilot, lambda: isinstance(app.screen, ConnectScreen))
        screen = app.screen
        scans = []
        screen.scan = lambda: scans.append(screen.focused.id if screen.focused else None)
        url_input = screen.query_one("#url")
        url_input.value = ""
        url_input.focus()
        await pilot.press("r")
        await wait_for(pilot, lambda: url_input.value == "r")
        await pilot.press("f5")
        await wait_for(pilot, lambda: scans == ["url"])
        assert url_input.value == "r"
        screen.query_one("#found").focus()
        await pilot.press("r")
        await wait_for(pilot, lambda: scans == ["url", "found"])
        shown = {key.key for key in screen.query("FooterKey")}   # the footer offers the key that works
        assert "f5" in shown and "r" not in shown


@async_test
async def test_a_bad_url_is_said_on_screen_and_nothing_crashes():
    app = AccelrigApp(device="sim://no-such-rig")
    async with app.run_test(size=(80, 24)) as pilot:
        await wait_for(pilot, lambda: app.connect_error is not None)
        await wait_for(pilot, lambda: "unknown simulated rig" in text_of(app, "#device-line"))   # the timer drew it
        await pilot.press("c")
        await wait_for(pilot, lambda: isinstance(app.screen, ConnectScreen))
        url_input = app.screen.query_one("#url")
        url_input.value = "nonsense"
        url_input.focus()
        await pilot.press("enter")
        await wait_for(pilot, lambda: "cannot connect" in text_of(app, "#connect-status"))
        assert "not a device URL" in text_of(app, "#connect-status")


@async_test
async def test_disconnect_is_said_on_the_live_view():
    app = AccelrigApp(device="sim://still?seed=2&pace=fast&disconnect_after=2", refresh_interval=0.05)
    async with app.run_test(size=(80, 24)) as pilot:
        await wait_for(pilot, lambda: app.session is not None and app.session.stats().state == State.DISCONNECTED)
        await wait_for(pilot, lambda: "disconnected" in text_of(app, "#stats-line"))   # the timer drew the state
        warning = text_of(app, "#warning-line")
        assert "DEVICE DISCONNECTED" in warning and "disconnected" in warning
        assert "disconnected" in text_of(app, "#stats-line")


@async_test
async def test_saturation_warning():
    app = AccelrigApp(device="sim://still?seed=3&pace=fast&seconds=3&noise=30", refresh_interval=0.05)
    async with app.run_test(size=(80, 24)) as pilot:
        await wait_for(pilot, lambda: app.session is not None and app.session.stats().state == State.ENDED)
        await wait_for(pilot, lambda: "source ended" in text_of(app, "#stats-line"))   # the timer drew the end
        assert "SATURATION" in text_of(app, "#warning-line")


def test_cli_says_which_extra_is_missing_without_textual(monkeypatch, capsys):
    import sys

    from accelrig.cli import main

    monkeypatch.setitem(sys.modules, "textual", None)  # import textual now fails as if not installed
    assert main(["tui"]) == 3
    err = capsys.readouterr().err
    assert "the TUI needs the Python package 'textual'" in err and "accelrig[tui]" in err


@async_test
async def test_a_long_path_is_shown_whole_under_its_field():
    # the field shows the end of a long path (a newcomer saw only "/i2c-sim-mpu9250-seed14-...yaml")
    from accelrig.tui.screens.dialogs import PathScreen
    from tui_support import screen_lines

    default = "/root/.local/share/accelrig/profiles/i2c-sim-mpu9250-seed14/20261125T034500Z-static.yaml"
    app = AccelrigApp(device=FINITE, refresh_interval=0.05)
    async with app.run_test(size=(80, 24)) as pilot:
        await wait_for(pilot, lambda: app.session is not None)
        app.push_screen(PathScreen("Save the profile to (the store by default):", default))
        await wait_for(pilot, lambda: isinstance(app.screen, PathScreen))
        await pilot.pause(0.1)
        shown = "".join(line.strip() for line in screen_lines(app))
        assert "/root/.local/share/accelrig/profiles/" in shown and "20261125T034500Z-static.yaml" in shown
        await pilot.press("ctrl+u", *"short.yaml")   # a path the field shows whole: no second line
        await pilot.pause(0.1)
        assert str(app.screen.query_one("#path-whole").render()).strip() == ""


@async_test
async def test_a_full_collection_in_the_ui_thread_leaves_the_loaded_modules_alone_while_a_device_streams():
    """The cyclic collector runs in the UI thread and holds the interpreter while it walks every object it
    sees; the pump cannot poll meanwhile.  Walking what the app loaded (textual, numpy, scipy, the driver:
    some 110 000 objects) took 60-130 ms (measured in a terminal), past the 85 ms an MPU-9250's FIFO holds
    at 1 kHz: the live view counted drops that `accelrig record` never had.  The app keeps what it loaded
    out of the collector's sight while it runs, and gives it back when it ends.  Counted, not timed, so
    a loaded test machine does not matter."""
    import gc

    gc.unfreeze()   # what an earlier test in this process froze (record does) is not this app's doing
    app = AccelrigApp(device="i2c-sim://mpu9250?rig=static&seed=14&rate=1000", refresh_interval=0.05)
    async with app.run_test(size=(80, 24)) as pilot:
        await wait_for(pilot, lambda: app.session is not None and app.session.stats().samples > 200)
        await pilot.pause(0.3)
        walked = len(gc.get_objects())   # what a full collection would walk now
        kept_aside = gc.get_freeze_count()
        # measured: about 6 000 walked, 120 000 kept aside (on main: 125 000 walked, none aside)
        assert walked < 25_000, f"a full collection walks {walked} objects ({kept_aside} kept out of its sight)"
        assert kept_aside > 50_000, kept_aside
        assert app.session.stats().state == State.STREAMING
    assert gc.get_freeze_count() == 0   # a program (or the next test) that goes on gets them collected again
