"""The static six-face wizard: drives accelrig.procedures.static_faces.StaticProcedure.

Faces can be taken in any order; the grid shows which are done, which one is
being held (with its progress) and a suggestion for the next.  'hold still',
'motion detected' and 'captured' come from the procedure's events as they
happen.  When all six are in, the fit runs (in a worker) and the results
open; r forgets a face so it can be taken again, c computes again.
"""

from __future__ import annotations

from textual import on, work
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical
from textual.screen import ModalScreen
from textual.widgets import Label, OptionList, ProgressBar, Static
from textual.widgets.option_list import Option

from accelrig.procedures.static_faces import StaticProcedure
from accelrig.tui.screens.legacy_wizard import LegacyWizard
from accelrig.tui.widgets.faces import FACES, FaceGrid
from accelrig.units import COUNT_MAX

PROBLEM_KINDS = {"too_short", "moved", "not_flat", "saturated", "motion"}
INSTRUCTION_KINDS = {"hold_still", "already_done", "captured", "complete", "redo"}


class RedoScreen(ModalScreen[str | None]):
    """Which face to take again."""

    BINDINGS = [Binding("escape", "cancel", "Cancel")]

    def __init__(self, done: list[str]):
        super().__init__()
        self.done = done

    def compose(self) -> ComposeResult:
        with Vertical(classes="dialog"):
            yield Label("Take which face again? (enter picks, escape cancels)")
            yield OptionList(*[Option(f"{face} down", id=face) for face in self.done], id="redo-faces")

    @on(OptionList.OptionSelected, "#redo-faces")
    def picked(self, event: OptionList.OptionSelected) -> None:
        self.dismiss(event.option.id)

    def action_cancel(self) -> None:
        self.dismiss(None)


class StaticWizard(LegacyWizard):
    wizard_title = "static six-face calibration"
    capture_name = "static"
    progress_label = "faces"
    BINDINGS = [
        Binding("r", "redo", "Redo a face"),
        Binding("c", "compute", "Compute"),
    ]

    def make_procedure(self) -> StaticProcedure:
        info = self.session_info
        # full scale in m/s^2, so the procedure can refuse clipped poses
        return StaticProcedure(rate=info.nominal_rate, full_scale=COUNT_MAX * info.scale)

    @property
    def session_info(self):
        return (self.session or self.app.session).info

    def opening_instruction(self) -> str:
        return "put the sensor down on any face and hold it still"

    def compose_body(self) -> ComposeResult:
        yield FaceGrid(id="faces")
        yield Static("", id="pose-state")
        with Horizontal(classes="bar-row"):
            yield Label("this pose", classes="bar-label")
            yield ProgressBar(total=1.0, show_eta=False, id="pose-progress")

    def begin(self) -> None:
        self.start()
        self.query_one("#faces", FaceGrid).show(self.procedure.progress)

    def handle(self, events: list) -> None:
        log_style = {kind: "bold red" for kind in PROBLEM_KINDS} | {"captured": "green", "complete": "bold green"}
        for event in events:
            self.log_event(event.message, log_style.get(event.kind, ""))
            if event.kind in PROBLEM_KINDS:
                self.set_instruction(event.message, "bold red")
            elif event.kind in INSTRUCTION_KINDS:
                self.set_instruction(event.message, "bold green" if event.kind in ("captured", "complete") else "bold")
        progress = self.procedure.progress
        self.query_one("#faces", FaceGrid).show(progress)
        self.query_one("#progress", ProgressBar).update(progress=progress["n_done"] / 6)
        self.query_one("#pose-progress", ProgressBar).update(progress=progress["hold_fraction"])
        if progress["still"]:
            state = (f"[green]● still[/]: {progress['current_face'] or 'not flat'} down, held "
                     f"{progress['held_seconds']:.1f} of {self.procedure.hold:g} s")
        elif progress["missing"]:
            state = "[yellow]◌ moving[/]: put the next face down and hold still"
        else:
            state = "[green]all six faces done[/]: c computes again, r takes a face again"
        self.query_one("#pose-state", Static).update(
            f"{state}   faces {progress['n_done']}/6   poses {progress['n_poses']}")
        if any(event.kind == "complete" for event in events):
            self.compute()

    def action_compute(self) -> None:
        missing = self.procedure.missing_faces if self.procedure is not None else FACES
        if missing:
            self.set_instruction(f"still missing: {', '.join(missing)} (any order)", "bold red")
            return
        self.compute()

    def action_redo(self) -> None:
        self.redo_flow()

    @work(exclusive=True, group="static-redo")
    async def redo_flow(self) -> None:
        done = self.procedure.faces_done if self.procedure is not None else []
        if not done:
            self.set_instruction("no face is done yet: nothing to redo")
            return
        face = await self.app.push_screen_wait(RedoScreen(done))
        if face is None:
            return
        self.handle(self.procedure.redo(face))
