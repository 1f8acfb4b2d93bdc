"""Small modal dialogs: yes/no confirmation, a path prompt, a choice, and a procedure's settings form.

Each dialog has its own key footer: the screen below keeps its footer under the dialog, and its keys
(a wizard's "w Write data", "r redo a face") do nothing, or the wrong thing, while a dialog is open.
"""

from __future__ import annotations

from rich.markup import escape
from textual import on, work
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical, VerticalScroll
from textual.screen import ModalScreen, ScreenResultType
from textual.widgets import Button, Input, OptionList, Static
from textual.widgets.option_list import Option

from accelrig.errors import AccelrigError, DataError
from accelrig.settings import Setting, values_from_texts
from accelrig.tui.widgets.keys import KeyFooter


def tell(status: Static, text: str) -> None:
    """An outcome (saved, written, refused) on a screen's ``status`` line and as a notification: the status
    line sits at the top, and an operator who scrolled down to read would not see it change."""
    status.update(text)
    status.app.notify(text, severity="error" if text.startswith("[red]") else "information")


DIALOG_TEXT_WIDTH = 66   # a .dialog's 72 columns less its border, padding and a scrollbar


class Dialog(ModalScreen[ScreenResultType]):
    """A modal dialog.  A modal screen takes no key from the app's bindings, so help (? or F1) is bound here
    again: it shows the dialog's keys and its ``help_text`` (what it asks), not the screen's below.  ``keys`` are the dialog's
    own bindings made at run time (a question's "y Leave  n Stay"), listed before
    help in the footer."""

    def __init__(self, keys: tuple[Binding, ...] = ()):
        super().__init__()
        for binding in keys:
            self._bindings.bind(binding.key, binding.action, binding.description, priority=binding.priority)
        self._bindings.bind("question_mark,f1", "app.help", "Help", key_display="?")


class ConfirmScreen(Dialog[bool]):
    """Ask a yes/no question; dismisses with True only on an explicit yes.

    ``details`` (what the answer will do, e.g. a flash plan's register table) scroll above the question
    when they are taller than the screen leaves them (up/down, page up/down), so their top, the
    question and the buttons all stay in sight."""

    BINDINGS = [
        Binding("escape", "answer(False)", "No", show=False),
        Binding("up", "scroll_details(-1)", "Scroll up", show=False),
        Binding("down", "scroll_details(1)", "Scroll down", show=False),
        Binding("pageup", "scroll_details(-10)", "Page up", show=False),
        Binding("pagedown", "scroll_details(10)", "Page down", show=False),
    ]

    def __init__(self, question: str, yes: str = "Yes", no: str = "No", details: str | None = None):
        # the footer names the answers as the buttons do ("y Leave  n Stay")
        super().__init__(keys=(Binding("y", "answer(True)", yes), Binding("n", "answer(False)", no)))
        self.question = question
        self.details = details
        self.yes, self.no = yes, no

    def help_text(self) -> str:
        scrolls = ("  The text above the question scrolls with the arrows and page keys." if self.details is not None
                   else "")
        return (f"[b]A question[/b]: {escape(self.question)}\n\n"
                f"y ({escape(self.yes)}) does what the question says; n ({escape(self.no)}) or escape does "
                f"not.{scrolls}")

    def compose(self) -> ComposeResult:
        with Vertical(classes="dialog"):
            if self.details is not None:
                with VerticalScroll(id="details"):
                    yield Static(self.details, id="details-text")
            yield Static(self.question, id="question")
            with Horizontal(classes="dialog-buttons"):
                yield Button(f"{self.yes} (y)", id="yes", variant="warning")
                yield Button(f"{self.no} (n)", id="no", variant="primary")
        yield KeyFooter()

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


# a path longer than this no longer fits the dialog's field: it is also shown whole, wrapped, under it
WHOLE_PATH_FROM = 60


