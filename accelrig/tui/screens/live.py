"""The home screen: the connected device, live."""

from __future__ import annotations

from textual.app import ComposeResult
from textual.binding import Binding
from textual.screen import Screen
from textual.widgets import Footer, Header

from accelrig.tui.screens.calibrate import CalibrateMenu
from accelrig.tui.screens.connect import ConnectScreen
from accelrig.tui.widgets.live import LiveView


class LiveScreen(Screen):
    BINDINGS = [
        Binding("c", "connect", "Connect"),
        Binding("k", "calibrate", "Calibrate"),
        Binding("p", "pause", "Pause view"),
    ]

    def __init__(self):
        super().__init__()
        self.paused = False

    def compose(self) -> ComposeResult:
        yield Header()
        yield LiveView(id="live")
        yield Footer()

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
