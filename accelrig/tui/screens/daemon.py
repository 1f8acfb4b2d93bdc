"""The daemon screen: a running daemon's devices, live, read-only (it only reads the status socket)."""

from __future__ import annotations

from pathlib import Path

from textual import work
from textual.app import ComposeResult
from textual.binding import Binding
from textual.screen import Screen
from textual.widgets import DataTable, Header, Static

from accelrig.daemon.status import COLUMNS, device_row, query
from accelrig.errors import AccelrigError
from accelrig.tui.widgets.keys import KeyFooter


class DaemonScreen(Screen):
    """Polls the status socket every ``interval`` seconds; the table follows the daemon's devices."""

    BINDINGS = [Binding("r", "refresh_now", "Refresh now"), Binding("escape", "back", "Back")]

    def __init__(self, socket_path: str | Path, interval: float = 1.0):
        super().__init__()
        self.socket_path = Path(socket_path)
        self.interval = interval
        self.last_status: dict | None = None

    def compose(self) -> ComposeResult:
        yield Header()
        yield Static(f"daemon status socket {self.socket_path} (read-only)", id="daemon-title")
        yield DataTable(id="daemon-devices", show_cursor=False, zebra_stripes=True)
        yield Static("", id="daemon-errors")
        yield KeyFooter()

    def on_mount(self) -> None:
        table = self.query_one("#daemon-devices", DataTable)
        for key, title in COLUMNS:
            table.add_column(title, key=key)
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
        table = self.query_one("#daemon-devices", DataTable)
        table.clear()
        for device in status["devices"]:
            row = device_row(device)
            table.add_row(*(row[key] for key, _ in COLUMNS), key=device["name"])
        errors = [f"{d['name']}: {d['error']}" for d in status["devices"] if d.get("error")]
        self.query_one("#daemon-errors", Static).update("\n".join(errors))

    def action_back(self) -> None:
        if len(self.app.screen_stack) > 2:
            self.app.pop_screen()
        else:
            self.app.exit()
