"""The static six-face wizard: the generic wizard on accelrig.procedures.static.procedure.StaticProcedure.

What it adds to the generic wizard: the face grid (which faces are done,
which one is held, with its progress, and a suggestion for the next; after the six, the faces to
hold once more for the drift check, in three rounds), the
held pose's own progress bar, r for the procedure's 'redo' (asking which
face), and 'still missing: ...' when c is pressed early.  Settings, events
('hold still', 'motion detected', 'captured'), the fit in a worker and the
results come from the generic wizard.

With the model setting ``multi-position`` ("hold it still in any orientation") the face grid gives
way to the sphere map (``widgets.sphere``): where the captured poses point, how many distinct
orientations there are (closer than 10 degrees counts once) and how many more are needed; the
procedure computes once it has enough.
"""

from __future__ import annotations

from textual import on, work
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical
from textual.widgets import Label, OptionList, ProgressBar, Static
from textual.widgets.option_list import Option

from accelrig.estimation.gravity_fit import MULTI_ASKED_WHY
from accelrig.procedures.static.poses import LAST_ROUND_WHY
from accelrig.procedures.static.procedure import StaticProcedure
from accelrig.tui.rigs import ORIENTATIONS_DEMO_NOTE, ORIENTATIONS_DEMO_URL, plays_faces_only
from accelrig.tui.screens.dialogs import ChoiceScreen, Dialog
from accelrig.tui.screens.wizard import ProcedureWizard
from accelrig.tui.widgets.faces import FaceGrid
from accelrig.tui.widgets.keys import KeyFooter
from accelrig.tui.widgets.sphere import SphereMap

# under the grid or the map once a finite source (a recording, a scripted simulation) has delivered everything:
# "turn it to a new orientation" and "put +x down once more" would ask for poses that cannot come
ENDED_STATE = "[dim]the source ended: no more poses will come (the headline says what can still be done)[/]"


class RedoScreen(Dialog[str | None]):
    """Which face to take again."""

    BINDINGS = [Binding("escape", "cancel", "Cancel")]

    def __init__(self, done: list[str]):
        super().__init__()
        self.done = done

    def help_text(self) -> str:
        return ("[b]Take a face again[/b]\n\nThe face you pick is forgotten (every pose of it) and the wizard asks "
                "you to put it down again: for a face that was bumped or held on a tilted surface.  The arrows move, "
                "enter picks, escape keeps every face.")

    def compose(self) -> ComposeResult:
        with Vertical(classes="dialog"):
            yield Label("Take which face again? (enter picks, escape cancels)")
            yield OptionList(*[Option(f"{face} down", id=face) for face in self.done], id="redo-faces")
        yield KeyFooter()   # this dialog's keys, not the wizard's below it

    @on(OptionList.OptionSelected, "#redo-faces")
    def picked(self, event: OptionList.OptionSelected) -> None:
        self.dismiss(event.option.id)

    def action_cancel(self) -> None:
        self.dismiss(None)


