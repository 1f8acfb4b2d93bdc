"""The results screen's plots have physical axes and draw the certificate's own arrays; c writes the
certificate through accelrig.report (HTML, PDF when Chromium is there, a clear message when it is not)."""

import numpy as np
import pytest

from accelrig.tui.app import AccelrigApp  # noqa: E402
from accelrig.tui.screens.dialogs import ConfirmScreen, PathScreen, SettingsForm  # noqa: E402
from accelrig.tui.screens.results import ResultsScreen, result_views  # noqa: E402
from report_support import DEVICE, slider_crank_result, static_result, wheel_result  # noqa: E402
from tui_support import async_test, wait_for  # noqa: E402

pytest.importorskip("matplotlib")

PHYSICAL = ("(s)", "(Hz)", "(degrees)", "time (s)")


@pytest.fixture(scope="module")
def static_run():
    return static_result()


@pytest.fixture(scope="module")
def wheel_run():
    return wheel_result()


def test_static_views_plot_the_pose_errors_against_time(static_run):
    result, rec = static_run
    views = result_views(result, rec)
    assert views and all(any(unit in v.x_label for unit in PHYSICAL) for v in views)
    magnitude = views[0]
    times = np.asarray(result.arrays["pose_times"]).mean(axis=1)
    after = {s.label: s for s in magnitude.series}["after"]
    assert np.allclose(after.x, times)
    corr = result.correction
    truth = np.linalg.norm((result.arrays["pose_means"] - corr.bias) @ corr.matrix.T, axis=1) - 9.80665
    assert np.allclose(after.y, truth)


def test_wheel_views_hold_residuals_against_time_and_angle_and_the_spectrum(wheel_run):
    result, rec = wheel_run
    views = {v.x_label: v for v in result_views(result, rec)}
    by_angle = views["angle (degrees)"]
    angle = np.asarray(result.arrays["angle_deg"])
    assert angle.min() >= 0 and angle.max() < 360
    for k, s in enumerate(by_angle.series):
        assert np.array_equal(s.x, angle) and np.array_equal(s.y, result.arrays["residuals"][:, k])
    # the angle is the fitted law's: its rate at the half-turn times is the fitted speed (deg/s vs rad/s)
    t = np.asarray(result.arrays["t"])
    unwrapped = np.rad2deg(np.unwrap(np.deg2rad(angle)))
    rate = np.interp(result.arrays["speed_time"], t[1:], np.diff(unwrapped) / np.diff(t))
    assert np.allclose(np.abs(np.deg2rad(rate)), result.arrays["speed_fit"], rtol=1e-2)
    assert "frequency (Hz)" in views and "time (s)" in views


def test_slider_crank_views_are_against_frequency_in_hz():
    result, rec = slider_crank_result()
    views = result_views(result, rec)
    assert [v.x_label for v in views] == ["crank frequency (Hz)"] * 2
    measured = {s.label: s for s in views[0].series}["measured"]
    assert np.allclose(measured.x, result.arrays["frequency_hz"]) and np.allclose(measured.y, result.arrays["amplitude"])
    radius = {s.label: s for s in views[1].series}["from the motion"]
    assert np.allclose(radius.y, 1e3 * result.arrays["radius_m"])


def status(app):
    return str(app.screen.query_one("#results-status").render())


async def open_results(pilot, result, rec):
    app = pilot.app
    await wait_for(pilot, lambda: app.session is not None)
    app.push_screen(ResultsScreen(result, rec, None))
    await wait_for(pilot, lambda: isinstance(app.screen, ResultsScreen) and app.screen.query_one("#result-plot"))
    await pilot.pause(0.1)
    return app.screen


async def fill_conditions(pilot, **texts):
    """The certificate's form (who it is for, who issues it): ``texts`` typed into their fields, then enter."""
    app = pilot.app
    await wait_for(pilot, lambda: isinstance(app.screen, SettingsForm))
    for name, text in texts.items():
        app.screen.field(name).value = text
    await pilot.press("enter")