class PathScreen(Dialog[str | None]):
    """Ask for a file path (or another one-line answer, a broker's URL); dismisses with it, or None on escape.
    ``verb`` is what enter does with it ("Save", "Write", "Open"), in the footer and the hint."""

    BINDINGS = [Binding("escape", "cancel", "Cancel")]

    def __init__(self, prompt: str, default: str, verb: str = "Save"):
        # enter is the field's own key; bound here too (priority) so the footer shows it, first
        super().__init__(keys=(Binding("enter", "submit", verb, priority=True),))
        self.prompt = prompt
        self.default = default
        self.verb = verb

    def help_text(self) -> str:
        return (f"[b]{escape(self.prompt)}[/b]\n\nType or edit it in the field (~ is your home folder).  enter "
                f"{self.verb.lower()}s, escape cancels and nothing is done.  In the field ? types itself: F1 opens "
                "this help.")

    def compose(self) -> ComposeResult:
        with Vertical(classes="dialog"):
            yield Static(self.prompt)
            yield Input(value=self.default, id="path")
            # the field shows the end of a long path (where the cursor is); the whole of it, wrapped, here
            yield Static(self._whole(self.default), id="path-whole")
            yield Static(f"[dim]enter {self.verb.lower()}s, escape cancels[/dim]")
        yield KeyFooter()

    @staticmethod
    def _whole(value: str) -> str:
        return f"[dim]{escape(value)}[/dim]" if len(value) > WHOLE_PATH_FROM else ""

    def on_input_changed(self, event: Input.Changed) -> None:
        self.query_one("#path-whole", Static).update(self._whole(event.value))

    def action_submit(self) -> None:
        path = self.query_one("#path", Input).value.strip()
        if path:
            self.dismiss(path)

    def action_cancel(self) -> None:
        self.dismiss(None)


class ChoiceScreen(Dialog[str | None]):
    """Ask the operator to pick one of a few ``(id, text)`` choices; dismisses with the id, or None on escape."""

    BINDINGS = [Binding("escape", "cancel", "Cancel")]

    def __init__(self, question: str, choices: list[tuple[str, str]]):
        super().__init__()
        self.question = question
        self.choices = choices

    def help_text(self) -> str:
        listed = "\n".join(f"  • {escape(text)}" for _, text in self.choices)
        return (f"[b]{escape(self.question)}[/b]\n\n{listed}\n\nThe arrows move to a choice and enter picks it; "
                "escape goes back without choosing.")

    def compose(self) -> ComposeResult:
        with Vertical(classes="dialog"):
            yield Static(self.question, id="question")
            yield OptionList(*[Option(text, id=key) for key, text in self.choices], id="choices")
            yield Static("[dim]enter picks, escape goes back[/dim]")
        yield KeyFooter()

    @on(OptionList.OptionSelected, "#choices")
    def picked(self, event: OptionList.OptionSelected) -> None:
        if self.is_current:   # an enter typed twice in a terminal can select twice: one answer
            self.dismiss(event.option.id)

    def action_cancel(self) -> None:
        self.dismiss(None)


class AsksBeforeClosing:
    """escape on a screen that holds a result (results, verification, campaign): a result that can be saved
    and is not asks "save it / discard it / stay" before the screen closes, as a careful editor asks
    before it closes an unsaved file; a saved result closes at once.

    The screen names what s saves (``saved_thing``), says whether it is unsaved (``unsaved_result``) and
    saves it after asking where (``save_result``, True once written).
    """

    saved_thing = "the result"

    def unsaved_result(self) -> bool:
        return getattr(self, "saved_path", None) is None

    async def save_result(self) -> bool:
        raise NotImplementedError

    def action_close(self) -> None:
        if self.unsaved_result():
            self.ask_before_closing()
        else:
            self.app.pop_screen()

    @work(exclusive=True, group="close")
    async def ask_before_closing(self) -> None:
        thing = self.saved_thing
        question = (f"{thing[0].upper()}{thing[1:]} is not saved: closing the results without saving loses "
                    "it (the wizard keeps the captured data, and c there computes it again).")
        choices = [("save", f"Save {thing}, then close"), ("discard", f"Discard {thing} and close"),
                   ("stay", "Stay on the results")]
        choice = await self.app.push_screen_wait(ChoiceScreen(question, choices))
        if choice == "discard" or (choice == "save" and await self.save_result()):
            self.app.pop_screen()


