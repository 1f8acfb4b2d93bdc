"""The fleet screen: the devices publishing to an MQTT broker, live and read-only.

The same table as ``accelrig fleet`` (``daemon.fleet.rows`` and ``cells``), kept live by one
subscription to the retained status and meta messages (``daemon.fleet.FleetWatcher``); the
table is redrawn every ``interval`` seconds, so "last seen" ages while a device is silent.
Nothing is published: the screen only reads.
"""

from __future__ import annotations

from dataclasses import dataclass

from rich.markup import escape
from textual import work
from textual.app import ComposeResult
from textual.binding import Binding
from textual.screen import Screen
from textual.widgets import Header, Static

from accelrig.errors import AccelrigError
from accelrig.tui.widgets.keys import KeyFooter
from accelrig.tui.widgets.table import FittedTable


@dataclass
class FleetOptions:
    """Where the fleet is and how to log in (from ``accelrig tui --broker ...``)."""

    broker: str
    site: str | None = None
    prefix: str = "accelrig"
    username: str | None = None
    password: str | None = None
    ca_file: str | None = None
    recalibrate_days: float | None = None


class FleetScreen(Screen):
    BINDINGS = [Binding("r", "refresh_now", "Refresh now"), Binding("escape", "back", "Back")]

    def __init__(self, options: FleetOptions, interval: float = 1.0):
        super().__init__()
        self.options = options
        self.interval = interval
        self.watcher = None
        self.connect_error: str | None = None
        self.connecting = False       # a connect is under way (an unanswered address can take long)
        self.login_needed = False     # the broker refused the login: not tried again (it would be in vain)
        self.table_rows: list[dict] = []

    def compose(self) -> ComposeResult:
        yield Header()
        yield Static(f"fleet at {escape(self.options.broker)}: connecting ...", id="fleet-title")
        yield FittedTable(self.priority(), id="fleet-devices")
        yield Static("", id="fleet-note")
        yield KeyFooter()

    def help_text(self) -> str:
        return ("[b]The fleet[/b]: every device publishing to the broker, from its retained status and meta "
                "messages, redrawn every second (the same table as [b]accelrig fleet[/b]).  'last seen' ages while "
                "a device is silent; [b]offline[/b] is the last will of a daemon that went away; 'spooled' counts "
                "blocks a daemon keeps on disk until the broker takes them.  This screen only reads.")

    def priority(self) -> list[int]:
        from accelrig.daemon.fleet import priority

        return priority(self.options.recalibrate_days)

    def on_mount(self) -> None:
        self.sub_title = "fleet (read-only)"
        self.start_connect()
        self.set_interval(self.interval, self.action_refresh_now)

    def start_connect(self) -> None:
        if not self.connecting:
            self.connecting = True
            self.connect()

    @work(thread=True, group="fleet-connect")
    def connect(self) -> None:
        """Subscribe off the UI thread; a broker that cannot be reached is tried again at the next refresh."""
        from accelrig.daemon.fleet import FleetWatcher

        o = self.options
        try:
            watcher = FleetWatcher(o.broker, site=o.site, prefix=o.prefix, username=o.username, password=o.password,
                                   ca_file=o.ca_file).start()
        except AccelrigError as exc:
            self.app.call_from_thread(self._set_error, str(exc))
            return
        self.app.call_from_thread(self._set_watcher, watcher)

    def _set_error(self, message: str) -> None:
        self.connecting = False
        self.connect_error = message
        if self.is_attached:
            self.show_error()   # tried again at the next refresh, not at once: no tight loop of attempts

    def _set_watcher(self, watcher) -> None:
        self.connecting = False
        if not self.is_attached:   # the screen was closed while connecting
            watcher.close()
            return
        self.watcher, self.connect_error = watcher, None
        self.action_refresh_now()

    def action_refresh_now(self) -> None:
        from accelrig.daemon.fleet import NO_DEVICES, cells, columns, notes, rows

        title = self.query_one("#fleet-title", Static)
        if self.watcher is not None and self.watcher.login_refused:
            self.refuse_login()
        if self.watcher is None:
            if self.connect_error is not None:
                self.show_error()
                if not self.login_needed:
                    self.start_connect()
            return
        self.table_rows = rows(self.watcher.snapshot(), recalibrate_days=self.options.recalibrate_days)
        state = ("[green]connected[/]" if self.watcher.connected
                 else f"[red]{escape(self.said(self.watcher.error or 'not connected'))}[/]")
        title.update(f"fleet at {self.where}: {state}, {len(self.table_rows)} devices (read-only; r refreshes, "
                     "escape goes back)")
        table = self.query_one("#fleet-devices", FittedTable)
        days = self.options.recalibrate_days
        table.show(columns(days), [cells(r, days) for r in self.table_rows],
                   [f"{r['site']}/{r['device']}" for r in self.table_rows])
        offline = [f"{r['site']}/{r['device']}" for r in self.table_rows if r["state"] == "offline"]
        lines = [NO_DEVICES] if not self.table_rows else [escape(line) for line in notes(self.table_rows)]
        if offline:
            lines.append(f"[yellow]offline:[/] {escape(', '.join(offline))} (the broker's last will: the daemon "
                         "went away)")
        if table.left_out:
            lines.append(f"[dim]left out at this width: {', '.join(table.left_out)} (accelrig fleet shows every "
                         "column)[/]")
        self.query_one("#fleet-note", Static).update("\n".join(lines))

    def said(self, message: str) -> str:
        """A watcher's message without the broker it starts with: the title already names it once."""
        from accelrig.daemon.wire import parse_broker

        for name in (str(parse_broker(self.options.broker)), self.options.broker):
            if message.startswith(name):
                return message[len(name):].lstrip(": ")
        return message

    @property
    def where(self) -> str:
        return escape(self.options.broker) + (f", site {escape(self.options.site)}" if self.options.site else "")

    def refuse_login(self) -> None:
        """The broker wants another login: stop asking (paho would retry with the same one for ever)
        and say how to give one."""
        watcher, self.watcher = self.watcher, None
        watcher.close()
        self.login_needed = True
        self.connect_error = watcher.refused

    def show_error(self) -> None:
        title = self.query_one("#fleet-title", Static)
        if not self.login_needed:
            title.update(f"[red]fleet at {self.where}: {escape(self.said(self.connect_error or ''))}[/] "
                         f"(trying again every {self.interval:g} s)")
            return
        given = ("the user name and password given were refused" if self.options.username
                 else "the broker asks for a login")
        title.update(f"[red]fleet at {self.where}: {escape(self.said(self.connect_error or ''))}[/]\n"
                     f"{given}; not tried again.  Quit and start with:  accelrig tui --broker "
                     f"{escape(self.options.broker)} --username NAME --password-file FILE  (or --password-env "
                     "VARIABLE; --ca-file CA.pem for mqtts://)")

    def on_unmount(self) -> None:
        if self.watcher is not None:
            self.watcher.close()

    def action_back(self) -> None:
        if len(self.app.screen_stack) > 2:
            self.app.pop_screen()
        else:
            self.app.exit()
