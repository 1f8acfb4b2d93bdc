"""Six face cells: done, being held (with its progress), still to do, or (after the six) to hold again,
then the opposite faces once more, then the first faces a third time (the drift check: held three times, a
face shows whether its offset drifted and in what shape; its opposite held twice lets the fit test the drift
between the holds)."""

from __future__ import annotations

from textual.app import ComposeResult
from textual.containers import Horizontal
from textual.widgets import Static

from accelrig.geometry import FACES


class FaceGrid(Horizontal):
    """Shows the static procedure's ``progress`` dict; holds no state of its own."""

    def compose(self) -> ComposeResult:
        for face in FACES:
            yield Static(face, id=f"face-{face.replace('+', 'p').replace('-', 'm')}", classes="face")

    def show(self, progress: dict) -> None:
        done = set(progress["faces_done"])
        # a face held to the end of its hold is captured: it shows as done, not "holding 100%" (the last face
        # of a run stays still while the result is computed)
        current = progress["current_face"] if progress["still"] and progress["hold_fraction"] < 1.0 else None
        missing = progress["missing"]
        again_done = set(progress.get("again_done", ()))
        third_done = set(progress.get("third_done", ()))
        opposite_done = set(progress.get("opposite_done", ()))
        again_missing = progress.get("again_missing", [])
        # the next face: a missing one, then (six done) one to hold again for the drift check
        todo = missing or again_missing
        suggested = todo[0] if todo and current not in todo else None
        for face in FACES:
            cell = self.query_one(f"#face-{face.replace('+', 'p').replace('-', 'm')}", Static)
            if face == current:
                state = f"holding {progress['hold_fraction']:.0%}"
            elif face == suggested:
                state = "next" if missing else "again next"
            elif face in third_done:
                state = "✓✓✓ done"
            elif face in opposite_done:
                state = "✓✓ done"
            elif face in again_done:
                state = "✓✓ · again" if face in again_missing else "✓✓ twice"
            elif face in done:
                state = "✓ · again" if not missing and face in again_missing else "✓ done"
            else:
                state = "to do"
            cell.update(f"[b]{face} down[/b]\n{state}")
            cell.set_class(face in done, "done")
            cell.set_class(face == current, "current")
            cell.set_class(face == suggested, "next")
