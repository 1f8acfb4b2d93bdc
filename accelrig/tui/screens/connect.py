"""Connect: pick a driver and device (found or typed), see identity, range and delivered rate."""

from __future__ import annotations

from rich.markup import escape
from textual import on, work
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical
from textual.screen import Screen
from textual.widgets import Button, Header, Input, Label, OptionList, Static
from textual.widgets.option_list import Option

from accelrig.acquisition.driver import load_drivers
from accelrig.acquisition.session import Session
from accelrig.errors import AccelrigError
from accelrig.profiles.flash import flash_url_profile
from accelrig.tui.rigs import fits, suggested_urls
from accelrig.tui.widgets.keys import KeyFooter

URL_HINT = "sim://static?seed=1   replay://run.csv   i2c://1/0x68   serial:///dev/ttyUSB0   ble://AA:BB:..."


class ConnectScreen(Screen):
    """``wizard``: the procedure name of the wizard that asked for a device; what fits it is listed first."""

    BINDINGS = [
        Binding("escape", "back", "Back"),
        # f5 works in the URL field too, where r types itself (a URL may hold an r); r, outside it
        Binding("f5", "rescan", "Rescan"),
        Binding("r", "rescan", "Rescan", show=False),
    ]

    def __init__(self, wizard: str | None = None):
        super().__init__()
        self.wizard = wizard

    def help_text(self) -> str:
        """What ? shows here: how to connect, and the URL forms."""
        back = "the wizard" if self.wizard else "the live view"
        return ("[b]Connect a device[/b]\n"
                "The arrows move in the list of devices found, and enter connects to the one highlighted.  Or "
                "tab to the URL field, type a device URL and press enter (in the field ? types itself: F1 opens "
                f"this help).  F5 scans again, as r does outside the URL field (Bluetooth takes a few seconds).  "
                f"escape goes back to {back}.\n"
                f"URLs: {escape(URL_HINT)}; sim://RIG plays a simulated rig (static, wheel, slider-crank, rotary, "
                "still), replay://FILE plays a recording.  The box at the bottom shows the connected device: "
                "its identity, range and the rate it delivers.")

    def compose(self) -> ComposeResult:
        yield Header()
        with Vertical(id="connect-box"):
            yield Label("Devices found (enter connects; F5 scans again, including BLE):")
            yield OptionList(id="found")
            yield Label("Device URL:")
            with Horizontal(id="url-row"):
                yield Input(placeholder=URL_HINT, id="url")
                yield Button("Connect", id="do-connect", variant="primary")
            yield Static("", id="connect-status")
            yield Static("", id="connected-device")
        yield KeyFooter()

    def on_mount(self) -> None:
        self.query_one("#url", Input).value = self.app.device
        self.scan()
        self.show_device()
        self.set_interval(0.5, self.show_device)

    @work(thread=True, exclusive=True, group="scan")
    def scan(self) -> None:
        """Ask every installed driver what it can find (a BLE scan takes a few seconds)."""
        self.app.call_from_thread(self._set_status, "scanning ...")
        found: list[tuple[str, str]] = list(suggested_urls(self.wizard))
        problems: list[str] = []
        try:
            drivers = load_drivers()
        except AccelrigError as exc:
            self.app.call_from_thread(self._set_status, str(exc))
            return
        for scheme in sorted(drivers):
            cls = drivers[scheme]
            try:
                for url in cls.discover():
                    if url not in (known for known, _ in found):
                        found.append((url, cls.description))
            except AccelrigError as exc:
                problems.append(f"{scheme}://: {exc}")
        self.app.call_from_thread(self._show_found, found, problems)

    def _show_found(self, found: list[tuple[str, str]], problems: list[str]) -> None:
        options = self.query_one("#found", OptionList)
        options.clear_options()
        if self.wizard is not None:   # what certainly fits the wizard first (a stable sort keeps the order)
            found = sorted(found, key=lambda item: not fits(self.wizard, item[0]))
        options.add_options([Option(f"{url}  [dim]{why}[/dim]", id=url) for url, why in found])
        # a driver that could not search (no Bluetooth here) is a note under the count, not an alarm
        self._set_status("\n".join([f"{len(found)} device(s) found", *(f"[dim]{escape(p)}[/dim]" for p in problems)]))

    def _set_status(self, text: str) -> None:
        self.query_one("#connect-status", Static).update(text)

    @on(OptionList.OptionSelected, "#found")
    def pick(self, event: OptionList.OptionSelected) -> None:
        """enter on a found device connects to it (one enter, as the label says); its URL stays in the field
        to be edited and connected again."""
        self.query_one("#url", Input).value = event.option.id
        self.connect()

    @on(Input.Submitted, "#url")
    @on(Button.Pressed, "#do-connect")
    def connect(self) -> None:
        url = self.query_one("#url", Input).value.strip()
        if not url:
            self._set_status("type a device URL first, e.g. sim://static")
            return
        self._set_status(f"connecting to {url} ...")
        self.open_device(url)

    @work(thread=True, exclusive=True, group="open")
    def open_device(self, url: str) -> None:
        try:
            session = Session.open_and_start(url, self.app.buffer_seconds, prepare=flash_url_profile)
        except AccelrigError as exc:
            self.app.call_from_thread(self._set_status, f"[red]cannot connect:[/] {exc}")
            return
        self.app.call_from_thread(self._connected, session)

    def _connected(self, session) -> None:
        self.app.use_session(session)
        self._set_status(f"[green]connected[/] to {session.url} (escape goes back"
                         + (" to the wizard)" if self.wizard else " to the live view)"))
        self.show_device()

    def show_device(self) -> None:
        session = self.app.session
        box = self.query_one("#connected-device", Static)
        if session is None or session.info is None:
            box.update("no device connected")
            return
        info = session.info
        stats = session.stats()
        box.update(
            f"[b]Connected:[/b] {info.url}\n"
            f"  driver {info.driver}   chip {info.chip}   identity {info.identity}"
            + (f"   WHO_AM_I 0x{info.who_am_i:02x}" if info.who_am_i is not None else "")
            + f"\n  range ±{info.range_g:g} g   nominal {info.nominal_rate:g} Hz   "
            f"delivered {stats.delivered_rate:.1f} Hz   state {stats.state.value}"
            + (f"\n  [red]{stats.last_error}[/]" if stats.last_error else "")
        )

    def action_rescan(self) -> None:
        self.scan()

    def action_back(self) -> None:
        self.dismiss()
