"""The slider-crank wizard end to end on sim://slider-crank, keyboard only: the radius matches the truth."""

import yaml
from textual import events

from accelrig.recording import Recording, save_recording  # noqa: E402
from accelrig.sim.device import simulate  # noqa: E402
from accelrig.sim.rigs.slider_crank import SliderCrankRig  # noqa: E402
from accelrig.sim.sensor import SensorModel, SimClock  # noqa: E402
from accelrig.tui.app import AccelrigApp  # noqa: E402
from accelrig.tui.screens.calibrate import CalibrateMenu  # noqa: E402
from accelrig.tui.screens.dialogs import ChoiceScreen, SettingsForm  # noqa: E402
from accelrig.tui.screens.slider_wizard import SliderCrankWizard, VerificationScreen  # noqa: E402
from tui_support import async_test, wait_for  # noqa: E402

# an ideal sensor: the raw data are the truth, so no profile is needed to verify the stand itself
DEVICE = "sim://slider-crank?seed=5&range=8&pace=fast&rate=2048&steps=3,6,9&noise=0.08&clearance=0.0002&truth=ideal"


async def pick(pilot, options, key):
    """Highlight the option ``key`` of an OptionList and press enter."""
    options.highlighted = [options.get_option_at_index(i).id for i in range(options.option_count)].index(key)
    await pilot.press("enter")


async def start_wizard(app, pilot, wrong_kind=False):
    await wait_for(pilot, lambda: app.session is not None)
    await pilot.press("k")
    await wait_for(pilot, lambda: isinstance(app.screen, CalibrateMenu))
    await pick(pilot, app.screen.query_one("#wizards"), "slider-crank")
    if wrong_kind:   # the device is said to be of the wrong kind; the operator uses it anyway
        await wait_for(pilot, lambda: isinstance(app.screen, ChoiceScreen))
        assert "simulated still rig" in str(app.screen.query_one("#question").render())
        await pick(pilot, app.screen.query_one("#choices"), "anyway")
    await wait_for(pilot, lambda: isinstance(app.screen, SettingsForm))


@async_test
async def test_slider_crank_steps_fill_the_response_and_the_radius_matches_the_truth():
    app = AccelrigApp(device=DEVICE, refresh_interval=0.05)
    async with app.run_test(size=(80, 24)) as pilot:
        await start_wizard(app, pilot)
        await pilot.press(*"0.00635", "down", *"0.0353", "down", *"0.0002", "down", *"3,6,9", "enter")
        await wait_for(pilot, lambda: isinstance(app.screen, VerificationScreen))
        wizard = app.screen_stack[-2]
        assert isinstance(wizard, SliderCrankWizard)
        assert wizard.recorder.reader.lost_total == 0
        # a word per key in the footer (it fits 80 columns); the whole description is in ?
        assert [wizard._bindings.key_to_bindings[k][0].description for k in ("space", "x", "v")] == [
            "capture", "skip", "verify"]
        assert "skip the step due (its speed is left out" in wizard.help_text()
        verification = app.screen.verification.details
        assert [round(s["frequency_hz"]["value"]) for s in verification["steps"]] == [3, 6, 9]
        screen = app.screen
        await wait_for(pilot, lambda: screen.query_one("#steps").row_count == 3)   # filled once mounted
        # each value rounded with its u, as on every screen (was amplitude "20.3" beside u "0.003")
        from accelrig.result import format_value

        table = screen.query_one("#steps")
        row, step = dict(zip(table.columns, table.get_row_at(0), strict=True)), verification["steps"][0]
        shown = {table.columns[key].label.plain: row[key] for key in table.columns}
        assert (shown["amplitude"], shown["u"]) == format_value(step["amplitude"]["value"],
                                                                step["amplitude"]["uncertainty"])
        assert (shown["radius mm"], shown["u mm"]) == format_value(step["radius_m"]["value"] * 1e3,
                                                                   step["radius_m"]["uncertainty"] * 1e3)
        # at 80 columns the table fits whole (it was 3 cells too wide and scrolled sideways): the model's
        # amplitude, which the plot draws, is left out, and the line under it says so (written after the table's
        # layout: waited for, it was still empty when read at once under load)
        await wait_for(pilot, lambda: "left out" in str(screen.query_one("#steps-left-out").render()))
        assert table.virtual_size.width <= table.size.width
        assert list(shown) == ["step", "Hz", "amplitude", "u", "radius mm", "u mm", "k for U", "flags"]
        # (said once the table has its width: it fits again after the screen mounted it)
        await wait_for(pilot, lambda: "left out at this width: model (s saves every column)" in str(
            screen.query_one("#steps-left-out").render()))
        assert verification["verdict"] in str(app.screen.query_one("#verdict").render())
        # ? tells how to read the verification (it said "Connect a device (c)", a key this screen does not have)
        await pilot.press("question_mark")
        await wait_for(pilot, lambda: app.screen is not screen)
        guide = str(app.screen.query_one("#help-intro").render())
        assert "Slider-crank verification" in guide and "Connect a device" not in guide
        await pilot.press("escape")
        await wait_for(pilot, lambda: app.screen is screen)
        # the step table's k, the clearance flag's and the verdict's are told apart under the table
        meaning = str(screen.query_one("#verification-k").render())
        assert "k for U (per step):" in meaning and "k (in clearance):" in meaning
        assert f"k = {verification['radius_k']:.2f}" in meaning
        radius = app.screen.verification.parameters["radius"]
        truth = app.session.info.truth["rig"]
        # two plots, as on the results screen: the amplitude against its band, then the radius per step
        plot = screen.query_one("#verification-plot")
        assert plot.title.startswith("first-harmonic amplitude") and "(1/2, n: next)" in plot.title
        await pilot.press("n")
        assert plot.title.startswith("crank radius per step (mm)")
    # the radius seen in the motion is the stand's effective radius (inside the clearance), within 4 u
    assert abs(radius.value - truth["effective_radius"]) < 4 * radius.uncertainty
    assert verification["verdict"] == "holds"


