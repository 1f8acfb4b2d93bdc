"""The static six-face wizard: the generic wizard on accelrig.procedures.static.procedure.StaticProcedure.

What it adds to the generic wizard: the face grid (which faces are done,
which one is held, with its progress, and a suggestion for the next), the
held pose's own progress bar, r for the procedure's 'redo' (asking which
face), and 'still missing: ...' when c is pressed early.  Settings, events
('hold still', 'motion detected', 'captured'), the fit in a worker and the
results come from the generic wizard.
"""

from __future__ import annotations

from textual import on
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical
from textual.screen import ModalScreen
from textual.widgets import Label, OptionList, ProgressBar, Static
from textual.widgets.option_list import Option

from accelrig.procedures.static.procedure import StaticProcedure
from accelrig.tui.screens.wizard import ProcedureWizard
from accelrig.tui.widgets.faces import FaceGrid


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


class StaticWizard(ProcedureWizard):
    procedure_class = StaticProcedure
    ACTION_KEYS = {"r": "redo"}
    progress_label = "faces"

    def compose_body(self) -> ComposeResult:
        yield FaceGrid(id="faces")
        yield Static("", id="pose-state")
        with Horizontal(classes="bar-row"):
            yield Label("this pose", classes="bar-label")
            yield ProgressBar(total=1.0, show_eta=False, id="pose-progress")

    def show_procedure(self, events: list) -> None:
        faces = self.procedure.faces
        self.query_one("#faces", FaceGrid).show(faces)
        self.query_one("#pose-progress", ProgressBar).update(progress=faces["hold_fraction"])
        if faces["still"]:
            state = (f"[green]● still[/]: {faces['current_face'] or 'not flat'} down, held "
                     f"{faces['held_seconds']:.1f} of {self.procedure.hold:g} s")
        elif faces["missing"]:
            state = "[yellow]◌ moving[/]: put the next face down and hold still"
        else:
            state = "[green]all six faces done[/]: c computes again, r takes a face again"
        self.query_one("#pose-state", Static).update(
            f"{state}   faces {faces['n_done']}/6   poses {faces['n_poses']}")

    async def action_arguments(self, action: str) -> dict | None:
        done = self.procedure.faces_done   # the only action is redo: which face?
        if not done:
            self.set_instruction("no face is done yet: nothing to redo")
            return None
        face = await self.app.push_screen_wait(RedoScreen(done))
        return None if face is None else {"face": face}

    def not_ready_text(self) -> str:
        return f"still missing: {', '.join(self.procedure.missing_faces)} (any order)"