async def type_path(pilot, path):
    app = pilot.app
    await fill_conditions(pilot)
    await wait_for(pilot, lambda: isinstance(app.screen, PathScreen))
    field = app.screen.query_one("#path")
    field.value = str(path)
    await pilot.press("enter")


@async_test
async def test_help_on_the_results_says_how_to_read_them_and_lists_their_keys(static_run, tmp_path):
    from accelrig.tui.screens.help import HelpScreen

    result, rec = static_run
    app = AccelrigApp(device="sim://still?seed=1&pace=fast&seconds=2", refresh_interval=0.05, profile_dir=tmp_path)
    async with app.run_test(size=(100, 30)) as pilot:
        await open_results(pilot, result, rec)
        await pilot.press("question_mark")
        await wait_for(pilot, lambda: isinstance(app.screen, HelpScreen))
        intro = str(app.screen.query_one("#help-intro").render())
        keys = str(app.screen.query_one("#help-keys").render())
        assert "Results of the" in intro and "standard uncertainty (k = 1)" in intro and "warnings" in intro
        assert "Connect a device" not in intro   # not the live screen's guide
        assert "Certificate" in keys and "Save profile" in keys


@async_test
async def test_c_writes_the_html_certificate_and_asks_before_overwriting(static_run, tmp_path, monkeypatch):
    monkeypatch.setattr("accelrig.report.certificate.find_browser", lambda: None)
    result, rec = static_run
    app = AccelrigApp(device="sim://still?seed=1&pace=fast&seconds=2", refresh_interval=0.05, profile_dir=tmp_path)
    async with app.run_test(size=(100, 30)) as pilot:
        results = await open_results(pilot, result, rec)
        assert "(s)" in results.query_one("#result-plot").x_label
        await pilot.press("c")
        # who it is for and who issues it, as `accelrig report`'s flags
        await fill_conditions(pilot, number="CAL-2026-0117", customer="Acme Sensors, Lyon", operator="J. Roux",
                              approved_by="M. Lefort")
        await wait_for(pilot, lambda: isinstance(app.screen, PathScreen))
        # no browser here: the offered file is HTML and the prompt says why
        default = app.screen.query_one("#path").value
        assert default.endswith("-static-certificate.html") and "no Chromium" in app.screen.prompt
        await pilot.press("enter")
        await wait_for(pilot, lambda: "certificate written" in status(app), timeout=60)
        path = results.certificate_path
        page = path.read_text(encoding="utf-8")
        assert "<svg" in page and rec.content_hash() in page
        for name in result.parameters:
            assert name in page
        for text in ("No. CAL-2026-0117", "Acme Sensors, Lyon", "J. Roux", "M. Lefort"):
            assert text in page, text

        # the form offers them again (kept between runs, as the wizards' forms are), but not the number:
        # each certificate has its own
        await pilot.press("c")
        await wait_for(pilot, lambda: isinstance(app.screen, SettingsForm))
        assert app.screen.field("operator").value == "J. Roux" and app.screen.field("approved_by").value == "M. Lefort"
        assert app.screen.field("number").value == ""
        assert app.setting_texts["certificate"]["customer"] == "Acme Sensors, Lyon"
        await pilot.press("escape")
        await wait_for(pilot, lambda: "no certificate written" in status(app))

        # again: an existing file is kept unless the operator says overwrite
        await pilot.press("c")
        await type_path(pilot, path)
        await wait_for(pilot, lambda: isinstance(app.screen, ConfirmScreen))
        await pilot.press("n")
        await wait_for(pilot, lambda: "kept as it was" in status(app))
        assert path.read_text(encoding="utf-8") == page

        # a PDF without a browser: told at once, nothing written
        await pilot.press("c")
        await type_path(pilot, tmp_path / "cert.pdf")
        await wait_for(pilot, lambda: "no certificate written" in status(app))
        assert "Chromium" in status(app) and not (tmp_path / "cert.pdf").exists()


