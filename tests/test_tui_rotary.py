"""The rotary bench wizard end to end on sim://rotary: each step's sensitivity matches the truth."""




from accelrig.sim.rigs.rotary import true_sensitivity  # noqa: E402
from accelrig.tui.app import AccelrigApp  # noqa: E402
from accelrig.tui.screens.dialogs import PathScreen  # noqa: E402
from accelrig.tui.screens.rotary_wizard import CampaignScreen, RotaryWizard  # noqa: E402
from tui_support import async_test, open_wizard, wait_for  # noqa: E402

# realtime: a step is recorded from the moment the operator presses space, as on a real bench
# (a pace=fast source would have run out before the first key press); 900 s outlasts the test on a loaded
# machine (60 s could end before the second capture, as a finite source ending between keys failed CI once)
DEVICE = "sim://rotary?seed=2&range=8&rate=1000&seconds=900"


@async_test
async def test_rotary_steps_by_keystroke_to_the_campaign_report(tmp_path):
    app = AccelrigApp(device=DEVICE, refresh_interval=0.05, profile_dir=tmp_path)
    async with app.run_test(size=(80, 24)) as pilot:
        await open_wizard(pilot, "rotary")
        # the simulated bench runs its one setting (5 Hz, 34 degrees): two repeats of 2 s.
        # (fields filled directly: at realtime each Pilot key press waits for an idle process)
        for field, value in (("radius", "0.170"), ("tangential", "x"), ("radial", "y"), ("plan", "5:34"),
                             ("repeats", "2"), ("seconds", "2")):
            app.screen.query_one(f"#setting-{field}").value = value
        app.screen.query_one("#setting-seconds").focus()
        await pilot.press("enter")
        await wait_for(pilot, lambda: isinstance(app.screen, RotaryWizard) and app.screen.procedure is not None
                       and app.screen.session is not None)
        wizard = app.screen
        assert "Set the motor to 5 Hz, 34 degrees" in str(wizard.query_one("#instruction").render())
        await pilot.press("space")
        await wait_for(pilot, lambda: len(wizard.procedure.results) == 1)
        await pilot.press("space")
        await wait_for(pilot, lambda: isinstance(app.screen, CampaignScreen) and app.screen.query("#campaign-3"))
        await pilot.pause(0.2)  # let the screen finish mounting before the app closes
        campaign = app.screen
        # one amplitude (two repeats of 5:34): no linearity line, left out of the budget and warned
        assert "linearity not evaluated" in str(campaign.query_one("#campaign-warnings").render())
        assert "span only" in str(campaign.query_one("#campaign-warnings").render())
        budget = campaign.query_one("#campaign-1")
        assert budget.row_count == 2 and "left out" in budget.get_row_at(0)
        # the budget's u_c is Table 2's combination of the contributions shown, as in the saved report
        entry = campaign.report.details["per_axis"]
        entry = entry[next(iter(entry))]["x"]["budget"]
        assert budget.get_row_at(0)[5] == f"{100 * entry['combined_standard_uncertainty']:.3f}"
        assert campaign.query_one("#campaign-0").row_count == 4   # 2 steps x 2 axes
        # numbered as the wizard numbered the steps (from 1), the device named, each step's recording traced
        assert [campaign.query_one("#campaign-0").get_row_at(i)[0] for i in range(4)] == ["1", "1", "2", "2"]
        # ? here tells how to read the campaign (it said "Connect a device (c)", and c writes the certificate)
        await pilot.press("question_mark")
        await wait_for(pilot, lambda: app.screen is not campaign)
        guide = str(app.screen.query_one("#help-intro").render())
        assert "Rotary bench: the campaign" in guide and "c writes the certificate" in guide
        assert "Connect a device" not in guide
        await pilot.press("escape")
        await wait_for(pilot, lambda: app.screen is campaign)
        # S and its u rounded together, as on every screen (was "416.324" beside "1.2")
        from accelrig.result import format_value

        row = campaign.query_one("#campaign-0").get_row_at(0)
        step = campaign.report.details["tests"][0]["sensitivity"][row[3]]
        assert tuple(row[5:7]) == format_value(step["value"], step["uncertainty"]) and len(row[6]) <= 4
        identity = app.session.info.identity
        assert campaign.report.details["campaign"] == f"{identity}: live session"
        records = campaign.report.details["records"]
        assert [r["test"] for r in records] == [1, 2] and all(r["recording_hash"].startswith("sha256:")
                                                               and r["samples"] >= 2000 for r in records)
        from accelrig.report.html import render_html
        from accelrig.report.source import from_result
        from accelrig.tui.screens.results import rotary_views

        (view,) = rotary_views(from_result(campaign.report))
        assert sorted({float(x) for series in view.series for x in series.x}) == [1.0, 2.0]   # as the table
        certificate = render_html(from_result(campaign.report))
        assert "Recordings of the tests" in certificate and records[1]["recording_hash"] in certificate
        # dated by the first test, as a person reads a time (2026-01-15 08:00 UTC)
        import re

        from accelrig.report.html import _when

        text = re.sub(r"<[^>]+>", "", certificate)
        assert "Date of calibration" in text and f"Date of calibration{_when(records[0]['captured'])}" in text
        # the report is saved as Markdown
        await pilot.press("s")
        await wait_for(pilot, lambda: isinstance(app.screen, PathScreen))
        await pilot.press("enter")
        await wait_for(pilot, lambda: campaign.saved_path is not None)
        report = campaign.saved_path.read_text()
        assert report.startswith("# Rotary bench campaign") and "linearity not evaluated" in report
        truth = true_sensitivity(app.session.info.truth)
        results = [result for _, result in wizard.procedure.results]
    assert len(results) == 2
    for result in results:
        for axis, s in result.sensitivity.items():
            assert abs(s.value - truth[axis]) < 4 * s.uncertainty, (axis, s.value, truth[axis], s.uncertainty)
