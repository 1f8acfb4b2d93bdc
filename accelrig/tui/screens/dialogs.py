"""Small modal dialogs: yes/no confirmation, a path prompt, and the wizards' setup form."""

from __future__ import annotations

from textual import on
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical
from textual.screen import ModalScreen
from textual.widgets import Button, Input, Label, Static

from accelrig.errors import AccelrigError


class ConfirmScreen(ModalScreen[bool]):
    """Ask a yes/no question; dismisses with True only on an explicit yes."""

    BINDINGS = [
        Binding("y", "answer(True)", "Yes"),
        Binding("n,escape", "answer(False)", "No"),
    ]

    def __init__(self, question: str, yes: str = "Yes", no: str = "No"):
        super().__init__()
        self.question = question
        self.yes, self.no = yes, no

    def compose(self) -> ComposeResult:
        with Vertical(classes="dialog"):
            yield Static(self.question, id="question")
            with Horizontal(classes="dialog-buttons"):
                yield Button(f"{self.yes} (y)", id="yes", variant="warning")
                yield Button(f"{self.no} (n)", id="no", variant="primary")

    def on_mount(self) -> None:
        self.query_one("#no", Button).focus()  # the safe answer is the default

    @on(Button.Pressed)
    def pressed(self, event: Button.Pressed) -> None:
        self.dismiss(event.button.id == "yes")

    def action_answer(self, answer: bool) -> None:
        self.dismiss(answer)


class PathScreen(ModalScreen[str | None]):
    """Ask for a file path; dismisses with the path, or None on escape."""

    BINDINGS = [Binding("escape", "cancel", "Cancel")]

    def __init__(self, prompt: str, default: str):
        super().__init__()
        self.prompt = prompt
        self.default = default

    def compose(self) -> ComposeResult:
        with Vertical(classes="dialog"):
            yield Static(self.prompt)
            yield Input(value=self.default, id="path")
            yield Static("[dim]enter saves, escape cancels[/dim]")

    @on(Input.Submitted, "#path")
    def submitted(self, event: Input.Submitted) -> None:
        path = event.value.strip()
        if path:
            self.dismiss(path)

    def action_cancel(self) -> None:
        self.dismiss(None)


class SetupForm(ModalScreen):
    """A wizard's setup questions, one Input per field; enter moves on, the last one submits.

    Subclasses give FIELDS as (name, label, placeholder) and ``parse(values)``,
    which turns the raw strings into the answer or raises ValueError /
    AccelrigError with a message the operator can act on (shown in red, the
    form stays open).  Escape dismisses with None.
    """

    BINDINGS = [Binding("escape", "cancel", "Cancel")]
    FIELDS: tuple[tuple[str, str, str], ...] = ()

    def compose(self) -> ComposeResult:
        with Vertical(classes="dialog"):
            for field, label, placeholder in self.FIELDS:
                yield Label(label)
                yield Input(placeholder=placeholder, id=f"setup-{field}")
            yield Static("[dim]enter moves on and starts after the last field, escape cancels[/dim]",
                         id="setup-status")

    def parse(self, values: dict[str, str]):
        raise NotImplementedError

    @on(Input.Submitted)
    def submitted(self, event: Input.Submitted) -> None:
        ids = [f"setup-{field}" for field, _, _ in self.FIELDS]
        position = ids.index(event.input.id)
        if position < len(ids) - 1:
            self.query_one(f"#{ids[position + 1]}", Input).focus()
            return
        values = {field: self.query_one(f"#setup-{field}", Input).value.strip() for field, _, _ in self.FIELDS}
        try:
            answer = self.parse(values)
        except (ValueError, AccelrigError) as exc:
            self.query_one("#setup-status", Static).update(f"[red]{exc}[/]")
            return
        self.dismiss(answer)

    def action_cancel(self) -> None:
        self.dismiss(None)

