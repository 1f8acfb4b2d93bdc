"""Pick a calibration procedure; only procedures this installation has are offered."""

from __future__ import annotations

import importlib

from textual import on
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Vertical
from textual.screen import Screen
from textual.widgets import Header, Label, OptionList, Static
from textual.widgets.option_list import Option

from accelrig.tui.widgets.keys import KeyFooter

# (key, title, procedure module the wizard drives, wizard screen "module:Class")
WIZARDS = (
    ("static", "Static faces: six or more still poses (no rig needed)",
     "accelrig.procedures.static.procedure", "accelrig.tui.screens.static_wizard:StaticWizard"),
    ("wheel", "Tilted wheel: spin it and let it coast",
     "accelrig.procedures.wheel.procedure", "accelrig.tui.screens.wheel_wizard:WheelWizard"),
    ("slider-crank", "Slider-crank stand: verify a calibration over motor speed steps",
     "accelrig.procedures.slider_crank.procedure", "accelrig.tui.screens.slider_wizard:SliderCrankWizard"),
    ("rotary", "Rotary bench: sensitivity per axis against the encoder",
     "accelrig.procedures.rotary.procedure", "accelrig.tui.screens.rotary_wizard:RotaryWizard"),
)


def available_wizards() -> list[tuple[str, str, str]]:
    """(key, title, screen path) of the wizards whose procedure is installed."""
    found = []
    for key, title, procedure_module, screen in WIZARDS:
        try:
            importlib.import_module(procedure_module)
        except ModuleNotFoundError as exc:
            if exc.name and procedure_module.startswith(exc.name):
                continue  # this procedure is not part of this installation
            raise
        found.append((key, title, screen))
    return found


def wizard_screen(path: str, *args, **kwargs):
    module_name, class_name = path.split(":")
    return getattr(importlib.import_module(module_name), class_name)(*args, **kwargs)


class CalibrateMenu(Screen):
    BINDINGS = [Binding("escape", "back", "Back")]

    def help_text(self) -> str:
        """What ? shows here: each wizard and what its rig is, so an operator picks the one that fits."""
        from rich.markup import escape

        from accelrig.tui.rigs import NEEDS

        lines = ["[b]Choose a calibration[/b]: the arrows move, enter starts the wizard on the connected device "
                 "(c on the live view connects another), escape goes back.  A device that cannot serve the "
                 "wizard is said, and the wizard offers its simulated rig."]
        for key, title, _ in available_wizards():
            needs = NEEDS.get(key)
            lines.append(f"[b]{escape(title)}[/b]" + (f": needs {escape(needs.motion)}; the simulated rig: "
                                                     f"{escape(needs.demo_note)}" if needs is not None else ""))
            if key == "static":
                lines.append("  A sensor that cannot sit on its faces: choose the model multi-position in the "
                             "static wizard's settings (12 orientations, any).")
        return "\n".join(lines)

    def compose(self) -> ComposeResult:
        yield Header()
        with Vertical(id="calibrate-box"):
            wizards = available_wizards()
            if wizards:
                yield Label("Choose a calibration (enter starts it):")
                yield OptionList(*[Option(title, id=key) for key, title, _ in wizards], id="wizards")
            else:
                yield Static("No calibration procedure is installed in this version of accelrig.")
            yield Static("", id="calibrate-status")
        yield KeyFooter()

    @on(OptionList.OptionSelected, "#wizards")
    def start(self, event: OptionList.OptionSelected) -> None:
        if not self.is_current:
            # A selection that arrives after this menu gave way to the wizard it started (an enter
            # typed quickly can reach the list twice in a terminal): one wizard, not two.
            return
        screens = {key: screen for key, _, screen in available_wizards()}
        session = self.app.session
        if session is None or session.info is None:
            self.query_one("#calibrate-status", Static).update("[red]connect a device first (c on the live view)[/]")
            return
        self.app.switch_screen(wizard_screen(screens[event.option.id], session))

    def action_back(self) -> None:
        self.app.pop_screen()
