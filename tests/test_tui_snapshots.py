"""Snapshots of the main screens at fixed sizes.

The device is a seeded, finite simulation at pace=fast: the screens are taken
once it has ended, so every number and trace on them is deterministic.
Regenerate after an intended change with ``pytest --snapshot-update`` and look
at the SVGs before committing them.
"""

import asyncio
import re
from pathlib import Path

from accelrig.acquisition.session import State  # noqa: E402
from accelrig.tui.app import AccelrigApp  # noqa: E402
from accelrig.tui.screens.calibrate import CalibrateMenu  # noqa: E402
from tui_support import choose, drawn, wait_for  # noqa: E402

FINITE = "sim://still?seed=1&pace=fast&seconds=10"
REPO = Path(__file__).resolve().parents[1]


async def until_ended(pilot):
    app = pilot.app
    loop = asyncio.get_running_loop()
    deadline = loop.time() + 60
    while app.session is None or app.session.stats().state != State.ENDED:
        assert loop.time() < deadline, "the simulated device did not end"
        await pilot.pause(0.05)
    # the refresh timer has drawn the final state (a fixed pause could end first on a loaded host): the stats
    # line says the source ended, and every other line comes from that same refresh
    await wait_for(pilot, lambda: "source ended" in str(app.screen.query_one("#stats-line").render()))
    await wait_for(pilot, lambda: drawn(app))


def test_live_80x24(snap_compare):
    assert snap_compare(AccelrigApp(device=FINITE, refresh_interval=0.05), terminal_size=(80, 24),
                        run_before=until_ended)


def test_live_120x40(snap_compare):
    assert snap_compare(AccelrigApp(device=FINITE, refresh_interval=0.05), terminal_size=(120, 40),
                        run_before=until_ended)


def test_help_80x24(snap_compare):
    async def open_help(pilot):
        from accelrig.tui.screens.help import HelpScreen

        await until_ended(pilot)
        await pilot.press("question_mark")
        await wait_for(pilot, lambda: isinstance(pilot.app.screen, HelpScreen) and drawn(pilot.app))

    assert snap_compare(AccelrigApp(device=FINITE, refresh_interval=0.05), terminal_size=(80, 24),
                        run_before=open_help)




def test_static_wizard_done_80x24(snap_compare):
    from accelrig.tui.screens.dialogs import SettingsForm
    from accelrig.tui.screens.results import ResultsScreen

    async def run_wizard(pilot):
        app = pilot.app
        loop = asyncio.get_running_loop()
        deadline = loop.time() + 120
        while app.session is None:
            await pilot.pause(0.05)
        await pilot.press("k")
        await wait_for(pilot, lambda: isinstance(pilot.app.screen, CalibrateMenu))   # enter goes to its list
        await pilot.press("enter")
        while not isinstance(app.screen, SettingsForm):
            assert loop.time() < deadline, "the settings form did not open"
            await pilot.pause(0.05)
        await pilot.press("enter")
        while not isinstance(app.screen, ResultsScreen):
            assert loop.time() < deadline, "the wizard did not finish"
            await pilot.pause(0.05)
        # the wizard computes while the last face is still held: the script plays on to its end (the fifteen
        # holds' result takes longer than that on a loaded host), so wait for it before the picture
        while app.session.stats().state != State.ENDED:
            assert loop.time() < deadline, "the simulated device did not end"
            await pilot.pause(0.05)
        await pilot.pause(0.3)
        await pilot.press("escape")   # the profile is not saved: it asks, and the result is discarded
        await choose(pilot, "discard")
        await wait_for(pilot, lambda: not isinstance(app.screen, ResultsScreen))   # back on the wizard
        # two live numbers depend on how many samples the last read took at pace=fast (the wizard stops reading
        # once it computes): the time the last face was held (4.0-4.6 s) and the samples captured. Pinned here so
        # the picture tests the layout, not the host's timing
        wizard = app.screen
        for selector, live, pinned in (("#pose-state", r"held \d+\.\d of", "held 4.0 of"),
                                       ("#wizard-stream", r"captured \d+ samples", "captured 17664 samples")):
            widget = wizard.query_one(selector)
            text = widget.content   # as given to update(), markup and all
            assert isinstance(text, str) and re.search(live, text), (selector, text)
            widget.update(re.sub(live, pinned, text))
        await wait_for(pilot, lambda: drawn(app))

    assert snap_compare(AccelrigApp(device="sim://static?seed=3&pace=fast", refresh_interval=0.05),
                        terminal_size=(80, 24), run_before=run_wizard)


