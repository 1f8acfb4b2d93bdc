"""The slider-crank wizard end to end on sim://slider-crank, keyboard only: the radius matches the truth."""

import asyncio
import functools

import pytest

pytest.importorskip("textual")
pytest.importorskip("accelrig.procedures.slider_crank", reason="the slider-crank procedure is not installed")

from accelrig.tui.app import AccelrigApp  # noqa: E402
from accelrig.tui.screens.calibrate import CalibrateMenu  # noqa: E402
from accelrig.tui.screens.slider_wizard import SliderCrankWizard, SliderSetupScreen, VerificationScreen  # noqa: E402

# an ideal sensor: the raw data are the truth, so no profile is needed to verify the stand itself
DEVICE = "sim://slider-crank?seed=5&range=8&pace=fast&rate=2048&steps=3,6,9&noise=0.08&clearance=0.0002&truth=ideal"


def async_test(fn):
    @functools.wraps(fn)
    def run(*args, **kwargs):
        return asyncio.run(fn(*args, **kwargs))

    return run


async def wait_for(pilot, condition, timeout=30.0):
    loop = asyncio.get_running_loop()
    deadline = loop.time() + timeout
    while not condition():
        if loop.time() > deadline:
            raise AssertionError("timed out waiting for the app")
        await pilot.pause(0.05)


async def start_wizard(app, pilot):
    await wait_for(pilot, lambda: app.session is not None)
    await pilot.press("k")
    await wait_for(pilot, lambda: isinstance(app.screen, CalibrateMenu))
    menu = app.screen.query_one("#wizards")
    menu.highlighted = [menu.get_option_at_index(i).id for i in range(menu.option_count)].index("slider-crank")
    await pilot.press("enter")
    await wait_for(pilot, lambda: isinstance(app.screen, SliderSetupScreen))


@async_test
async def test_slider_crank_steps_fill_the_response_and_the_radius_matches_the_truth():
    app = AccelrigApp(device=DEVICE, refresh_interval=0.05)
    async with app.run_test(size=(80, 24)) as pilot:
        await start_wizard(app, pilot)
        await pilot.press(*"0.00635", "enter", *"0.0353", "enter", *"0.0002", "enter", *"3,6,9", "enter", "enter")
        await wait_for(pilot, lambda: isinstance(app.screen, VerificationScreen))
        wizard = app.screen_stack[-2]
        assert isinstance(wizard, SliderCrankWizard)
        assert wizard.reader.lost_total == 0
        verification = app.screen.verification
        assert [round(s.frequency_hz.value) for s in verification.steps] == [3, 6, 9]
        assert app.screen.query_one("#steps").row_count == 3
        assert verification.verdict in str(app.screen.query_one("#verdict").render())
        truth = app.session.info.extra["truth"]["rig"]
    # the radius seen in the motion is the stand's effective radius (inside the clearance), within 4 u
    assert abs(verification.radius_m.value - truth["effective_radius"]) < 4 * verification.radius_m.uncertainty
    assert verification.verdict == "holds"


@async_test
async def test_a_device_without_step_marks_is_refused_with_a_message():
    app = AccelrigApp(device="sim://still?seed=1&pace=fast&seconds=2", refresh_interval=0.05)
    async with app.run_test(size=(80, 24)) as pilot:
        await start_wizard(app, pilot)
        # a profile that cannot be read is refused in the setup, naming the problem
        await pilot.press(*"0.006", "enter", *"0.035", "enter", "enter", "enter", *"nope.yaml", "enter")
        status = app.screen.query_one("#setup-status")
        await wait_for(pilot, lambda: "nope.yaml" in str(status.render()))
        await pilot.press(*["backspace"] * len("nope.yaml"), "enter")
        await wait_for(pilot, lambda: isinstance(app.screen, SliderCrankWizard))
        await wait_for(pilot, lambda: "marks no motor steps" in str(app.screen.query_one("#instruction").render()))
        assert "accelrig verify slider-crank" in str(app.screen.query_one("#instruction").render())
