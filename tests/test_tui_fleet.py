"""The TUI's fleet screen against a real Mosquitto: the same table as 'accelrig fleet', live; reachable with
--broker and with the live screen's m; a broker that refuses says so in the screen."""

import os
import shutil

import pytest

from accelrig.daemon.fleet import cells, columns, rows
from accelrig.tui.app import AccelrigApp  # noqa: E402
from accelrig.tui.screens.dialogs import PathScreen  # noqa: E402
from accelrig.tui.screens.fleet import FleetOptions, FleetScreen  # noqa: E402
from mqtt_support import COLLECTOR_PASSWORD, COLLECTOR_USER, DAEMON_PASSWORD, DAEMON_USER
from tui_support import async_test, wait_for  # noqa: E402

pytestmark = pytest.mark.skipif(
    shutil.which("mosquitto") is None and not os.environ.get("CI"),
    reason="mosquitto is not installed (apt-get install mosquitto); CI installs it and runs these tests")


def publisher(broker, tmp_path, device: str, status: dict):
    """A device's real MQTT publisher (what the daemon runs), its status from ``status``."""
    from accelrig.daemon.config import MqttConfig
    from accelrig.daemon.mqtt import Publisher

    (tmp_path / "pw").write_text(DAEMON_PASSWORD)
    settings = MqttConfig(broker=broker.url, site="north", username=DAEMON_USER, password_file=str(tmp_path / "pw"),
                          status_seconds=0.2)
    pub = Publisher(settings, device, tmp_path / f"spool-{device}", lambda: dict(status), lambda line: None)
    pub.announce({"identity": f"sim-{device}", "nominal_rate": 500.0}, 0.0006, "",
                 {"calibration": {"procedure": "static", "method": "map"}})
    pub.start()
    return pub


def table_cells(screen) -> dict[str, list[str]]:
    table = screen.query_one("#fleet-devices")
    return {str(table.get_row_at(i)[0]): [str(c) for c in table.get_row_at(i)] for i in range(table.row_count)}


@async_test
async def test_fleet_screen_shows_the_fleet_table_live(broker, tmp_path):
    status = {"state": "streaming", "delivered_rate": 499.8, "gaps": 0, "missing": 0}
    pub_a = publisher(broker, tmp_path, "a", status)
    options = FleetOptions(broker.url, username=COLLECTOR_USER, password=COLLECTOR_PASSWORD, recalibrate_days=30)
    app = AccelrigApp(fleet=options, refresh_interval=0.05)
    try:
        async with app.run_test(size=(120, 30)) as pilot:
            await wait_for(pilot, lambda: isinstance(app.screen, FleetScreen)
                           and "north/a" in table_cells(app.screen))
            screen = app.screen
            table = screen.query_one("#fleet-devices")
            assert [str(c.label) for c in table.columns.values()] == columns(30)
            # the same cells as accelrig fleet's table, from the same rows ("last seen" ages between the two)
            expected = cells(rows(screen.watcher.snapshot(), recalibrate_days=30)[0], 30)
            shown = table_cells(screen)["north/a"]
            assert shown[:3] + shown[4:] == expected[:3] + expected[4:] and shown[3].endswith(" s ago")
            row = table_cells(screen)["north/a"]
            assert row[2] == "streaming" and row[4] == "499.8" and row[7] == "none"   # no profile created date
            # live: a change of state shows without a key
            status["state"] = "disconnected"
            await wait_for(pilot, lambda: table_cells(screen)["north/a"][2] == "disconnected")
            # a second device appears by itself
            pub_b = publisher(broker, tmp_path, "b", {"state": "streaming", "delivered_rate": 250.0})
            try:
                await wait_for(pilot, lambda: "north/b" in table_cells(screen))
            finally:
                pub_b.close()
            await wait_for(pilot, lambda: table_cells(screen)["north/b"][2] == "stopped")
            assert "connected" in str(screen.query_one("#fleet-title").render())
            # read-only: the screen's keys change nothing anywhere; escape leaves (it is the only screen)
            await pilot.press("r")
            await pilot.press("escape")
            await pilot.pause(0.2)
    finally:
        pub_a.close()


@async_test
async def test_m_on_the_live_screen_asks_for_the_broker_and_a_refusal_is_shown(broker):
    app = AccelrigApp(device="sim://still?seed=1&pace=fast&seconds=2", refresh_interval=0.05)
    async with app.run_test(size=(120, 30)) as pilot:
        await wait_for(pilot, lambda: app.session is not None)
        await pilot.press("m")
        await wait_for(pilot, lambda: isinstance(app.screen, PathScreen))
        app.screen.query_one("#path").value = "http://nowhere"
        await pilot.press("enter")
        await wait_for(pilot, lambda: not isinstance(app.screen, PathScreen))
        assert not isinstance(app.screen, FleetScreen)   # not a broker URL: told, nothing opened
        await pilot.press("m")
        await wait_for(pilot, lambda: isinstance(app.screen, PathScreen))
        app.screen.query_one("#path").value = broker.url   # no user name: this broker refuses anonymous clients
        await pilot.press("enter")
        await wait_for(pilot, lambda: isinstance(app.screen, FleetScreen))
        screen = app.screen
        await wait_for(pilot, lambda: "refused" in str(screen.query_one("#fleet-title").render()))
        # a login the m key cannot give: said, with the options that give one, and not asked again in vain
        await wait_for(pilot, lambda: "asks for a login" in str(screen.query_one("#fleet-title").render()))
        title = str(screen.query_one("#fleet-title").render())
        assert f"accelrig tui --broker {broker.url} --username NAME --password-file FILE" in title
        await pilot.pause(1.5)   # refreshed again: no new connection
        assert screen.watcher is None and not screen.connecting and "not tried again" in title
        await pilot.press("escape")
        await wait_for(pilot, lambda: not isinstance(app.screen, FleetScreen))


@async_test
async def test_a_refused_login_from_the_command_line_is_said_and_not_retried(broker):
    app = AccelrigApp(fleet=FleetOptions(broker.url, username=COLLECTOR_USER, password="wrong"),
                      refresh_interval=0.05)
    async with app.run_test(size=(120, 30)) as pilot:
        await wait_for(pilot, lambda: isinstance(app.screen, FleetScreen)
                       and "not tried again" in str(app.screen.query_one("#fleet-title").render()))
        title = str(app.screen.query_one("#fleet-title").render())
        assert "refused the connection" in title and "the user name and password given were refused" in title


@async_test
async def test_a_broker_that_is_not_there_is_said_and_tried_again_one_connect_at_a_time(tmp_path):
    from mqtt_support import free_port

    url = f"mqtt://127.0.0.1:{free_port()}"
    app = AccelrigApp(fleet=FleetOptions(url), refresh_interval=0.05)
    async with app.run_test(size=(120, 30)) as pilot:
        await wait_for(pilot, lambda: isinstance(app.screen, FleetScreen)
                       and "cannot connect" in str(app.screen.query_one("#fleet-title").render()))
        screen = app.screen
        assert str(screen.query_one("#fleet-title").render()).count(url) == 1   # named once, not again in the error
        await pilot.pause(2.5)   # refreshed twice more: tried again, never two connects at once
        assert "trying again" in str(screen.query_one("#fleet-title").render())
        running = [w for w in app.workers if w.group == "fleet-connect" and not w.is_finished]
        assert len(running) <= 1
        assert screen.query_one("#fleet-devices").row_count == 0