@async_test
async def test_a_bad_profile_is_refused_and_a_device_without_step_marks_asks_for_space():
    app = AccelrigApp(device="sim://still?seed=1&pace=fast&seconds=2", refresh_interval=0.05)
    async with app.run_test(size=(80, 24)) as pilot:
        await start_wizard(app, pilot, wrong_kind=True)
        # a profile that cannot be read is refused in the setup, naming the problem
        await pilot.press(*"0.006", "down", *"0.035", "down", "down", "down", "down", "down", *"nope.yaml", "enter")
        status = app.screen.query_one("#setup-status")
        await wait_for(pilot, lambda: "nope.yaml" in str(status.render()))
        await pilot.press(*["backspace"] * len("nope.yaml"), "enter")
        await wait_for(pilot, lambda: isinstance(app.screen, SliderCrankWizard))
        wizard = app.screen
        assert "Press space to capture 2 s" in wizard.procedure.instruction()
        assert not wizard.procedure.marked
        # the 2 s source ends before any step: the headline says so and what can still be done
        await wait_for(pilot, lambda: "source ended" in str(wizard.query_one("#instruction").render()))
        headline = str(wizard.query_one("#instruction").render())
        assert "v: verify with the steps taken so far" in headline and "w writes" in headline
        # capturing needs samples that will never come: refused at once, nothing waits forever
        await pilot.press("space")
        await wait_for(pilot, lambda: "needs new samples" in str(wizard.query_one("#instruction").render()))
        assert not wizard.procedure.capture.armed


# A real rig without step marks, played back at its own pace (looping, so the test need not
# catch the first pass): a slider-crank recording whose step channel was dropped.  Each step runs
# STEP_SECONDS after a SETTLE ramp; the test presses space while the motor runs steadily, as an
# operator would, and CAPTURE seconds are taken from that moment.
# STEP_SECONDS leaves 3.4 s between the earliest key press and the latest one whose capture still ends before the
# next ramp: under load 30 a capture began over 0.5 s after the point the test had judged steady, and with 2.5 s
# steps (0.9 s of room) it crossed into the next step's ramp ([3, 7, 9] Hz; 5 of 11 runs failed so).
STEPS = (3.0, 6.0, 9.0)
SETTLE, STEP_SECONDS, CAPTURE, RATE = 0.3, 5.0, 1.0, 1000.0
SEGMENT = SETTLE + STEP_SECONDS


def unmarked_recording(path):
    rig = SliderCrankRig(steps=STEPS, step_seconds=STEP_SECONDS, settle=SETTLE, clearance=0.0002,
                         radius_offset=0.00012)
    rec = simulate(rig, SensorModel(range_g=8.0), SimClock(nominal_rate=RATE), seed=7)
    assert "step" in rec.channels
    save_recording(Recording(rec.t, rec.acc, rec.units, {}, {"rate": RATE}), path)
    return rig


