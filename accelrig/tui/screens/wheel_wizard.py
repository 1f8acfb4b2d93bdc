"""The tilted-wheel wizard: WheelProcedure on the contract, plus the turns and speed it reports and a live
plot of its speed trace (one full-turn speed every half turn), so the coast-down shows as it happens.
r starts again from a new spin."""

from __future__ import annotations

from textual.app import ComposeResult
from textual.binding import Binding
from textual.widgets import Static

from accelrig.procedures.wheel.procedure import WheelProcedure
from accelrig.tui.screens.wizard import ProcedureWizard
from accelrig.tui.widgets.plot import LinePlot, Series


class WheelWizard(ProcedureWizard):
    procedure_class = WheelProcedure
    progress_label = "turns"
    BINDINGS = [Binding("r", "restart", "Start again")]

    def compose_body(self) -> ComposeResult:
        yield Static("turns: waiting for rotation", id="wheel-turns")
        yield Static("speed: -", id="wheel-speed")
        yield LinePlot("wheel speed (rad/s)", x_label="time (s)", id="speed-plot")

    def reset_body(self) -> None:
        self.query_one("#wheel-turns", Static).update("turns: waiting for rotation")
        self.query_one("#wheel-speed", Static).update("speed: -")
        self.query_one("#speed-plot", LinePlot).set_series([])

    def show_procedure(self, events: list) -> None:
        for event in events:
            if "turns" in event.data:
                self.query_one("#wheel-turns", Static).update(event.message)
            if "speed" in event.data:  # the procedure recomputed its speed trace at this look
                self.query_one("#wheel-speed", Static).update(event.message)
                times, speeds = self.procedure.speed_trace()
                self.query_one("#speed-plot", LinePlot).set_series([Series(times, speeds, "yellow")])