def test_static_results_120x40(snap_compare):
    from accelrig.acquisition.driver import driver_for
    from accelrig.acquisition.recorder import record
    from accelrig.procedures.static.procedure import calibrate_static
    from accelrig.tui.screens.results import ResultsScreen

    with driver_for("sim://static?seed=3&pace=fast") as driver:
        recording = record(driver)
    result = calibrate_static(recording)
    # the fit's wall-clock time is the one figure that differs between runs
    result.quality["fit_seconds"] = 0.01

    async def show(pilot):
        await until_ended(pilot)
        screen = ResultsScreen(result, recording, None)
        pilot.app.push_screen(screen)
        await wait_for(pilot, lambda: pilot.app.screen is screen and screen.query_one("#parameters").row_count > 0
                       and drawn(pilot.app))

    assert snap_compare(AccelrigApp(device=FINITE, refresh_interval=0.05), terminal_size=(120, 40), run_before=show)


def test_fleet_without_a_broker_80x24(snap_compare):
    """The fleet screen when nothing listens at the broker's address (port 1: no service there)."""
    from accelrig.tui.screens.fleet import FleetOptions

    async def refused(pilot):
        loop = asyncio.get_running_loop()
        deadline = loop.time() + 60
        while "refused" not in str(pilot.app.screen.query_one("#fleet-title").render()):
            assert loop.time() < deadline, "the refusal was not shown"
            await pilot.pause(0.05)
        await pilot.pause(0.2)

    assert snap_compare(AccelrigApp(fleet=FleetOptions("mqtt://127.0.0.1:1"), refresh_interval=0.05),
                        terminal_size=(80, 24), run_before=refused)


def until_rows(table: str, rows: int):
    """Wait until the screen's ``table`` shows ``rows`` rows."""
    async def shown(pilot):
        loop = asyncio.get_running_loop()
        deadline = loop.time() + 60
        while pilot.app.screen.query_one(table).row_count < rows:
            assert loop.time() < deadline, f"{table} did not show {rows} rows"
            await pilot.pause(0.05)
        await pilot.pause(0.2)

    return shown


def _daemon_device(name, state, rate, samples, profile, error=None):
    return {"name": name, "url": "i2c://1/0x68", "state": state, "error": error, "identity": None,
            "nominal_rate": 2048.0, "delivered_rate": rate, "measured_rate": rate, "delivered": samples,
            "written": samples, "dropped": 0, "missing": 12, "gaps": 3, "connects": 2, "failed_connects": 0,
            "bytes_written": samples * 6, "segments": 4, "profile": profile, "output": "raw",
            "last_sample": None, "seconds_since_data": 0.1}


def test_daemon_screen_80x24(snap_compare, tmp_path):
    """Wider than 80 columns: the columns that fit whole, the most important first, and the others named;
    what is wrong with a device (recording raw, cannot connect) under the table, wrapped."""
    from accelrig.daemon.status import StatusServer

    status = {"daemon": {"pid": 4242, "started": "2026-11-24T01:00:00Z", "uptime": 86400.0,
                         "config": "/etc/accelrig/daemon.yaml", "output": "/var/lib/accelrig", "reloads": 0,
                         "ready": True},
              "devices": [
                  _daemon_device("pier-3", "streaming", 2048.1, 176947200,
                                 "/var/lib/accelrig/profiles/i2c-0x68-a1/20261001T120000Z-static.yaml"),
                  _daemon_device("pier-4", "recording raw", 2047.9, 176947100, "none",
                                 "recording raw: no profile for 'i2c-0x69-b2' in the store /var/lib/accelrig/profiles "
                                 "(it is empty); calibrate the device and file its profile (accelrig profile add "
                                 "PROFILE), then reload the daemon (SIGHUP or systemctl reload) to get calibrated "
                                 "channels; `accelrig profile apply` calibrates what was recorded raw"),
                  _daemon_device("deck", "waiting", 0.0, 5000, "none", "cannot connect: /dev/ttyUSB0: no such file")]}
    server = StatusServer(tmp_path / "s.sock", lambda: status)
    server.start()

    try:
        assert snap_compare(AccelrigApp(daemon_socket=tmp_path / "s.sock"), terminal_size=(80, 24),
                            run_before=until_rows("#daemon-devices", 3))
    finally:
        server.stop()


