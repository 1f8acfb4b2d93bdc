"""The home screen: the connected device, live."""

from __future__ import annotations

from textual import work
from textual.app import ComposeResult
from textual.binding import Binding
from textual.screen import Screen
from textual.widgets import Header

from accelrig.tui.screens.calibrate import CalibrateMenu
from accelrig.tui.screens.connect import ConnectScreen
from accelrig.tui.screens.dialogs import PathScreen
from accelrig.tui.screens.fleet import FleetOptions, FleetScreen
from accelrig.tui.widgets.keys import KeyFooter
from accelrig.tui.widgets.live import LiveView


class LiveScreen(Screen):
    BINDINGS = [
        Binding("c", "connect", "Connect"),
        Binding("k", "calibrate", "Calibrate"),
        Binding("p", "pause", "Pause view"),
        Binding("m", "fleet", "Fleet (MQTT)"),
    ]

    def __init__(self):
        super().__init__()
        self.paused = False

    def compose(self) -> ComposeResult:
        yield Header()
        yield LiveView(id="live")
        yield KeyFooter()

    def on_mount(self) -> None:
        self.refresh_view()
        self.set_interval(self.app.refresh_interval, self.refresh_view)

    def refresh_view(self) -> None:
        if self.paused:
            return
        self.query_one(LiveView).refresh_from(self.app.session, self.app.connect_error)

    def session_changed(self) -> None:
        self.refresh_view()

    def action_pause(self) -> None:
        self.paused = not self.paused
        self.sub_title = "view paused (p resumes)" if self.paused else ""

    def action_connect(self) -> None:
        self.app.push_screen(ConnectScreen())

    def action_calibrate(self) -> None:
        self.app.push_screen(CalibrateMenu())

    def action_fleet(self) -> None:
        """The fleet screen: of the broker given with --broker, else of one the operator names."""
        if self.app.fleet is not None:
            self.app.push_screen(FleetScreen(self.app.fleet))
        else:
            self.ask_broker()

    @work(exclusive=True, group="fleet-broker")
    async def ask_broker(self) -> None:
        from accelrig.daemon.wire import parse_broker
        from accelrig.errors import AccelrigError

        url = await self.app.push_screen_wait(PathScreen(
            "MQTT broker of the fleet (mqtt://HOST[:PORT], or mqtts:// for TLS; for a user name and password "
            "start with: accelrig tui --broker URL --username NAME --password-file FILE):", "mqtt://localhost:1883",
            verb="Open"))
        if url is None:
            return
        try:
            parse_broker(url)
        except AccelrigError as exc:
            self.notify(str(exc), title="not a broker URL", severity="error", timeout=8)
            return
        self.app.push_screen(FleetScreen(FleetOptions(url)))
