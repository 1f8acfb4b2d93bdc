"""A wizard driven only by the Procedure contract: its setup form is rendered from the declared settings.

The procedure is made from the form's values and the device's facts; each
chunk goes to ``feed``, the end of a finite source to ``finish``, the space
key to ``act("capture")``, and the result to a rig's result screen.  Rig
wizards add their plots (``show_events``) and nothing else.
"""

from __future__ import annotations

from textual import work
from textual.binding import Binding
from textual.widgets import ProgressBar

from accelrig.settings import values_from_texts
from accelrig.tui.screens.legacy_wizard import LegacyWizard, SetupForm


class SettingsForm(SetupForm):
    """One field per declared setting, parsed by the setting itself (same words as the CLI's flags).

    ``prepare(values)`` may turn values into more arguments for the procedure
    (a profile's correction) or refuse them; the form dismisses with
    (values, arguments).
    """

    def __init__(self, settings, prepare=None):
        super().__init__()
        self.settings = settings
        self.prepare = prepare
        self.FIELDS = tuple((s.name, s.describe() + ":", s.example or s.default_text()) for s in settings)

    def parse(self, texts: dict[str, str]):
        values = values_from_texts(self.settings, texts)
        return values, (self.prepare(values) if self.prepare is not None else {})


class ContractWizard(LegacyWizard):
    """Base of the wizards of procedures that meet the contract; subclasses set ``procedure_class``."""

    procedure_class = None
    BINDINGS = [Binding("space", "act('capture')", "Capture step")]

    def __init__(self, session):
        super().__init__(session)
        self.values: dict | None = None
        self.arguments: dict = {}

    def prepare(self, values: dict) -> dict:
        """More arguments for ``create`` from the form's values (may raise to refuse them)."""
        return {}

    def begin(self) -> None:
        self.ask_setup()

    @work(exclusive=True, group="wizard-setup")
    async def ask_setup(self) -> None:
        answer = await self.app.push_screen_wait(SettingsForm(self.procedure_class.settings, self.prepare))
        if answer is None:
            self.app.pop_screen()
            return
        self.values, self.arguments = answer
        self.start()

    def make_procedure(self):
        info = (self.session or self.app.session).info
        device = {k: v for k, v in info.to_dict().items() if k != "extra"}
        return self.procedure_class.create(self.values, device, **self.arguments)

    def opening_instruction(self) -> str:
        return self.procedure.instruction()

    def feed_chunk(self, chunk) -> list:
        events = self.procedure.feed(chunk)
        self.query_one("#progress", ProgressBar).update(progress=self.procedure.progress)
        return events

    def source_ended(self) -> list:
        return self.procedure.finish()

    def action_act(self, action: str) -> None:
        if self.procedure is None or self.session is None or self.finished:
            return
        if self._finished_source:
            self.log_event("the source has ended: there is nothing more to capture (escape, then connect again)",
                           "yellow")
            return
        self.handle(self.procedure.act(action))
