"""The help screen: every key that works on the screen below, and what it does."""

from __future__ import annotations

from textual.app import App, ComposeResult
from textual.binding import Binding
from textual.containers import VerticalScroll
from textual.screen import ModalScreen, Screen
from textual.widgets import Input, Static

from accelrig.tui.widgets.keys import KeyFooter

INTRO = (
    "[b]accelrig[/b] calibrates 3-axis accelerometers.  Connect a device (c), watch it live, "
    "then run a calibration wizard (k).  Every wizard step can be cancelled (escape) "
    "and redone; captured data are kept if the device disconnects."
)


class HelpScreen(ModalScreen):
    BINDINGS = [Binding("escape,q,question_mark,f1", "close", "Close help")]

    def __init__(self, below: Screen):
        super().__init__()
        self.below = below

    def compose(self) -> ComposeResult:
        rows = []
        seen = set()
        for active in self.below.active_bindings.values():
            binding = active.binding
            if not binding.description or (binding.action, binding.description) in seen:
                continue
            if not isinstance(active.node, (Screen, App)):
                continue   # a list's or a field's own keys (Scroll Left, Page Right, ...): the line below says them
            seen.add((binding.action, binding.description))
            shown = binding.key_display or self.app.get_key_display(binding)
            if binding.action in ("help", "app.help") and isinstance(self.below.focused, Input):
                shown = "f1"   # in a text field (a form) ? types itself: the key that opened this help
            rows.append(f"  [b]{shown:>10}[/b]  {binding.description}")
        guide = getattr(self.below, "help_text", None)
        with VerticalScroll(id="help-box"):
            yield Static(guide() if guide is not None else INTRO, id="help-intro")
            yield Static("[b]Keys on this screen[/b]\n" + "\n".join(rows), id="help-keys")
            yield Static("[dim]tab / shift+tab move between fields, the arrows and page keys move in a list, "
                         "enter activates, the mouse works too.  escape closes this help.[/dim]")
        yield KeyFooter()   # the help's own key: the screen below's keys do not work while it is open

    def action_close(self) -> None:
        self.dismiss()
