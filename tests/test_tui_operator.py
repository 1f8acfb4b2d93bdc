"""What a first-time operator meets in the TUI, read off the screen as drawn (``screen_lines``): a result is
not lost to escape, a dialog shows its own keys, forms read whole at 80x24 and 120x40, the results' numbers
are in view, and a setting remembered from someone else's run is seen and easily reset."""

import pytest
import yaml

from accelrig.tui.app import AccelrigApp, settings_file  # noqa: E402
from accelrig.tui.screens.calibrate import CalibrateMenu  # noqa: E402
from accelrig.tui.screens.dialogs import ChoiceScreen, ConfirmScreen, PathScreen, SettingsForm  # noqa: E402
from accelrig.tui.screens.results import ResultsScreen  # noqa: E402
from accelrig.tui.screens.static_wizard import StaticWizard  # noqa: E402
from report_support import static_result  # noqa: E402
from tui_support import async_test, choose, drawn, screen_lines, wait_for  # noqa: E402

FINITE = "sim://still?seed=1&pace=fast&seconds=2"


@pytest.fixture(scope="module")
def static_run():
    return static_result()


async def show_results(pilot, result, recording) -> ResultsScreen:
    app = pilot.app
    await wait_for(pilot, lambda: app.session is not None)
    screen = ResultsScreen(result, recording, None)
    app.push_screen(screen)
    await wait_for(pilot, lambda: app.screen is screen and screen.profile is not None
                   and screen.query_one("#parameters").row_count > 0)
    await pilot.pause(0.1)
    return screen


@async_test
async def test_escape_on_an_unsaved_result_asks_save_discard_or_stay(static_run, tmp_path):
    """escape on results whose profile is not written asks, as a careful tool does; saving from the question
    closes once written; a saved result closes at once; discarding closes and writes nothing."""
    result, recording = static_run
    app = AccelrigApp(device=FINITE, refresh_interval=0.05, profile_dir=tmp_path)
    async with app.run_test(size=(80, 24)) as pilot:
        results = await show_results(pilot, result, recording)
        await pilot.press("escape")
        await wait_for(pilot, lambda: isinstance(app.screen, ChoiceScreen))
        question = str(app.screen.query_one("#question").render())
        assert "The profile is not saved" in question
        assert [app.screen.query_one("#choices").get_option_at_index(i).id for i in range(3)] == \
            ["save", "discard", "stay"]
        await choose(pilot, "stay")
        assert app.screen is results and not list(tmp_path.glob("*.yaml"))

        await pilot.press("escape")
        await choose(pilot, "save")
        await wait_for(pilot, lambda: isinstance(app.screen, PathScreen))
        await pilot.press("enter")
        await wait_for(pilot, lambda: results not in app.screen_stack)   # written, then closed
        assert results.saved_path is not None and results.saved_path.exists()

        # saved (with s): escape closes without a question
        saved = await show_results(pilot, result, recording)
        await pilot.press("s")
        await wait_for(pilot, lambda: isinstance(app.screen, PathScreen))
        app.screen.query_one("#path").value = str(tmp_path / "second.yaml")
        await pilot.press("enter")
        await wait_for(pilot, lambda: saved.saved_path is not None and app.screen is saved)
        await pilot.press("escape")
        await wait_for(pilot, lambda: saved not in app.screen_stack)
        assert not isinstance(app.screen, ChoiceScreen)

        # discard: closes, nothing more written
        discarded = await show_results(pilot, result, recording)
        await pilot.press("escape")
        await choose(pilot, "discard")
        await wait_for(pilot, lambda: discarded not in app.screen_stack)
    assert sorted(p.name for p in tmp_path.glob("*.yaml")) == ["device-static.yaml", "second.yaml"]