@async_test
async def test_space_captures_each_step_of_a_device_without_step_marks(tmp_path):
    rig = unmarked_recording(tmp_path / "unmarked.csv")
    url = f"replay://{tmp_path / 'unmarked.csv'}?pace=realtime&block=50&loop=1"
    app = AccelrigApp(device=url, refresh_interval=0.05)
    async with app.run_test(size=(80, 24)) as pilot:
        await start_wizard(app, pilot)
        # (fields filled and submitted directly: at realtime each Pilot key press waits about 2 s for
        # an idle process, and the first step would be gone by then)
        for field, value in (("crank_radius", "0.00635"), ("rod_length", "0.0353"), ("clearance", "0.0002"),
                             ("speeds", "3,6,9"), ("seconds", f"{CAPTURE:g}")):
            app.screen.query_one(f"#setting-{field}").value = value
        await app.screen.query_one("#setting-profile").action_submit()
        await wait_for(pilot, lambda: isinstance(app.screen, SliderCrankWizard) and app.screen.recorder is not None)
        wizard = app.screen
        assert not wizard.procedure.marked and "Press space to capture 1 s" in str(wizard.query_one("#instruction").render())

        def steady(index):
            """Step ``index``'s steady run, with room for the whole capture, holds both what the wizard has read
            and what the device has delivered: the capture starts at the first sample the wizard reads after the
            key, somewhere between the two.  (On a loaded machine the wizard's reads lag the stream by a second or
            more; judged from what it had read alone, the capture began in the next step's ramp: [3, 7, 9] Hz.)"""
            def inside(samples):
                into = (samples / RATE) % (SEGMENT * len(STEPS)) - index * SEGMENT
                return SETTLE + 0.1 <= into <= SEGMENT - CAPTURE - 0.5

            return inside(wizard.recorder.samples) and inside(wizard.session.stats().samples)

        def response_points():
            series = wizard.query_one("#fr-plot").series
            return series[1].x.size if len(series) > 1 else 0

        for index in range(len(STEPS)):
            await wait_for(pilot, lambda index=index: steady(index))
            # the key goes straight to the app, as a terminal's would: Pilot's press first waits for an idle
            # process (up to seconds while a real-time source streams), and the stream moves on meanwhile
            app.post_message(events.Key("space", " "))
            if index < len(STEPS) - 1:
                await wait_for(pilot, lambda index=index: len(wizard.procedure.steps) == index + 1)
                # the response plot fills in as the steps are taken (drawn once the pump's events reach the
                # screen, which can come after the step is counted in the pump's thread)
                await wait_for(pilot, lambda index=index: response_points() == index + 1)
        await wait_for(pilot, lambda: isinstance(app.screen, VerificationScreen))
        verification = app.screen.verification.details
        radius = app.screen.verification.parameters["radius"]
        assert wizard.recorder.reader.lost_total == 0
    assert [round(s["frequency_hz"]["value"]) for s in verification["steps"]] == [3, 6, 9]
    # each step is the capture's seconds of steady running after the key press
    assert all(abs(s["n_samples"] - CAPTURE * RATE) <= 2 and not s["speed_unsteady"] for s in verification["steps"])
    assert abs(radius.value - rig.effective_radius) < 4 * radius.uncertainty
    assert verification["verdict"] == "holds"


@async_test
async def test_a_profile_for_another_range_is_refused_as_on_the_command_line_unless_forced(tmp_path):
    """The same check as `verify slider-crank --profile` (device, chip, range), with the same override."""
    from accelrig.cli import main

    static, profile = tmp_path / "static.csv", tmp_path / "two-g.yaml"
    assert main(["record", "sim://static?seed=5&pace=fast&rate=200", "-o", str(static)]) == 0   # +-2 g
    assert main(["calibrate", "static", str(static), "-o", str(profile)]) == 0
    app = AccelrigApp(device=DEVICE.replace("&truth=ideal", ""), refresh_interval=0.05)   # the same part at +-8 g
    async with app.run_test(size=(80, 24)) as pilot:
        await start_wizard(app, pilot)
        form = app.screen
        for field, value in (("crank_radius", "0.00635"), ("rod_length", "0.0353"), ("clearance", "0.0002"),
                             ("speeds", "3,6,9"), ("profile", str(profile))):
            form.query_one(f"#setting-{field}").value = value
        await form.query_one("#setting-profile").action_submit()
        status = form.query_one("#setup-status")
        await wait_for(pilot, lambda: "range but the data were taken at +-8 g" in str(status.render()))
        assert isinstance(app.screen, SettingsForm)
        form.query_one("#setting-force").value = "yes"
        await form.query_one("#setting-force").action_submit()
        await wait_for(pilot, lambda: isinstance(app.screen, VerificationScreen))
        warnings = app.screen.verification.warnings
        await pilot.pause(0.2)
    assert any(w.startswith("forced: ") and "+-2 g range" in w for w in warnings)
    # the override was this run's decision: the next operator's form starts without it
    from accelrig.tui.app import settings_file

    kept = yaml.safe_load(settings_file().read_text())["slider-crank"]
    assert kept["profile"] == str(profile) and "force" not in kept
