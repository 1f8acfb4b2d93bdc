"""The one calibration wizard: any procedure that meets the contract (accelrig.procedures.contract).

The wizard holds no calibration logic.  It

1. renders the procedure's declared ``settings`` as a form (what the operator
   typed last time in this app session is offered again) and makes the
   procedure with ``create(values, device)``, so an impossible combination is
   refused while the form is still open;
2. reopens the device with a Recorder attached before its first sample
   (``Session.open_and_start``), so the procedure sees the stream from its
   start (a scripted simulation starts its script again) and every sample it
   saw is kept;
3. on a timer, hands what the recorder takes to ``feed(chunk)`` in a thread worker
   (a slow feed never freezes the screen) and shows the ``Event``s it returns:
   the instruction line, the log, the progress bar (``progress``);
4. binds the procedure's ``actions`` to keys (a rig screen maps keys to action
   names in ``ACTION_KEYS``) and calls ``act``;
5. calls ``finish()`` when a finite source has delivered everything;
6. once ``done``, runs ``result()`` in a thread worker and opens the results.

Every call into the procedure runs in a worker thread under one lock; while
the procedure collects data, its actions and feeds run in one pump at a time,
and the screen reads the procedure only between pumps.  A
disconnect mid-procedure is said on screen; the samples captured so far stay
in memory and can be written to a file (w).  An action that makes the
procedure need more data again (redo a face after the results) resumes
feeding from the live stream.

A rig screen is a thin subclass: ``procedure_class``, ``ACTION_KEYS``, and the
hooks ``create_arguments`` (what ``create`` takes beyond the settings),
``opening_instruction``, ``compose_body`` (its plots and widgets),
``show_procedure`` (refresh them), ``reset_body``, ``action_arguments`` (ask
what an action needs), ``not_ready_text`` and ``result_screen``.
"""

from __future__ import annotations

import dataclasses
import threading
import time
from pathlib import Path

from rich.markup import escape
from textual import work
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical
from textual.screen import Screen
from textual.widgets import Header, Label, ProgressBar, RichLog, Static

from accelrig.acquisition.recorder import Recorder, streaming_writer
from accelrig.acquisition.session import Session, State
from accelrig.errors import AccelrigError, DeviceError
from accelrig.procedures.contract import Event, Procedure
from accelrig.profiles.flash import flash_url_profile
from accelrig.recording import loss_warning, save_recording
from accelrig.tui.screens.dialogs import ConfirmScreen, PathScreen, SettingsForm
from accelrig.tui.widgets.keys import KeyFooter
from accelrig.tui.widgets.live import shortened

EVENT_STYLES = {"problem": "bold red", "ready": "bold green", "instruction": "bold", "captured": "green"}
# Event kinds that replace the instruction line (progress only goes to the log and the bar).
INSTRUCTION_KINDS = ("instruction", "captured", "ready", "problem")


def device_facts(info) -> dict:
    """What a procedure is told about the device (contract ``device``): its info without the
    driver's private extras, and ``rate``, the rate it was configured for, in Hz."""
    facts = {key: value for key, value in info.to_dict().items() if key != "extra"}
    facts["rate"] = info.nominal_rate
    return facts


