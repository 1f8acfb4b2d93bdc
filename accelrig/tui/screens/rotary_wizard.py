"""The rotary bench wizard: RotaryProcedure on the contract, plus each axis's sensitivity per step as it
comes; the campaign report (repeatability, linearity, budget) at the end."""

from __future__ import annotations

import numpy as np
import yaml
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import VerticalScroll
from textual.screen import Screen
from textual.widgets import Footer, Header, Static

from accelrig.procedures.rotary.procedure import RotaryProcedure
from accelrig.result import to_plain
from accelrig.tui.screens.wizard import ProcedureWizard
from accelrig.tui.widgets.plot import LinePlot, Series

AXIS_STYLES = {"x": "red", "y": "green", "z": "dodger_blue1"}


class RotaryWizard(ProcedureWizard):
    procedure_class = RotaryProcedure
    ACTION_KEYS = {"space": "capture"}
    progress_label = "steps"

    def compose_body(self) -> ComposeResult:
        yield LinePlot("sensitivity per step (counts per m/s²)", x_label="step", id="sensitivity-plot")

    def show_procedure(self, events: list) -> None:
        if not any(e.kind == "captured" for e in events):
            return
        self.query_one("#sensitivity-plot", LinePlot).set_series([
            Series(np.arange(1, len(v) + 1, dtype=float), v, AXIS_STYLES.get(axis, "white"), axis, join=len(v) > 1)
            for axis, v in self.procedure.sensitivities().items()])

    def result_screen(self, result, recording) -> Screen:
        return CampaignScreen(result)


class CampaignScreen(Screen):
    """The campaign statistics of the steps recorded (repeatability, linearity, budget), as given."""

    BINDINGS = [Binding("escape", "close", "Close")]

    def __init__(self, result):
        super().__init__()
        self.report = result

    def compose(self) -> ComposeResult:
        yield Header()
        with VerticalScroll(id="results"):
            yield Static("[b]rotary bench: campaign report[/b] (values k = 1 unless labelled)")
            yield Static(yaml.safe_dump(to_plain(self.report.to_json_dict()), sort_keys=False, width=100),
                         id="campaign-report", markup=False)
        yield Footer()

    def on_mount(self) -> None:
        self.sub_title = "campaign"

    def action_close(self) -> None:
        self.app.pop_screen()