@async_test
async def test_c_prints_a_pdf_when_chromium_is_installed(static_run, tmp_path):
    from accelrig.report.certificate import find_browser

    if find_browser() is None:
        pytest.skip("no Chromium here (.ci/run installs it)")
    result, rec = static_run
    app = AccelrigApp(device="sim://still?seed=1&pace=fast&seconds=2", refresh_interval=0.05, profile_dir=tmp_path)
    async with app.run_test(size=(100, 30)) as pilot:
        results = await open_results(pilot, result, rec)
        await pilot.press("c")
        await fill_conditions(pilot)
        await wait_for(pilot, lambda: isinstance(app.screen, PathScreen))
        assert app.screen.query_one("#path").value.endswith(".pdf")
        await pilot.press("enter")
        await wait_for(pilot, lambda: "certificate written" in status(app), timeout=120)
        assert results.certificate_path.read_bytes().startswith(b"%PDF")


def test_device_identity_names_the_default_file(tmp_path, static_run):
    from accelrig.tui.screens.certificate import default_certificate_path

    result, _ = static_run
    path = default_certificate_path(tmp_path, result, DEVICE)
    assert path.parent == tmp_path and path.name.startswith("sim-0042-static-certificate.")


@async_test
async def test_the_campaign_screen_plots_the_sensitivities_and_writes_the_certificate(tmp_path, monkeypatch):
    from accelrig.tui.screens.rotary_wizard import CampaignScreen
    from report_support import rotary_campaign_result

    monkeypatch.setattr("accelrig.report.certificate.find_browser", lambda: None)
    result, _ = rotary_campaign_result(tmp_path / "campaign")
    app = AccelrigApp(device="sim://still?seed=1&pace=fast&seconds=2", refresh_interval=0.05, profile_dir=tmp_path)
    async with app.run_test(size=(120, 40)) as pilot:
        await wait_for(pilot, lambda: app.session is not None)
        app.push_screen(CampaignScreen(result, DEVICE))
        await wait_for(pilot, lambda: isinstance(app.screen, CampaignScreen) and app.screen.query_one("#campaign-plot"))
        screen = app.screen
        plot = screen.query_one("#campaign-plot")
        assert plot.x_label == "test number" and "counts per m/s²" in plot.title
        values = sorted(v for s in plot.series for v in s.y)
        assert values == sorted(t_s["value"] for t in result.details["tests"] for t_s in t["sensitivity"].values())
        await pilot.press("c")
        await fill_conditions(pilot, operator="J. Roux")
        await wait_for(pilot, lambda: isinstance(app.screen, PathScreen))
        assert app.screen.query_one("#path").value.endswith("sim-0042-rotary-certificate.html")
        await pilot.press("enter")
        await wait_for(pilot, lambda: screen.certificate_path is not None, timeout=60)
        page = screen.certificate_path.read_text(encoding="utf-8")
        assert "Group results" in page and "J. Roux" in page
        # the item calibrated names the device the campaign screen was given, beside the campaign and its file
        # (newcomer 14 #7: a live campaign's certificate had no chip, range or connection)
        item = page.split("Item calibrated")[1].split("<h2>")[0]
        assert "<th>Identity</th>" in item and DEVICE["identity"] in item and "<td>±4 g</td>" in item
        assert "<th>Campaign file</th>" in item


def test_the_certificate_form_asks_for_the_report_command_s_conditions_in_its_words():
    """One field per condition flag of `accelrig report`, the flag's help as the field's text."""
    import argparse

    from accelrig.commands import report
    from accelrig.report.conditions import CONDITION_SETTINGS

    parser = argparse.ArgumentParser()
    report.register(parser.add_subparsers(), None)
    command = parser._subparsers._group_actions[0].choices["report"]
    helps = {action.option_strings[0]: action.help.replace("%%", "%") for action in command._actions
             if action.option_strings}
    conditions = ("--number", "--customer", "--customer-reference", "--operator", "--approved-by", "--location", "--temperature",
                  "--humidity")
    assert {s.flag: s.help for s in CONDITION_SETTINGS} == {flag: helps[flag] for flag in conditions}