class SettingsForm(Dialog):
    """A procedure's declared settings as a form: one field per ``Setting``.

    Each field starts with ``texts`` (what the operator typed last time, or a simulated rig's values) or
    blank; a blank field takes the setting's default, shown beside it.  What came from last time
    (``remembered``) and differs from the default is listed under the title, and ctrl+r puts every field
    back to its default (or to the simulated rig's value, ``filled``): a choice made once by someone else
    (a model, a flatness) is seen before it is used.  The texts are parsed by ``values_from_texts``, so a
    value is taken or refused with the same words as the command line's flag.  ``check(values)`` may
    refuse a combination (raising AccelrigError), e.g. a procedure that cannot start from these values.
    Enter starts (tab and the arrows move between fields); a refusal is shown in red and puts the cursor
    in the field it names.  Dismisses with ``(values, texts)``, or None on escape.
    """

    BINDINGS = [
        # enter is each field's own key; bound here too (priority) so the footer shows it
        Binding("enter", "submit", "Start", priority=True),
        Binding("escape", "cancel", "Cancel"),
        Binding("ctrl+r", "defaults", "Defaults"),
        Binding("down", "app.focus_next", "Next field", show=False),
        Binding("up", "app.focus_previous", "Previous field", show=False),
    ]
    AUTO_FOCUS = ".setting-input"

    def __init__(self, title: str, settings: tuple[Setting, ...], texts: dict[str, str] | None = None,
                 check=None, remembered: dict[str, str] | None = None, filled: dict[str, str] | None = None,
                 note: str = "", verb: str = "Start"):
        """``verb``: what enter does, in the footer and the hint ("Start" a procedure, "Continue" to a file's
        name)."""
        super().__init__()
        # the footer keeps enter first, named by what it does here
        self._bindings.key_to_bindings["enter"] = [Binding("enter", "submit", verb, priority=True)]
        self.verb = verb
        self.title_text = title
        self.note = note
        self.settings = tuple(settings)
        self.texts = dict(texts or {})
        self.check = check
        self.remembered = dict(remembered or {})
        self.filled = dict(filled or {})

    def help_text(self) -> str:
        fields = "\n".join(f"  [b]{escape(s.title.split(' (')[0])}[/b]: {escape(s.describe())}" for s in self.settings)
        note = f"\n\n{escape(self.note[:1].upper() + self.note[1:])}." if self.note else ""
        return (f"[b]{escape(self.title_text)}[/b]{note}\n\nOne field for each value asked; a blank field "
                "takes its default (in grey), a field marked required must be filled.  tab or the arrows move "
                f"between fields, enter {self.verb.lower()}s, a value that cannot work is refused in red with the "
                "reason, ctrl+r "
                f"puts every field back to its default, escape cancels.  In a field ? types itself: F1 opens this "
                f"help.\n\n{fields}")

    def compose(self) -> ComposeResult:
        with VerticalScroll(classes="dialog settings-form"):
            # a Static wraps a title wider than the dialog (a Label cut it, and its closing parenthesis)
            yield Static(f"[b]{escape(self.title_text)}[/b]", id="settings-title")
            if self.note:   # what the fields need together, which no one label says
                yield Static(escape(self.note[:1].upper() + self.note[1:] + "."), id="settings-note")
            yield Static(self.remembered_text(), id="settings-remembered")
            for s in self.settings:
                with Horizontal(classes="setting-row"):
                    yield Static(escape(s.describe(s.title)), id=f"label-{s.name}", classes="setting-label")
                    field = Input(value=self.texts.get(s.name, ""), placeholder=f"e.g. {s.example}" if s.example else s.default_text(),
                                  id=f"setting-{s.name}", classes="setting-input")
                    field.tooltip = s.describe()
                    yield field
            yield Static(f"[dim]enter {self.verb.lower()}s, tab or the arrows move between fields, escape "
                         "cancels[/dim]", id="setup-status")
        yield KeyFooter()

    def kept_from_last_time(self) -> list[Setting]:
        """The settings whose field still holds last time's text, where that text is not the default."""
        return [s for s in self.settings if (text := self.remembered.get(s.name, "").strip())
                and self.field_text(s.name) == text and text != s.default_text()]

    def field_text(self, name: str) -> str:
        fields = self.query(f"#setting-{name}")
        return fields.first(Input).value.strip() if fields else self.texts.get(name, "").strip()

    def remembered_text(self) -> str:
        kept = self.kept_from_last_time()
        if not kept:
            return ""
        # the label without its explanation: "model", not "model (multi-position: hold it still in ...)"
        listed = "; ".join(f"{s.title.split(' (')[0]}: {self.remembered[s.name].strip()}" for s in kept)
        return (f"[yellow]kept from last time:[/] {escape(listed)} "
                "[dim](ctrl+r puts every field back to its default)[/]")

    def refresh_remembered(self) -> None:
        """The note under the title, and the labels of the fields it lists in its colour."""
        kept = {s.name for s in self.kept_from_last_time()}
        note = self.query_one("#settings-remembered", Static)
        note.update(self.remembered_text())
        note.display = bool(kept)
        for s in self.settings:
            self.query_one(f"#label-{s.name}", Static).set_class(s.name in kept, "remembered")

    def on_mount(self) -> None:
        self.refresh_remembered()

    @on(Input.Changed, ".setting-input")
    def edited(self) -> None:
        self.refresh_remembered()

    def action_defaults(self) -> None:
        """ctrl+r: every field blank (its default), or the simulated rig's value where the wizard filled one."""
        for s in self.settings:
            self.field(s.name).value = self.filled.get(s.name, "")
        self.refresh_remembered()
        self.query_one("#setup-status", Static).update(f"every field is back to its default: enter "
                                                       f"{self.verb.lower()}s")

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
            self.query_one("#setup-status", Static).update(f"[red]{escape(str(exc))}[/]")
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