class StaticWizard(ProcedureWizard):
    procedure_class = StaticProcedure
    ACTION_KEYS = {"r": "redo"}
    progress_label = "faces"
    faces_rig_accepted = False   # the operator chose to run multi-position on a six-face rig anyway

    def start(self) -> None:
        """As the generic wizard, but multi-position on a simulated rig that plays only the six faces would run
        out of orientations (6 of the 9 needed) at the end of its script: offer the rig that fits first."""
        if (self.values.get("model") == "multi-position" and plays_faces_only(self.url)
                and not self.faces_rig_accepted):
            self.offer_orientations_rig()
            return
        super().start()

    @work(exclusive=True, group="wizard-rig")
    async def offer_orientations_rig(self) -> None:
        question = (f"{self.url} plays the six faces: 6 distinct orientations, and the multi-position model "
                    "needs at least 9.")
        choices = [("demo", f"Use {ORIENTATIONS_DEMO_URL}: {ORIENTATIONS_DEMO_NOTE}"),
                   ("faces", "Keep this rig and calibrate on its faces (model auto)"),
                   ("anyway", "Use this device anyway (it will run out of orientations)")]
        choice = await self.app.push_screen_wait(ChoiceScreen(question, choices))
        if choice == "demo":
            if not await self.switch_device(ORIENTATIONS_DEMO_URL):
                return
        elif choice == "faces":
            self.values = {**self.values, "model": "auto"}
        elif choice == "anyway":
            self.faces_rig_accepted = True
        else:   # escape: back to the settings
            self.ask_settings()
            return
        self.start()

    def compose_body(self) -> ComposeResult:
        yield FaceGrid(id="faces")
        sphere = SphereMap("", id="sphere")
        sphere.display = False    # until the settings choose the any-orientation flow
        yield sphere
        yield Static("", id="pose-state")
        with Horizontal(classes="bar-row"):
            yield Label("this pose", classes="bar-label")
            yield ProgressBar(total=1.0, show_eta=False, id="pose-progress")

    def check_action(self, action: str, parameters: tuple[object, ...]) -> bool | None:
        """Any orientation keeps every pose: 'redo a face' is not offered (hidden from the keys)."""
        if action == "procedure_action" and parameters == ("redo",) and self.procedure is not None:
            return not self.procedure.any_orientation
        return True

    def reset_body(self) -> None:
        """Faces or the sphere, as the settings chose, with the title and keys to match."""
        any_orientation = self.procedure.any_orientation
        self.sub_title = "multi-position static calibration" if any_orientation else self.procedure_class.title
        self.refresh_bindings()
        self.query_one("#faces", FaceGrid).display = not any_orientation
        self.query_one("#sphere", SphereMap).display = any_orientation
        self.query(".bar-label").last().update("orientations" if any_orientation else self.progress_label)

    def show_procedure(self, events: list) -> None:
        faces = self.procedure.faces
        self.query_one("#pose-progress", ProgressBar).update(progress=faces["hold_fraction"])
        if self.procedure.any_orientation:
            orientations = self.procedure.orientations
            self.query_one("#sphere", SphereMap).show(orientations)
            state = (f"[green]● still[/]: held {faces['held_seconds']:.1f} of {self.procedure.hold:g} s"
                     if faces["still"] else ENDED_STATE if self.source_ended
                     else "[yellow]◌ moving[/]: turn it to a new orientation and hold still")
            if not orientations["more"] and orientations["more_asked"] and not self.source_ended:
                asked = orientations["more_asked"]
                state += (f"; {asked} more orientation{'s' if asked != 1 else ''} asked, {MULTI_ASKED_WHY} "
                          "(c computes without)")
            self.query_one("#pose-state", Static).update(state)
            return
        self.query_one("#faces", FaceGrid).show(faces)
        if faces["still"]:
            state = (f"[green]● still[/]: {faces['current_face'] or 'not flat'} down, held "
                     f"{faces['held_seconds']:.1f} of {self.procedure.hold:g} s")
        elif self.source_ended:
            state = ENDED_STATE
        elif faces["missing"]:
            state = "[yellow]◌ moving[/]: put the next face down and hold still"
        elif faces["again_missing"] and faces.get("again_round") == 3:
            state = (f"[yellow]last round[/]: put {', '.join(faces['again_missing'])} down a third time, "
                     f"{LAST_ROUND_WHY} (c computes without)")
        elif faces["again_missing"] and faces.get("again_round") == 2:
            # the reason is in the log's line (OPPOSITE_ROUND_WHY): with it this line takes three rows at 80 columns
            state = (f"[yellow]drift check, round 2 of 3[/]: put {', '.join(faces['again_missing'])} down once "
                     "more (the opposite faces), or c to compute without it")
        elif faces["again_missing"]:
            state = (f"[yellow]drift check[/]: put {', '.join(faces['again_missing'])} down once more "
                     "(either face of each axis), or c to compute without it")
        else:
            state = "[green]all six faces done, drift checked[/]: c computes again, r takes a face again"
        self.query_one("#pose-state", Static).update(
            f"{state}   faces {faces['n_done']}/6   holds {faces['n_poses']} of {faces['holds_asked']}")

    async def action_arguments(self, action: str) -> dict | None:
        if self.procedure.any_orientation:
            self.set_instruction("any orientation: every pose is kept, nothing to redo (hold more orientations)")
            return None
        done = self.procedure.faces_done   # the only action is redo: which face?
        if not done:
            self.set_instruction("no face is done yet: nothing to redo")
            return None
        face = await self.app.push_screen_wait(RedoScreen(done))
        return None if face is None else {"face": face}

    def not_ready_text(self) -> str:
        if self.procedure.any_orientation:
            o = self.procedure.orientations
            return (f"{o['n_distinct']} distinct orientations: {o['more']} more needed (turn the sensor at least "
                    f"{o['distinct_deg']:g} degrees from every pose held, between the faces too)")
        return f"still missing: {', '.join(self.procedure.missing_faces)} (any order)"
