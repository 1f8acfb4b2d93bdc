"""Six face cells: done, being held (with its progress), or still to do."""

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
        current = progress["current_face"] if progress["still"] else None
        missing = progress["missing"]
        suggested = missing[0] if missing and current not in missing else None
        for face in FACES:
            cell = self.query_one(f"#face-{face.replace('+', 'p').replace('-', 'm')}", Static)
            if face == current:
                state = f"holding {progress['hold_fraction']:.0%}"
            elif face in done:
                state = "✓ done"
            elif face == suggested:
                state = "next"
            else:
                state = "to do"
            cell.update(f"[b]{face} down[/b]\n{state}")
            cell.set_class(face in done, "done")
            cell.set_class(face == current, "current")
            cell.set_class(face == suggested, "next")
