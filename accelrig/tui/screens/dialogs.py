"""Small modal dialogs: yes/no confirmation, a path prompt, and a procedure's settings form."""

from __future__ import annotations

from textual import on
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical, VerticalScroll
from textual.screen import ModalScreen
from textual.widgets import Button, Input, Label, OptionList, Static
from textual.widgets.option_list import Option

from accelrig.errors import AccelrigError, DataError
from accelrig.settings import Setting, values_from_texts


def tell(status: Static, text: str) -> None:
    """An outcome (saved, written, refused) on a screen's ``status`` line and as a notification: the status
    line sits at the top, and an operator who scrolled down to read would not see it change."""
    status.update(text)
    status.app.notify(text, severity="error" if text.startswith("[red]") else "information")


DIALOG_TEXT_WIDTH = 66   # a .dialog's 72 columns less its border, padding and a scrollbar


class ConfirmScreen(ModalScreen[bool]):
    """Ask a yes/no question; dismisses with True only on an explicit yes.

    ``details`` (what the answer will do, e.g. a flash plan's register table) scroll above the question
    when they are taller than the screen leaves them (up/down, page up/down), so their top, the
    question and the buttons all stay in sight."""

    BINDINGS = [
        Binding("y", "answer(True)", "Yes"),
        Binding("n,escape", "answer(False)", "No"),
        Binding("up", "scroll_details(-1)", "Scroll up", show=False),
        Binding("down", "scroll_details(1)", "Scroll down", show=False),
        Binding("pageup", "scroll_details(-10)", "Page up", show=False),
        Binding("pagedown", "scroll_details(10)", "Page down", show=False),
    ]

    def __init__(self, question: str, yes: str = "Yes", no: str = "No", details: str | None = None):
        super().__init__()
        self.question = question
        self.details = details
        self.yes, self.no = yes, no

    def compose(self) -> ComposeResult:
        with Vertical(classes="dialog"):
            if self.details is not None:
                with VerticalScroll(id="details"):
                    yield Static(self.details, id="details-text")
            yield Static(self.question, id="question")
            with Horizontal(classes="dialog-buttons"):
                yield Button(f"{self.yes} (y)", id="yes", variant="warning")
                yield Button(f"{self.no} (n)", id="no", variant="primary")

    def on_mount(self) -> None:
        self.query_one("#no", Button).focus()  # the safe answer is the default
        if self.details is not None:
            self.call_after_refresh(self._say_it_scrolls)

    def _say_it_scrolls(self) -> None:
        if self.query_one("#details", VerticalScroll).max_scroll_y > 0:
            self.query_one("#question", Static).update(f"{self.question}  [dim](↑/↓, PgUp/PgDn scroll the text "
                                                       "above)[/]")

    @on(Button.Pressed)
    def pressed(self, event: Button.Pressed) -> None:
        self.dismiss(event.button.id == "yes")

    def action_answer(self, answer: bool) -> None:
        self.dismiss(answer)

    def action_scroll_details(self, lines: int) -> None:
        if self.details is not None:
            self.query_one("#details", VerticalScroll).scroll_relative(y=lines, animate=False)


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


class ChoiceScreen(ModalScreen[str | None]):
    """Ask the operator to pick one of a few ``(id, text)`` choices; dismisses with the id, or None on escape."""

    BINDINGS = [Binding("escape", "cancel", "Cancel")]

    def __init__(self, question: str, choices: list[tuple[str, str]]):
        super().__init__()
        self.question = question
        self.choices = choices

    def compose(self) -> ComposeResult:
        with Vertical(classes="dialog"):
            yield Static(self.question, id="question")
            yield OptionList(*[Option(text, id=key) for key, text in self.choices], id="choices")
            yield Static("[dim]enter picks, escape goes back[/dim]")

    @on(OptionList.OptionSelected, "#choices")
    def picked(self, event: OptionList.OptionSelected) -> None:
        if self.is_current:   # an enter typed twice in a terminal can select twice: one answer
            self.dismiss(event.option.id)

    def action_cancel(self) -> None:
        self.dismiss(None)


class SettingsForm(ModalScreen):
    """A procedure's declared settings as a form: one field per ``Setting``.

    Each field starts with what the operator typed last time (``texts``) or
    blank; a blank field takes the setting's default, shown beside it.  The
    texts are parsed by ``values_from_texts``, so a value is taken or refused
    with the same words as the command line's flag.  ``check(values)`` may
    refuse a combination (raising AccelrigError), e.g. a procedure that cannot
    start from these values.  Enter starts (tab and the arrows move between
    fields); a refusal is shown in red and puts the cursor in the field it
    names.  Dismisses with ``(values, texts)``, or None on escape.
    """

    BINDINGS = [
        Binding("escape", "cancel", "Cancel"),
        Binding("down", "app.focus_next", "Next field", show=False),
        Binding("up", "app.focus_previous", "Previous field", show=False),
    ]
    AUTO_FOCUS = ".setting-input"

    def __init__(self, title: str, settings: tuple[Setting, ...], texts: dict[str, str] | None = None,
                 check=None):
        super().__init__()
        self.title_text = title
        self.settings = tuple(settings)
        self.texts = dict(texts or {})
        self.check = check

    def compose(self) -> ComposeResult:
        with VerticalScroll(classes="dialog settings-form"):
            yield Label(f"[b]{self.title_text}[/b]")
            for s in self.settings:
                with Horizontal(classes="setting-row"):
                    yield Label(s.describe(s.title), classes="setting-label")
                    field = Input(value=self.texts.get(s.name, ""), placeholder=f"e.g. {s.example}" if s.example else s.default_text(),
                                  id=f"setting-{s.name}", classes="setting-input")
                    field.tooltip = s.describe()
                    yield field
            yield Static("[dim]enter starts, tab or the arrows move between fields, escape cancels[/dim]",
                         id="setup-status")

    def field(self, name: str) -> Input:
        return self.query_one(f"#setting-{name}", Input)

    @on(Input.Submitted)
    def action_submit(self) -> None:
        texts = {s.name: self.field(s.name).value.strip() for s in self.settings}
        try:
            values = values_from_texts(self.settings, texts)
            if self.check is not None:
                self.check(values)
        except AccelrigError as exc:
            self.query_one("#setup-status", Static).update(f"[red]{exc}[/]")
            bad = next((s for s in self.settings if not _accepts(s, texts[s.name])), None)
            if bad is not None:
                self.field(bad.name).focus()
            return
        self.dismiss((values, texts))

    def action_cancel(self) -> None:
        self.dismiss(None)


def _accepts(setting: Setting, text: str) -> bool:
    try:
        setting.parse(text)
    except DataError:
        return False
    return True
