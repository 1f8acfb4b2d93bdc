"""The accelrig Textual application: connect, live view, help, calibration wizards."""

from __future__ import annotations

import gc
from pathlib import Path

import yaml
from textual import work
from textual.app import App
from textual.binding import Binding
from textual.widgets import Input

from accelrig.acquisition.session import Session
from accelrig.errors import AccelrigError
from accelrig.files import atomic_write
from accelrig.profiles.flash import flash_url_profile
from accelrig.profiles.store import default_store_dir
from accelrig.tui.screens.help import HelpScreen
from accelrig.tui.screens.live import LiveScreen

# With no hardware the TUI opens on a simulated static rig at the device's own pace,
# so a newcomer sees data flow at once.
DEFAULT_DEVICE = "sim://static"


def settings_file() -> Path:
    """Where the setup forms' last values are kept between runs: beside the profile store."""
    return default_store_dir().parent / "tui-settings.yaml"


def load_setting_texts() -> dict[str, dict[str, str]]:
    """The forms' last values (procedure name -> field -> text); a missing or unreadable file is no memory."""
    try:
        data = yaml.safe_load(settings_file().read_text(encoding="utf-8"))
    except (OSError, yaml.YAMLError):
        return {}
    if not isinstance(data, dict):
        return {}
    return {str(name): {str(k): str(v) for k, v in texts.items()}
            for name, texts in data.items() if isinstance(texts, dict)}


class AccelrigApp(App):
    """Holds the one live Session; screens read it, the connect screen replaces it."""

    CSS_PATH = "accelrig.tcss"
    TITLE = "accelrig"
    SUB_TITLE = "accelerometer calibration"
    BINDINGS = [
        Binding("question_mark,f1", "help", "Help", key_display="?"),
        Binding("q", "quit", "Quit"),
        Binding("ctrl+q", "quit", "Quit", show=False, priority=True),
    ]

    def __init__(self, device: str = DEFAULT_DEVICE, refresh_interval: float = 0.1,
                 profile_dir: str | Path | None = None, buffer_seconds: float = 30.0,
                 daemon_socket: str | Path | None = None, fleet=None):
        super().__init__()
        self.daemon_socket = daemon_socket  # set: watch a running daemon instead of opening a device
        self.fleet = fleet                  # screens.fleet.FleetOptions: watch an MQTT fleet instead
        self.device = device
        self.refresh_interval = refresh_interval
        # None: profiles go into the store (accelrig.profiles.store), captures beside it
        self.profile_dir = Path(profile_dir) if profile_dir is not None else None
        self.buffer_seconds = buffer_seconds
        self.session: Session | None = None
        self._collector_frozen = False   # see use_session
        self.connect_error: str | None = None
        # What the operator last typed into each procedure's setup form (procedure name -> texts),
        # offered again the next time that wizard starts (kept in settings_file() between runs).
        self.setting_texts: dict[str, dict[str, str]] = load_setting_texts()

    @property
    def output_dir(self) -> Path:
        """Where captures and reports are offered to be written: --profile-dir, else the accelrig home."""
        return self.profile_dir if self.profile_dir is not None else default_store_dir().parent

    def remember_settings(self, procedure: str, texts: dict[str, str]) -> None:
        """Keep what was typed into ``procedure``'s form, for this run and the next (best effort: a
        read-only home only loses the memory, never the calibration)."""
        self.setting_texts[procedure] = dict(texts)
        path = settings_file()
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            text = yaml.safe_dump(self.setting_texts, sort_keys=True)
            atomic_write(path, lambda fh: fh.write(text), text=True)
        except (OSError, AccelrigError) as exc:
            self.notify(f"the form's values are not kept for the next run: {exc}", severity="warning")

    def unsaved_work(self) -> str | None:
        """What quitting now would lose (captured samples or a result neither written nor saved), or None."""
        for screen in self.screen_stack:
            unsaved = getattr(screen, "unsaved", None)
            if unsaved:
                return unsaved
        return None

    async def action_quit(self) -> None:
        """q / ctrl+q: asks first when captured data or a result would be lost (as escape in a wizard does)."""
        from accelrig.tui.screens.dialogs import ConfirmScreen

        if isinstance(self.screen, ConfirmScreen):
            return   # a question is open: it wants y or n
        unsaved = self.unsaved_work()
        if unsaved:
            self.ask_quit(unsaved)
            return
        self.exit()

    @work(exclusive=True, group="quit")
    async def ask_quit(self, unsaved: str) -> None:
        from accelrig.tui.screens.dialogs import ConfirmScreen

        if await self.push_screen_wait(ConfirmScreen(f"Quit? {unsaved}", "Quit", "Stay")):
            self.exit()

    def exit(self, *args, **kwargs) -> None:
        """Leave the app; each wizard's capture segments are finished first (they stay under captures/)."""
        for screen in self.screen_stack:
            close = getattr(screen, "close_recorder", None)
            if close is not None:
                close()
        super().exit(*args, **kwargs)

    def on_mount(self) -> None:
        if self.daemon_socket is not None:
            from accelrig.tui.screens.daemon import DaemonScreen

            self.push_screen(DaemonScreen(self.daemon_socket))
            return
        if self.fleet is not None:
            from accelrig.tui.screens.fleet import FleetScreen

            self.push_screen(FleetScreen(self.fleet))
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
        if not self._collector_frozen:
            # As record and the daemon do once the device streams: what is loaded by now (textual, numpy,
            # scipy, the driver: some 110 000 objects) stays for the app's life.  Out of the cyclic
            # collector's sight, a full collection in this thread takes a few ms instead of 60-130 ms,
            # during which the pump cannot poll (an MPU-9250 FIFO overflows after 85 ms at 1 kHz).
            gc.freeze()
            self._collector_frozen = True
        self.post_message_to_screens()

    def post_message_to_screens(self) -> None:
        for screen in self.screen_stack:
            if hasattr(screen, "session_changed"):
                screen.session_changed()

    def get_key_display(self, binding: Binding) -> str:
        """Help's key as it works now: in a text field ? types itself (a URL has one), so F1 is named."""
        if binding.action in ("help", "app.help") and isinstance(self.focused, Input):
            return "f1"
        return super().get_key_display(binding)

    def action_help(self) -> None:
        if not isinstance(self.screen, HelpScreen):
            self.push_screen(HelpScreen(self.screen))

    def on_unmount(self) -> None:
        if self.session is not None:
            self.session.stop()
        if self._collector_frozen:
            # a program (or a test) that goes on after the app gets its objects collected again
            gc.unfreeze()
            self._collector_frozen = False
