"""The accelrig Textual application: connect, live view, help, calibration wizards."""

from __future__ import annotations

from pathlib import Path

from textual import work
from textual.app import App
from textual.binding import Binding

from accelrig.acquisition.session import Session
from accelrig.errors import AccelrigError
from accelrig.profiles.flash import flash_url_profile
from accelrig.tui.screens.help import HelpScreen
from accelrig.tui.screens.live import LiveScreen

# With no hardware the TUI opens on a simulated static rig at the device's own pace,
# so a newcomer sees data flow at once.
DEFAULT_DEVICE = "sim://static"


class AccelrigApp(App):
    """Holds the one live Session; screens read it, the connect screen replaces it."""

    CSS_PATH = "accelrig.tcss"
    TITLE = "accelrig"
    SUB_TITLE = "accelerometer calibration"
    BINDINGS = [
        Binding("question_mark,f1", "help", "Help", key_display="?"),
        Binding("q", "quit", "Quit"),
    ]

    def __init__(self, device: str = DEFAULT_DEVICE, refresh_interval: float = 0.1,
                 profile_dir: str | Path | None = None, buffer_seconds: float = 30.0,
                 daemon_socket: str | Path | None = None):
        super().__init__()
        self.daemon_socket = daemon_socket  # set: watch a running daemon instead of opening a device
        self.device = device
        self.refresh_interval = refresh_interval
        self.profile_dir = Path(profile_dir) if profile_dir is not None else Path.cwd()
        self.buffer_seconds = buffer_seconds
        self.session: Session | None = None
        self.connect_error: str | None = None
        # What the operator last typed into each procedure's setup form (procedure name -> texts),
        # offered again the next time that wizard starts in this session of the app.
        self.setting_texts: dict[str, dict[str, str]] = {}

    def on_mount(self) -> None:
        if self.daemon_socket is not None:
            from accelrig.tui.screens.daemon import DaemonScreen

            self.push_screen(DaemonScreen(self.daemon_socket))
            return
        self.push_screen(LiveScreen())
        self.connect_to(self.device)

    @work(thread=True, exclusive=True, group="connect")
    def connect_to(self, url: str) -> None:
        """Open ``url`` off the UI thread (BLE and serial opens can take seconds)."""
        try:
            session = Session.open_and_start(url, self.buffer_seconds, prepare=flash_url_profile)
        except AccelrigError as exc:
            self.call_from_thread(self._connect_failed, url, str(exc))
            return
        self.call_from_thread(self.use_session, session)

    def _connect_failed(self, url: str, message: str) -> None:
        self.connect_error = f"{url}: {message}"
        self.notify(self.connect_error, title="cannot connect", severity="error", timeout=8)

    def use_session(self, session: Session) -> None:
        """Make ``session`` the live one (stopping the previous one)."""
        if self.session is not None and self.session is not session:
            self.session.stop()
        self.session = session
        self.device = session.url
        self.connect_error = None
        self.post_message_to_screens()

    def post_message_to_screens(self) -> None:
        for screen in self.screen_stack:
            if hasattr(screen, "session_changed"):
                screen.session_changed()

    def action_help(self) -> None:
        if not isinstance(self.screen, HelpScreen):
            self.push_screen(HelpScreen(self.screen))

    def on_unmount(self) -> None:
        if self.session is not None:
            self.session.stop()