class ProcedureWizard(Screen):
    """Drives one ``Procedure`` from the live stream.  Rig screens subclass it (see the module doc)."""

    procedure_class: type[Procedure] | None = None
    ACTION_KEYS: dict[str, str] = {}   # key -> procedure action name
    progress_label = "progress"
    BINDINGS = [
        Binding("escape", "cancel", "Cancel"),
        Binding("w", "write_capture", "Write data"),
        Binding("c", "compute", "Compute"),
    ]

    def __init__(self, session: Session, procedure_class: type[Procedure] | None = None,
                 values: dict | None = None):
        """``values``: the settings already parsed (no form is shown)."""
        super().__init__()
        self.procedure_class = procedure_class or type(self).procedure_class
        if self.procedure_class is None:
            raise TypeError("a wizard needs a procedure class")
        unknown = sorted(set(self.ACTION_KEYS.values()) - set(self.procedure_class.actions))
        if unknown:
            raise TypeError(f"{self.procedure_class.__name__} has no action {', '.join(unknown)}")
        self.url = session.url
        self.device = device_facts(session.info)
        self.values = values
        self.session: Session | None = None
        self.procedure: Procedure | None = None
        self.recorder: Recorder | None = None
        self.finished = False      # the procedure has enough data: no more feeding
        self.computing = False
        self.result_shown = False
        self.source_ended = False  # finish() was called: a finite source delivered everything
        self._lock = threading.Lock()   # one call into the procedure at a time
        self._pumping = False
        self._actions: list[tuple[str, dict]] = []   # operator actions for the next pump
        self._generation = 0       # a pump begun for an earlier procedure reports to nobody
        self._timer = None
        self._compute_clock = None  # counts the seconds of a compute on the headline
        self._compute_started = 0.0
        self._stream_line = ""
        self._last_logged = ""      # the last line of the log: a headline already there is not written twice
        self._alarm_key = None
        self.written_samples = 0   # samples written to a file so far (w)
        self.capture_path: Path | None = None       # where this run's capture streams to (segments)
        self.results_screen: Screen | None = None   # the last results shown (its saved_path: saved)
        for key, action in self.ACTION_KEYS.items():
            # the footer has room for a word per key at 80 columns; ? shows the whole description
            what = self.procedure_class.actions[action]
            self._bindings.bind(key, f"procedure_action({action!r})", what if len(what) <= 20 else action)

    @property
    def unsaved(self) -> str | None:
        """What leaving now would lose: captured samples neither written (w) nor turned into a saved result."""
        if self.recorder is None or self.recorder.samples <= self.written_samples:
            return None
        if getattr(self.results_screen, "saved_path", None) is not None:
            return None
        where = f" are on disk in {self.capture_path}" if self.capture_path is not None else ""
        return (f"The {self.recorder.samples} samples captured for the {self.procedure_class.title}{where} but "
                "are not written as a file (w writes them) and no result of them was saved.")

    @property
    def capture_name(self) -> str:
        """Default file name stem for written captures."""
        return self.procedure_class.name

    # ------------------------------------------------------------------ rig screen hooks
    def create_arguments(self, values: dict) -> dict:
        """What ``create`` takes beyond the values and the device (a profile's correction); raising
        AccelrigError refuses the values while the form is open."""
        return {}

    def opening_instruction(self) -> str:
        """What the operator reads once the device streams: the procedure's ``instruction()`` if it has one."""
        if hasattr(self.procedure, "instruction"):
            return self.procedure.instruction()
        return f"{self.procedure_class.title}: streaming, follow the instructions below"

    def compose_body(self) -> ComposeResult:
        """The rig's own widgets, shown between the instruction and the progress bar."""
        yield from ()

    def reset_body(self) -> None:
        """A new procedure starts: clear the rig's widgets."""

    def show_procedure(self, events: list[Event]) -> None:
        """Refresh the rig's widgets from the procedure (after each feed, action or finish)."""

    async def action_arguments(self, action: str) -> dict | None:
        """The arguments of ``action`` (ask the operator here); None cancels the action."""
        return {}

    def not_ready_text(self) -> str:
        """What 'compute' says while the procedure has not enough data."""
        return f"not enough data yet ({self.procedure.progress:.0%} of what the procedure needs)"

    def result_screen(self, result, recording) -> Screen:
        from accelrig.tui.screens.results import ResultsScreen

        return ResultsScreen(result, recording, self.session)

    # ------------------------------------------------------------------ layout
    def compose(self) -> ComposeResult:
        yield Header()
        with Vertical(classes="wizard"):
            yield Static("", id="instruction")
            yield from self.compose_body()
            with Horizontal(classes="bar-row"):
                yield Label(self.progress_label, classes="bar-label")
                yield ProgressBar(total=1.0, show_eta=False, id="progress")
            yield Static("", id="wizard-stream")
            yield Static("", id="wizard-alarm")
            # min_width 1: RichLog renders at least 78 columns by default, wider than the log at 80x24, and
            # cropped the rest of each long line ("radius 6.3495 ± 0.00093 mm" read "± 0.00")
            yield RichLog(id="events", max_lines=200, wrap=True, markup=True, min_width=1)
        yield KeyFooter()

    def on_mount(self) -> None:
        self.sub_title = self.procedure_class.title
        if self.values is not None or not self.procedure_class.settings:
            self.values = self.values if self.values is not None else {}
            self.start()
        else:
            self.find_rig()

    def help_text(self) -> str:
        """What ? shows in a wizard: what this procedure needs and does, then its keys (listed by the help)."""

        from accelrig.tui.rigs import NEEDS

        cls = self.procedure_class
        needs = NEEDS.get(cls.name)
        lines = [f"[b]{escape(cls.title)}[/b] on {escape(self.url)}"]
        if needs is not None:
            lines.append(f"Needs {escape(needs.motion)}; without such a device, the simulated rig "
                         f"({escape(needs.demo_note)}) shows how it goes.")
        if self.procedure is not None and hasattr(self.procedure, "instruction") and not self._pumping:
            lines.append(f"Now: {escape(self.procedure.instruction())}")
        lines.append("The headline says what to do; w writes the samples captured so far at any time; escape "
                     "leaves (asking first when something is unsaved).")
        lines += [f"[b]{escape(key)}[/b]: {escape(cls.actions[action])}" for key, action in self.ACTION_KEYS.items()]
        return "\n".join(lines)

    def use_device(self, session: Session) -> None:
        """Run on ``session``'s device from now on (the operator picked another one)."""
        self.url = session.url
        self.device = device_facts(session.info)

    async def switch_device(self, url: str) -> bool:
        """Open ``url`` (a simulated rig the wizard offered) and run on it from now on; False when it cannot
        be opened (the headline says why)."""
        import asyncio

        self.set_instruction(f"opening {url} ...")
        try:
            session = await asyncio.to_thread(Session.open_and_start, url, self.app.buffer_seconds,
                                              prepare=flash_url_profile)
        except AccelrigError as exc:
            self.set_instruction(f"cannot open {url}: {exc}", "bold red")
            return False
        self.app.use_session(session)
        self.use_device(session)
        return True

    @work(exclusive=True, group="wizard-rig")
    async def find_rig(self) -> None:
        """A device of the wrong kind is said, with the matching simulated rig or the connect list offered;
        then the settings form (filled in for the simulated rig when that was taken)."""
        from accelrig.tui.rigs import NEEDS, rig_problem
        from accelrig.tui.screens.connect import ConnectScreen
        from accelrig.tui.screens.dialogs import ChoiceScreen

        cls = self.procedure_class
        needs = NEEDS.get(cls.name)
        filled: dict[str, str] = {}
        while (problem := rig_problem(cls, self.url, self.device)) is not None:
            self.set_instruction(problem, "bold red")
            choices = [("connect", "Pick another device (the connect list shows what fits first)"),
                       ("anyway", "Use this device anyway"), ("back", "Go back")]
            if needs is not None:
                choices.insert(0, ("demo", f"Use the simulated {needs.sim_rig} rig: {needs.demo_note}"))
            choice = await self.app.push_screen_wait(ChoiceScreen(f"{problem}.", choices))
            if choice == "demo":
                if not await self.switch_device(needs.demo_url):
                    continue
                filled = dict(needs.demo_texts)
            elif choice == "connect":
                await self.app.push_screen_wait(ConnectScreen(wizard=cls.name))
                if self.app.session is not None and self.app.session.info is not None:
                    self.use_device(self.app.session)
            elif choice == "anyway":
                break
            else:
                self.app.pop_screen()
                return
        self.set_instruction(f"{self.url}: fill in the settings")
        self.ask_settings(filled)

    def set_instruction(self, text: str, style: str = "bold") -> None:
        """The headline, kept in the log too: a message that is soon replaced can still be read there."""
        self.query_one("#instruction", Static).update(f"[{style}]{text}[/]")
        if text != self._last_logged:
            self.log_event(text, "" if style == "bold" else style)

    def log_event(self, text: str, style: str = "") -> None:
        self._last_logged = text
        self.query_one("#events", RichLog).write(f"[{style}]{text}[/]" if style else text)

    # ------------------------------------------------------------------ settings
    @work(exclusive=True, group="wizard-settings")
    async def ask_settings(self, filled: dict[str, str] | None = None) -> None:
        """The settings form: what was typed last for this procedure, or ``filled`` (a simulated rig's)."""
        cls = self.procedure_class
        filled = dict(filled or {})
        remembered = {name: text for name, text in self.app.setting_texts.get(cls.name, {}).items()
                      if name not in filled}
        title = f"{cls.title}: settings" + (" (filled in for the simulated rig)" if filled else "")
        answer = await self.app.push_screen_wait(SettingsForm(title, cls.settings, {**remembered, **filled},
                                                              check=self.make_procedure, remembered=remembered,
                                                              filled=filled, note=cls.settings_note))
        if answer is None:
            self.app.pop_screen()
            return
        self.values, texts = answer
        forgotten = {s.name for s in cls.settings if not s.remembered}
        self.app.remember_settings(cls.name, {name: text for name, text in texts.items() if name not in forgotten})
        self.start()

    def make_procedure(self, values: dict) -> Procedure:
        """A new procedure from ``values`` and the device's facts (AccelrigError if it cannot be)."""
        missing = [c for c in self.procedure_class.channels_needed if c not in self.device.get("channels", ())]
        if missing:
            raise DeviceError(f"{self.url} delivers no {', '.join(missing)} channel, which the "
                              f"{self.procedure_class.title} needs", "escape, then pick a device that has it")
        return self.procedure_class.create(values, self.device, **self.create_arguments(values))

    # ------------------------------------------------------------------ running
    def start(self) -> None:
        """(Re)start: a new procedure on a freshly opened device."""
        try:
            procedure = self.make_procedure(self.values)
        except AccelrigError as exc:
            self.set_instruction(f"cannot start: {exc}", "bold red")
            return
        self._generation += 1
        self.stop_compute_clock()
        self.close_recorder()
        self.procedure = procedure
        self.recorder = None
        self._actions = []
        self.finished = self.computing = self.result_shown = self.source_ended = False
        self.written_samples = 0
        self.results_screen = None
        self._alarm_key = None
        self.query_one("#progress", ProgressBar).update(progress=0)
        self.query_one("#events", RichLog).clear()
        self._last_logged = ""
        self.alarm_clear()
        self.reset_body()
        self.show_procedure([])
        self.set_instruction(f"opening {self.url} ...")
        # A real device cannot be opened twice: release it before reopening.
        if self.app.session is not None:
            self.app.session.stop()
        self.open_device(self._generation)

    def capture_directory(self) -> Path:
        """Where this run's capture streams (one folder per start): OUTPUT/captures/NAME-UTC."""
        stamp = time.strftime("%Y%m%dT%H%M%SZ", time.gmtime())
        return Path(self.app.output_dir) / "captures" / f"{self.capture_name}-{stamp}-{self._generation}"

    @work(thread=True, exclusive=True, group="wizard-open")
    def open_device(self, generation: int) -> None:
        # The capture streams to disk segments as it arrives (bounded memory however long the
        # procedure runs); results and 'w' read it back.
        directory = self.capture_directory()
        try:
            session = Session.open_and_start(self.url, self.app.buffer_seconds, record=True,
                                             prepare=flash_url_profile,
                                             writer=lambda info: streaming_writer(info, directory))
        except AccelrigError as exc:
            self.app.call_from_thread(self.set_instruction, f"cannot open the device: {exc}", "bold red")
            return
        self.app.call_from_thread(self._opened, generation, session, directory)

    def _opened(self, generation: int, session: Session, directory: Path) -> None:
        if generation != self._generation:
            # restarted or left while it opened: this stream is no one's; its capture is finished
            # on disk and the device released, and the wizard's own stream stays untouched
            self.close_recorder(session.recorder)
            session.stop()
            return
        self.session, self.recorder, self.capture_path = session, session.recorder, directory
        self.app.use_session(session)
        self.set_instruction(self.opening_instruction())
        if self._timer is None:
            self._timer = self.set_interval(self.app.refresh_interval, self.tick)

    def tick(self) -> None:
        if self.session is None or self.recorder is None:
            return
        stats = self.session.stats()
        feeding = not self.finished
        if not self._pumping and self.procedure is not None and (feeding or self._actions):
            self._pumping = True
            actions, self._actions = self._actions, []
            self.pump(self._generation, self.procedure, self.recorder if feeding else None, stats.state, actions)
        stream = self.query_one("#wizard-stream", Static)
        counters = (f"   {stats.state.value}   {stats.delivered_rate:.1f} Hz   captured {self.recorder.samples} "
                    f"samples   drops {stats.missing}   gaps {stats.gap_events}")
        line = shortened(self.url, stream.content_size.width - len(counters)) + counters
        if line != self._stream_line:  # an idle screen does no work
            self._stream_line = line
            stream.update(escape(line))
        self.report_state(stats)

    @work(thread=True, group="wizard-pump")
    def pump(self, generation: int, procedure: Procedure, recorder: Recorder | None, state: State,
             actions: list) -> None:
        """The operator's actions, then what the recorder takes (or finish a source that ended before this
        read).

        Every call into the procedure while it collects data happens here, one pump at a
        time, so the screen reads the procedure only between pumps.
        """
        notes: list[tuple[str, str]] = []
        events: list[Event] = []
        called = False
        error = None
        with self._lock:
            for action, arguments in actions:
                try:
                    events += procedure.act(action, **arguments)
                except AccelrigError as exc:
                    notes.append((str(exc), "bold red"))
                called = True
            if recorder is not None:
                chunk = recorder.poll()
                if chunk.lost:  # cannot happen with a lossless reader; never hide it
                    notes.append((f"{chunk.lost} samples were lost before the procedure saw them", "bold red"))
                for _, missing, cause in chunk.gaps:
                    notes.append((f"the device reported a gap ({missing if missing >= 0 else 'unknown'} samples "
                                  f"missing{': ' + cause if cause else ''})", "yellow"))
                try:
                    if chunk.n:
                        # times from the capture's start, as the recording's (and the command line's) are:
                        # a device's own clock reads its uptime (16787.99 s on a BLE board)
                        events += procedure.feed(dataclasses.replace(chunk, t=chunk.t - recorder.start))
                        called = True
                    elif state == State.ENDED and not self.source_ended:
                        # a finite source (replay, scripted simulation) delivered everything (the state
                        # was read before this empty read): let the procedure close what is in progress
                        self.source_ended = True
                        events += procedure.finish()
                        called = True
                except AccelrigError as exc:
                    error = str(exc)
            # computes on its own once the guided sequence is through, or with enough data once the source
            # ended (a finite replay): nothing more will come
            done = procedure.complete or (procedure.done and self.source_ended)
        self.app.call_from_thread(self._pumped, generation, notes, events, called, bool(actions), error, done)

    def _pumped(self, generation: int, notes, events, called: bool, acted: bool, error: str | None,
                done: bool) -> None:
        self._pumping = False
        if generation != self._generation or not self.app.is_running:
            # a pump that ends while the app quits reports to nobody: the screen's widgets are being removed
            # (the face grid's cells were gone: NoMatches); what it read is in the capture on disk
            return
        for text, style in notes:
            self.log_event(text, style)
            if style == "bold red":
                self.set_instruction(text, style)
        if called:
            self.handle(events)
        if error is not None:
            self.set_instruction(error, "bold red")
            self.stop_feeding()
        elif done and not self.finished:
            self.stop_feeding()
            self.compute()
        elif acted and not done and self.finished and not self.computing:
            self.resume_feeding()
        if self.session is not None:
            self.report_state(self.session.stats())

    def stop_feeding(self) -> None:
        self.finished = True
        if self.recorder is not None:
            self.recorder.close()

    def resume_feeding(self) -> None:
        """The procedure needs data again after it had enough: it and the recorder take the live
        stream on (the recording's times jump over what came while nobody read)."""
        if self.session is None:
            return
        self.finished = self.result_shown = False
        self.recorder.reader = self.session.reader(lossless=True)

    def handle(self, events: list[Event]) -> None:
        """Show events: the log, the instruction line, the progress bar; then the rig's widgets."""
        for event in events:
            style = EVENT_STYLES.get(event.kind, "")
            self.log_event(event.message, style)
            if event.kind in INSTRUCTION_KINDS:
                self.set_instruction(event.message, style or "bold")
        self.query_one("#progress", ProgressBar).update(progress=float(self.procedure.progress))
        self.show_procedure(events)

    def report_state(self, stats) -> None:
        ended = stats.state == State.ENDED and self.source_ended
        lost = stats.state in (State.DISCONNECTED, State.FAILED)
        # once the device is lost the recorder still takes what the ring holds: the count may grow
        key = (stats.state, ended, self.finished, self.result_shown, self.computing,
               self.recorder.samples if lost else None)
        if key == self._alarm_key:
            return
        self._alarm_key = key
        alarm = self.query_one("#wizard-alarm", Static)
        busy_or_done = self.finished or self.result_shown or self.computing
        if lost and not busy_or_done:
            alarm.update(
                f"DEVICE LOST: {stats.last_error}\n{self.recorder.samples} captured samples are kept: "
                "w writes them to a file, escape returns to connect again."
            )
            alarm.add_class("alarm")
            self.set_instruction("the device disconnected", "bold red")
        elif ended and not busy_or_done:
            alarm.update("the source ended before the procedure had enough data (w writes what was captured)")
            alarm.add_class("alarm")
            self.set_instruction(self.ended_text(), "bold red")
        else:
            self.alarm_clear()

    def stream_over(self) -> bool:
        """No more samples will reach the procedure: the source ended (or, once the wizard stopped
        reading, the device stopped streaming)."""
        if self.source_ended:
            return True
        return (self.finished and self.session is not None
                and self.session.stats().state in (State.ENDED, State.DISCONNECTED, State.FAILED, State.STOPPED))

    def closing_keys(self) -> list[str]:
        """'key: what it does' for the procedure's actions that finish with what was taken."""
        return [f"{key}: {self.procedure_class.actions[action]}" for key, action in self.ACTION_KEYS.items()
                if action in self.procedure_class.closing_actions]

    def ended_text(self) -> str:
        """The headline once the source ended short: what can still be done."""
        return "; ".join(["the source ended: no more samples will come", *self.closing_keys(),
                          "w writes what was captured", "escape, then c connects again"])

    def alarm_clear(self) -> None:
        alarm = self.query_one("#wizard-alarm", Static)
        alarm.update("")
        alarm.remove_class("alarm")

    # ------------------------------------------------------------------ actions
    def action_procedure_action(self, action: str) -> None:
        if self.procedure is None or self.computing:
            return
        if self.stream_over() and action not in self.procedure_class.closing_actions:
            # it would wait for samples that will never come (and might drop what was taken)
            self.set_instruction(f"not done: '{self.procedure_class.actions[action]}' needs new samples and "
                                 f"the source has ended. {self.ended_text()}", "bold red")
            return
        self.act_flow(action)

    @work(exclusive=True, group="wizard-act")
    async def act_flow(self, action: str) -> None:
        arguments = await self.action_arguments(action)
        if arguments is not None:
            self._actions.append((action, arguments))   # the next pump carries it out

    # ------------------------------------------------------------------ fit
    def action_compute(self) -> None:
        if self.procedure is None or self.computing:
            return
        if not self.procedure.done:
            self.set_instruction(self.not_ready_text(), "bold red")
            return
        self.compute()

    def compute(self) -> None:
        if self.computing:
            return
        self.computing = True
        self.set_instruction(self.computing_text(), "bold green")
        # a fit can take a minute on a loaded machine: the headline counts the seconds, so the operator
        # sees it is alive (the log keeps the line once, without them)
        self._compute_started = time.monotonic()
        self._compute_clock = self.set_interval(1.0, self.show_computing)
        self._fit(self._generation, self.procedure)

    def computing_text(self) -> str:
        return f"enough data: computing the {self.procedure_class.title} ..."

    def show_computing(self) -> None:
        elapsed = time.monotonic() - self._compute_started
        self.query_one("#instruction", Static).update(f"[bold green]{escape(self.computing_text())} "
                                                      f"{elapsed:.0f} s[/]")

    def stop_compute_clock(self) -> None:
        if self._compute_clock is not None:
            self._compute_clock.stop()
            self._compute_clock = None

    @work(thread=True, exclusive=True, group="wizard-fit")
    def _fit(self, generation: int, procedure: Procedure) -> None:
        try:
            with self._lock:
                result = procedure.result()
                used = self.recorder.samples   # every sample polled was fed: these, and no more, were calibrated
        except AccelrigError as exc:
            self.app.call_from_thread(self.fit_failed, generation, str(exc))
            return
        # the capture runs on while the result is computed and shown (the operator still holds the last face):
        # the profile names the samples calibrated (its hash and sample count), so a report re-runs on those
        recording = self.recorder.recording()
        if len(recording) > used:
            recording = recording.slice(0, used)
        # heavy link loss says so in the result (and the profile) as the CLI's commands say it (warn_loss):
        # the status line's drop count is gone once the results are up
        if (loss := loss_warning(recording)) is not None and loss not in result.warnings:
            result.warnings.append(loss)
        self.app.call_from_thread(self._show, generation, result, recording)

    def fit_failed(self, generation: int, message: str) -> None:
        self.stop_compute_clock()
        if generation != self._generation:
            return
        self.computing = False
        self.set_instruction(f"calibration failed: {message}", "bold red")

    def _show(self, generation: int, result, recording) -> None:
        self.stop_compute_clock()
        if generation != self._generation:
            return
        self.computing = False
        self.result_shown = True
        self.alarm_clear()
        self.set_instruction("done: results are shown (escape on the results returns here)", "bold green")
        self.results_screen = self.result_screen(result, recording)
        self.app.push_screen(self.results_screen)

    def on_screen_resume(self) -> None:
        """Back from the results: the headline said "results are shown"; it says what was kept and what
        can be done now."""
        shown = self.results_screen
        if not self.result_shown or shown is None or shown in self.app.screen_stack:
            return
        saved = getattr(shown, "saved_path", None)
        kept = f"saved to {saved}" if saved is not None else "closed without saving"
        self.set_instruction(f"results {kept}: c shows them again (computed afresh from the captured data), "
                             "w writes the data, escape leaves")

    def action_restart(self) -> None:
        """Start again from a fresh procedure and a reopened device (rig screens bind it to a key)."""
        if not self.computing and self.values is not None:
            self.start()

    # ------------------------------------------------------------------ operator actions
    def action_cancel(self) -> None:
        self.cancel_flow()

    @work(exclusive=True, group="wizard-cancel")
    async def cancel_flow(self) -> None:
        if self.unsaved:
            if not await self.app.push_screen_wait(ConfirmScreen(f"Leave this calibration? {self.unsaved}",
                                                                 "Leave", "Stay")):
                return
        self._generation += 1   # whatever is still running reports to nobody
        self.close_recorder()
        self.app.pop_screen()

    def close_recorder(self, recorder: Recorder | None = None) -> None:
        """Release the stream (the wizard's, or ``recorder``) and finish the capture's segments (they
        stay on disk, under captures/)."""
        recorder = self.recorder if recorder is None else recorder
        if recorder is None:
            return
        recorder.close()
        try:
            recorder.writer.close()
        except AccelrigError as exc:   # a full disk: the open segment stays readable as it is
            self.log_event(f"capture segments not finished: {exc}", "yellow")

    def action_write_capture(self) -> None:
        self.write_flow()

    @work(exclusive=True, group="wizard-write")
    async def write_flow(self) -> None:
        if self.recorder is None or not self.recorder.samples:
            self.log_event("nothing captured yet", "yellow")
            return
        default = str(Path(self.app.output_dir) / f"{self.capture_name}-capture.csv")
        path = await self.app.push_screen_wait(PathScreen("Write the captured samples to (.csv or .npz):", default,
                                                                   verb="Write"))
        if path is None:
            return
        try:
            Path(path).expanduser().parent.mkdir(parents=True, exist_ok=True)
            save_recording(self.recorder.recording(), Path(path).expanduser())
        except (AccelrigError, OSError) as exc:
            self.log_event(f"not written: {exc}", "bold red")
            return
        self.written_samples = self.recorder.samples
        self.log_event(f"{self.recorder.samples} samples written to {path}", "green")