def test_fleet_table_80x24(snap_compare, monkeypatch):
    """The fleet's table at 80 columns: whole columns, the others named, each daemon's error under it."""
    from datetime import UTC, datetime, timedelta

    from accelrig.daemon import fleet
    from accelrig.tui.screens.fleet import FleetOptions

    class Watcher:   # the retained messages a broker would hand over, ages fixed against the clock
        connected, error, refused, login_refused = True, None, None, False

        def __init__(self, *args, **kwargs):
            pass

        def start(self):
            return self

        def close(self):
            pass

        def snapshot(self):
            now = datetime.now(UTC)

            def ago(seconds):
                return (now - timedelta(seconds=seconds)).isoformat().replace("+00:00", "Z")

            def device(state, rate, profile_days, host="gateway-north", error=None):
                meta = {"nominal_rate": 2048.0, "host": host}
                if profile_days is not None:
                    meta["profile"] = {"procedure": "static", "method": "vp", "created": ago(profile_days * 86400)}
                status = {"state": state, "utc": ago(3), "delivered_rate": rate, "gaps": 2, "missing": 0,
                          "host": host, "error": error, "mqtt": {"spooled": 0, "dropped_samples": 0}}
                return {"status": status, "meta": meta}

            return {("north", "pier-3"): device("streaming", 2048.1, 41),
                    ("north", "pier-4"): device("recording raw", 2047.9, None, error=(
                        "recording raw: no profile for 'i2c-0x69-b2' in the store /var/lib/accelrig/profiles (it is "
                        "empty); calibrate the device and file its profile (accelrig profile add PROFILE), then "
                        "reload the daemon (SIGHUP or systemctl reload) to get calibrated channels")),
                    ("south", "deck"): device("offline", None, 400, host="gateway-south")}

    monkeypatch.setattr(fleet, "FleetWatcher", Watcher)
    assert snap_compare(AccelrigApp(fleet=FleetOptions("mqtt://gateway.example", recalibrate_days=180),
                                    refresh_interval=0.05), terminal_size=(80, 24),
                        run_before=until_rows("#fleet-devices", 3))


def test_flash_plan_80x24(snap_compare):
    """The flash dialog at 80x24: the plan's first lines (the register table) in sight, the rest scrolling
    above the question and the buttons."""
    from rich.markup import escape

    from accelrig.acquisition.driver import driver_for
    from accelrig.profiles import load_profile
    from accelrig.profiles.flash import format_plan, plan_flash
    from accelrig.tui.screens.dialogs import DIALOG_TEXT_WIDTH, ConfirmScreen

    profile = load_profile(REPO / "profiles" / "example-static_faces-vp.yaml")
    profile.data["device"].update(identity="i2c-sim-mpu9250-seed3", driver="i2c-sim", chip="mpu9250", who_am_i=0x71)
    with driver_for("i2c-sim://mpu9250?rig=still&rate=200&seed=3") as chip:
        plan = plan_flash(chip, profile)

    async def ask(pilot):
        await until_ended(pilot)
        pilot.app.push_screen(ConfirmScreen("Write to the device?", "Write", "Cancel",
                                            details=escape(format_plan(plan, width=DIALOG_TEXT_WIDTH))))
        await wait_for(pilot, lambda: isinstance(pilot.app.screen, ConfirmScreen) and drawn(pilot.app))

    assert snap_compare(AccelrigApp(device=FINITE, refresh_interval=0.05), terminal_size=(80, 24), run_before=ask)
