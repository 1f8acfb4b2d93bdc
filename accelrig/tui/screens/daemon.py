"""The daemon screen: a running daemon's devices, live, read-only (it only reads the status socket)."""

from __future__ import annotations

from pathlib import Path

from rich.markup import escape
from textual import work
from textual.app import ComposeResult
from textual.binding import Binding
from textual.screen import Screen
from textual.widgets import Header, Static

from accelrig.daemon.status import COLUMNS, PRIORITY, device_row, query
from accelrig.errors import AccelrigError
from accelrig.tui.widgets.keys import KeyFooter
from accelrig.tui.widgets.table import FittedTable


class DaemonScreen(Screen):
    """Polls the status socket every ``interval`` seconds; the table follows the daemon's devices."""

    BINDINGS = [Binding("r", "refresh_now", "Refresh now"), Binding("escape", "back", "Back")]

    def help_text(self) -> str:
        """What ? shows here (the app's opening text named keys that this screen does not have)."""
        return ("[b]A running daemon's devices[/b] (read-only, refreshed every second from its status socket)\n"
                "Each row: the device's state, delivered rate, samples delivered / written / dropped / missing, "
                "gaps, connects, megabytes written and the profile in use.  Under the table: what is wrong with "
                "each device, and the columns a narrow terminal leaves out (accelrig daemon status prints them "
                "all).  r refreshes now; escape goes back (or quits when the daemon is all this shows).")

    def __init__(self, socket_path: str | Path, interval: float = 1.0):
        super().__init__()
        self.socket_path = Path(socket_path)
        self.interval = interval
        self.last_status: dict | None = None

    def compose(self) -> ComposeResult:
        yield Header()
        yield Static(f"daemon status socket {self.socket_path} (read-only)", id="daemon-title")
        keys = [key for key, _ in COLUMNS]
        yield FittedTable([keys.index(key) for key in PRIORITY], id="daemon-devices")
        yield Static("", id="daemon-errors")
        yield KeyFooter()

    def on_mount(self) -> None:
        self.action_refresh_now()
        self.set_interval(self.interval, self.action_refresh_now)

    def action_refresh_now(self) -> None:
        self._poll()

    @work(thread=True, exclusive=True, group="daemon-status")
    def _poll(self) -> None:
        try:
            status = query(self.socket_path, timeout=2.0)
        except AccelrigError as exc:
            self.app.call_from_thread(self._show_error, str(exc))
            return
        self.app.call_from_thread(self._show, status)

    def _show_error(self, message: str) -> None:
        self.query_one("#daemon-title", Static).update(f"[b]no daemon[/b]: {message}")

    def _show(self, status: dict) -> None:
        self.last_status = status
        daemon = status["daemon"]
        self.query_one("#daemon-title", Static).update(
            f"daemon pid {daemon['pid']}, up {daemon['uptime']:.0f} s, config {daemon['config']}, "
            f"output {daemon['output']} (read-only)")
        table = self.query_one("#daemon-devices", FittedTable)
        rows = []
        for device in status["devices"]:
            row = device_row(device)
            if "/" in row["profile"]:   # a profile file: its name says which (the path is in daemon status)
                row["profile"] = Path(row["profile"]).name
            rows.append([row[key] for key, _ in COLUMNS])
        table.show([title for _, title in COLUMNS], rows, [d["name"] for d in status["devices"]])
        lines = [escape(f"{d['name']}: {d['error']}") for d in status["devices"] if d.get("error")]
        if table.left_out:
            lines.append(f"[dim]left out at this width: {', '.join(table.left_out)} (accelrig daemon status "
                         "shows every column)[/]")
        self.query_one("#daemon-errors", Static).update("\n".join(lines))

    def action_back(self) -> None:
        if len(self.app.screen_stack) > 2:
            self.app.pop_screen()
        else:
            self.app.exit()