@async_test
async def test_the_rotary_form_reads_whole_its_title_and_the_axis_row_at_120x40_and_80x24():
    """The title keeps its closing parenthesis; the radial axis row reads "x, y or z" with its value set apart
    (it read "x, y or y": the label wrapped after "or" and the value sat next to it)."""
    app = AccelrigApp(device="sim://static?seed=5&pace=fast", refresh_interval=0.05)
    async with app.run_test(size=(120, 40)) as pilot:
        await wait_for(pilot, lambda: app.session is not None)
        await pilot.press("k")
        await wait_for(pilot, lambda: isinstance(app.screen, CalibrateMenu))   # the arrows go to the menu
        await pilot.press("down", "down", "down", "enter")
        await choose(pilot, "demo")
        await wait_for(pilot, lambda: isinstance(app.screen, SettingsForm))
        for size in ((120, 40), (80, 24)):
            await pilot.resize_terminal(*size)
            await wait_for(pilot, lambda: drawn(app))   # laid out again for the new size
            lines = screen_lines(app)
            assert len(lines) == size[1]
            assert any("rotary bench calibration: settings (filled in for the simulated rig)" in line
                       for line in lines), "\n".join(lines)
            (row,) = [line for line in lines if "towards the rotation axis" in line]
            label, value = row.split("▊")
            assert "x, y or z" in label and value.strip().split()[0] == "y", row


@async_test
async def test_the_static_results_keep_every_parameter_in_view_at_120x40(static_run):
    """The sentences of the checks grew long enough to push the last parameter row below the fold: the
    tables come first, the sentences after them."""
    result, recording = static_run
    app = AccelrigApp(device=FINITE, refresh_interval=0.05)
    async with app.run_test(size=(120, 40)) as pilot:
        await show_results(pilot, result, recording)
        screen = "\n".join(screen_lines(app))
        for name in ("angle_x", "gain_z", "offset_z", "b m/s²"):
            assert name in screen, screen
        assert "warning" in screen or "no warnings" in screen   # the warnings stay first


@async_test
async def test_a_long_log_line_is_shown_whole_at_80_columns():
    """Every word of a line longer than the log is on the screen (the log rendered 78 columns into 76 and
    a word at the wrap point disappeared behind a horizontal scroll)."""
    from accelrig.procedures.static.procedure import StaticProcedure
    from accelrig.settings import values_from_texts

    app = AccelrigApp(device="sim://static?seed=5", refresh_interval=0.05)   # real time: no results over it
    async with app.run_test(size=(80, 24)) as pilot:
        await wait_for(pilot, lambda: app.session is not None)
        wizard = StaticWizard(app.session, values=values_from_texts(StaticProcedure.settings, {}))
        app.push_screen(wizard)
        await wait_for(pilot, lambda: app.screen is wizard and wizard.procedure is not None)
        text = ("drift check, last round: now put -y down once more (the opposite face), so the fit can test "
                "the drift between the holds. c computes without it")
        wizard.log_event(text)

        def words():
            return " ".join(" ".join(line.strip("│ ▁▂▃▄▅▆▇█") for line in screen_lines(app)).split())

        # read off the screen once the log has drawn it (the wizard's timer keeps the screen busy: a fixed pause
        # could read it before)
        await wait_for(pilot, lambda: "the drift between the holds" in words())
        assert " ".join(text.split()) in words()


@async_test
async def test_a_first_time_operator_gets_the_six_face_wizard_with_no_detour_and_each_screen_its_keys():
    """A clean home: the static form holds nothing from last time, and enter starts the six faces on the
    default device (no dialog about orientations).  Each dialog's footer shows its own keys."""
    assert not settings_file().exists()
    app = AccelrigApp(refresh_interval=0.05)   # the default device
    async with app.run_test(size=(80, 24)) as pilot:
        await wait_for(pilot, lambda: app.session is not None)
        await pilot.press("k")
        await wait_for(pilot, lambda: isinstance(pilot.app.screen, CalibrateMenu))   # enter goes to its list
        await pilot.press("enter")
        await wait_for(pilot, lambda: isinstance(app.screen, SettingsForm))
        form = app.screen
        assert form.field("model").value == "" and not form.query_one("#settings-remembered").display
        # the footer shows the form's keys, not the wizard's below it (which do nothing there)
        await wait_for(pilot, lambda: "Start" in screen_lines(app)[-1])
        footer = screen_lines(app)[-1]
        assert "Start" in footer and "Cancel" in footer and "Defaults" in footer, footer
        assert "Write data" not in footer and "redo a face" not in footer, footer
        await pilot.press("enter")
        await wait_for(pilot, lambda: isinstance(app.screen, StaticWizard) and app.screen.procedure is not None)
        wizard = app.screen
        assert not isinstance(app.screen, ChoiceScreen)   # (the orientation question comes instead of a procedure)
        assert wizard.sub_title == "six-face static calibration" and wizard.query_one("#faces").display
        # the wizard's keys once it is in front (drawn after it: wait for the footer, not a fixed pause)
        await wait_for(pilot, lambda: "Write data" in screen_lines(app)[-1])
        app.push_screen(ConfirmScreen("Leave this calibration?", "Leave", "Stay"))
        await wait_for(pilot, lambda: isinstance(app.screen, ConfirmScreen))
        # the footer is drawn after the dialog (under load it was still blank after a fixed 0.2 s)
        await wait_for(pilot, lambda: "Leave" in screen_lines(app)[-1])
        footer = screen_lines(app)[-1]
        assert "Leave" in footer and "Stay" in footer and "Write data" not in footer, footer


