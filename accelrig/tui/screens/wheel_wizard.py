"""The tilted-wheel wizard: drives accelrig.procedures.wheel.WheelProcedure.

Asks the measured radius (and tilt, when known; blank = estimated), tells
the operator to spin the wheel and let it coast, shows the turns counted and
the speed as the procedure reports them, plots the procedure's speed trace
(one full-turn speed every half turn) so the coast-down shows as it happens,
says when enough data are in, then fits in a worker and opens the results.
r starts again from a new spin.
"""

from __future__ import annotations

from textual import on, work
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Vertical
from textual.screen import ModalScreen
from textual.widgets import Input, Label, Static

from accelrig.procedures.wheel import WheelProcedure
from accelrig.tui.screens.legacy_wizard import LegacyWizard
from accelrig.tui.widgets.plot import LinePlot, Series


def parse_optional_float(text: str, what: str, low: float, high: float) -> float | None:
    """'' -> None (estimate it); otherwise a number within [low, high] or ValueError with a message."""
    text = text.strip()
    if not text:
        return None
    try:
        value = float(text)
    except ValueError:
        raise ValueError(f"{what} {text!r} is not a number") from None
    if not low <= value <= high:
        raise ValueError(f"{what} {value:g} is outside {low:g} .. {high:g}")
    return value


class WheelSetupScreen(ModalScreen[tuple[float | None, float | None] | None]):
    """The rig geometry the operator measured."""

    BINDINGS = [Binding("escape", "cancel", "Cancel")]

    def compose(self) -> ComposeResult:
        with Vertical(classes="dialog"):
            yield Label("Distance from the wheel axis to the sensor, m (blank: estimate it):")
            yield Input(placeholder="e.g. 0.28", id="radius")
            yield Label("Tilt of the wheel axis from vertical, degrees (blank: estimate it):")
            yield Input(placeholder="e.g. 45", id="tilt")
            yield Static("[dim]enter starts, escape cancels[/dim]", id="setup-status")

    @on(Input.Submitted)
    def submitted(self, event: Input.Submitted) -> None:
        if event.input.id == "radius":
            self.query_one("#tilt", Input).focus()
            return
        values = {}
        for field, what, low, high in (("radius", "radius", 0.01, 10.0), ("tilt", "tilt", 0.0, 89.0)):
            box = self.query_one(f"#{field}", Input)
            try:
                values[field] = parse_optional_float(box.value, what, low, high)
            except ValueError as exc:
                self.query_one("#setup-status", Static).update(f"[red]{exc}[/]")
                box.focus()  # straight back to the field to fix
                return
        self.dismiss((values["radius"], values["tilt"]))

    def action_cancel(self) -> None:
        self.dismiss(None)


class WheelWizard(LegacyWizard):
    wizard_title = "tilted wheel calibration"
    capture_name = "wheel"
    progress_label = "turns"
    BINDINGS = [Binding("r", "restart", "Start again")]

    def __init__(self, session):
        super().__init__(session)
        self.radius: float | None = None
        self.tilt_deg: float | None = None

    def make_procedure(self) -> WheelProcedure:
        info = (self.session or self.app.session).info
        meta = {k: v for k, v in info.to_dict().items() if k != "extra"}
        return WheelProcedure(radius=self.radius, tilt_deg=self.tilt_deg, meta=meta)

    def compose_body(self) -> ComposeResult:
        yield Static("", id="wheel-geometry")
        yield Static("turns: waiting for rotation", id="wheel-turns")
        yield Static("speed: -", id="wheel-speed")
        yield LinePlot("wheel speed (rad/s)", x_label="s", id="speed-plot")

    def begin(self) -> None:
        self.ask_geometry()

    @work(exclusive=True, group="wheel-setup")
    async def ask_geometry(self) -> None:
        answer = await self.app.push_screen_wait(WheelSetupScreen())
        if answer is None:
            self.app.pop_screen()
            return
        self.radius, self.tilt_deg = answer
        self.query_one("#wheel-geometry", Static).update(
            "radius " + (f"{self.radius:g} m" if self.radius is not None else "estimated")
            + "   tilt " + (f"{self.tilt_deg:g} deg" if self.tilt_deg is not None else "estimated"))
        self.start()

    def show_events(self, events: list) -> None:
        speed_seen = False
        for event in events:
            if event.turns is not None:
                self.query_one("#wheel-turns", Static).update(event.message)
            if event.speed is not None:
                self.query_one("#wheel-speed", Static).update(event.message)
                speed_seen = True
        if speed_seen:  # the procedure recomputed its speed trace at this look
            times, speeds = self.procedure.speed_trace()
            self.query_one("#speed-plot", LinePlot).set_series([Series(times, speeds, "yellow")])

    def action_restart(self) -> None:
        if self.computing:
            return
        if self.recorder is not None:
            self.recorder.close()
        self.query_one("#speed-plot", LinePlot).set_series([])
        self.query_one("#wheel-turns", Static).update("turns: waiting for rotation")
        self.query_one("#wheel-speed", Static).update("speed: -")
        self.start()