@async_test
async def test_a_remembered_model_is_shown_as_such_and_ctrl_r_puts_the_defaults_back():
    """Someone chose multi-position on this machine once: the form says it was kept from last time (so the
    orientation question that follows on the six-face rig is no surprise), and ctrl+r resets it."""
    settings_file().parent.mkdir(parents=True, exist_ok=True)
    settings_file().write_text(yaml.safe_dump({"static": {"model": "multi-position", "pose_flatness_deg": "1"}}))
    app = AccelrigApp(refresh_interval=0.05)
    async with app.run_test(size=(80, 24)) as pilot:
        await wait_for(pilot, lambda: app.session is not None)
        await pilot.press("k")
        await wait_for(pilot, lambda: isinstance(pilot.app.screen, CalibrateMenu))   # enter goes to its list
        await pilot.press("enter")
        await wait_for(pilot, lambda: isinstance(app.screen, SettingsForm))
        form = app.screen
        await pilot.pause(0.2)
        note = str(form.query_one("#settings-remembered").render())
        assert "kept from last time: model: multi-position" in note and "ctrl+r" in note
        assert "flatness" not in note   # the default typed out is nothing to point at
        assert form.query_one("#label-model").has_class("remembered")
        await pilot.press("ctrl+r")
        assert form.field("model").value == "" and not form.query_one("#settings-remembered").display
        await pilot.press("enter")
        await wait_for(pilot, lambda: isinstance(app.screen, StaticWizard) and app.screen.procedure is not None)
        await pilot.pause(0.3)
        assert app.screen.sub_title == "six-face static calibration"
    assert yaml.safe_load(settings_file().read_text())["static"]["model"] == ""


@async_test
async def test_the_wheel_and_rotary_forms_say_on_their_face_what_only_f1_said():
    """The wheel's form did not say that the radius or the tilt is needed (F1 did), and the rotary form's
    plan, steps FREQUENCY:DEGREES, gave no unit."""
    from tui_support import open_wizard

    for wizard, url, label, said in (
            ("wheel", "sim://wheel?seed=1", "#settings-note", "Give the radius, the tilt, or both: the one left "
                                                              "blank is estimated (one is needed)."),
            ("rotary", "sim://rotary?seed=1", "#label-plan", "steps FREQUENCY:DEGREES, in Hz:degrees peak to peak")):
        app = AccelrigApp(device=url, refresh_interval=0.05)
        async with app.run_test(size=(80, 24)) as pilot:
            await open_wizard(pilot, wizard)
            form = app.screen
            form.query_one(label).scroll_visible(animate=False)
            await wait_for(pilot, lambda form=form, label=label: str(form.query_one(label).render()).strip())
            assert " ".join(str(form.query_one(label).render()).split()) == said
            await pilot.pause(0.2)
            words = " ".join(" ".join(line.strip("│ ▁▂▃▄▅▆▇█▊▎") for line in screen_lines(app)).split())
            assert said.split(":")[0] in words, words   # drawn where the operator reads it
