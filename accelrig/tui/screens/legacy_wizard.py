"""The wizard base of the procedures not yet on the Procedure contract (static, wheel).

Delete this module once they run on ``accelrig.tui.screens.wizard.ProcedureWizard``,
the one generic wizard over ``accelrig.procedures.contract``.  What follows is
the old base as it was:

What every calibration wizard shares: drive a procedure object from the live stream.

A wizard holds no calibration logic.  It reopens the device (so the procedure
sees the stream from its first sample; a scripted simulation starts its
script again), reads the session's ring buffer with a lossless reader on a
timer, hands each chunk to ``procedure.feed(t, raw)`` and shows the events
the procedure returns.  When the procedure says it has enough data the fit
runs in a thread worker (the screen stays live) and the results screen opens.

A disconnect mid-procedure is said on screen; the samples captured so far
stay in memory and can be written to a file (w).
"""

from __future__ import annotations

from pathlib import Path

from textual import work
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical
from textual.screen import Screen
from textual.widgets import Footer, Header, Label, ProgressBar, RichLog, Static

from accelrig.acquisition.recorder import Recorder
from accelrig.acquisition.session import Session, State
from accelrig.errors import AccelrigError
from accelrig.profiles.flash import flash_url_profile
from accelrig.recording import save_recording
from accelrig.tui.screens.dialogs import ConfirmScreen, PathScreen

EVENT_STYLES = {"problem": "bold red", "ready": "bold green", "instruction": "bold", "captured": "green"}


class LegacyWizard(Screen):
    """Base of the wizards.  Subclasses set ``wizard_title``, make the procedure and add widgets."""

    wizard_title = "calibration"
    progress_label = "progress"
    capture_name = "capture"   # default file name stem for written captures
    BINDINGS = [
        Binding("escape", "cancel", "Cancel"),
        Binding("w", "write_capture", "Write data"),
    ]

    def __init__(self, session: Session):
        super().__init__()
        self.url = session.url
        self.session: Session | None = None
        self.procedure = None
        self.recorder: Recorder | None = None
        self.finished = False      # the procedure has enough data
        self.computing = False
        self.reported_state: State | None = None
        self._stream_line = ""
        self._finished_source = False
        self.result_shown = False

    # ------------------------------------------------------------------ subclass hooks
    def make_procedure(self):
        """A fresh procedure object (may raise AccelrigError with a message for the operator)."""
        raise NotImplementedError

    def compose_body(self) -> ComposeResult:
        """Procedure-specific widgets shown above the event log."""
        yield from ()

    def show_events(self, events: list) -> None:
        """Procedure-specific reaction to events (after they are logged)."""

    def feed_chunk(self, chunk) -> list:
        """Hand one ring-buffer chunk to the procedure; returns its events."""
        return self.procedure.feed(chunk.t, chunk.acceleration())

    def source_ended(self) -> list:
        """A finite source delivered everything: let the procedure close what is in progress."""
        finish = getattr(self.procedure, "finish", None)
        return finish() if finish is not None else []

    def opening_instruction(self) -> str:
        """What the operator reads once the device streams."""
        return "streaming: follow the instructions below"

    def compute_result(self):
        """The fit (runs in a thread worker)."""
        return self.procedure.result()

    def procedure_done(self) -> bool:
        return bool(getattr(self.procedure, "done", False))

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
            yield RichLog(id="events", max_lines=200, wrap=True, markup=True)
        yield Footer()

    def on_mount(self) -> None:
        # (Textual calls on_mount of every class in the MRO: subclasses override begin(), not this)
        self.sub_title = self.wizard_title
        self.begin()

    def begin(self) -> None:
        """First thing on the screen: subclasses that need the operator's input ask it here."""
        self.start()

    def set_instruction(self, text: str, style: str = "bold") -> None:
        self.query_one("#instruction", Static).update(f"[{style}]{text}[/]")

    def log_event(self, text: str, style: str = "") -> None:
        self.query_one("#events", RichLog).write(f"[{style}]{text}[/]" if style else text)

    # ------------------------------------------------------------------ running
    def start(self) -> None:
        """(Re)start: a new procedure on a freshly opened device."""
        try:
            self.procedure = self.make_procedure()
        except AccelrigError as exc:
            self.set_instruction(f"cannot start: {exc}", "bold red")
            return
        self.finished = False
        self.computing = False
        self.reported_state = None
        self._finished_source = False
        self.result_shown = False
        self.query_one("#progress", ProgressBar).update(progress=0)
        self.query_one("#events", RichLog).clear()
        self.set_instruction(f"opening {self.url} ...")
        # A real device cannot be opened twice: release it before reopening.
        if self.app.session is not None:
            self.app.session.stop()
        self.open_device()

    @work(thread=True, exclusive=True, group="wizard-open")
    def open_device(self) -> None:
        try:
            session = Session.open_and_start(self.url, self.app.buffer_seconds, record=True,
                                             prepare=flash_url_profile)
        except AccelrigError as exc:
            self.app.call_from_thread(self.set_instruction, f"cannot open the device: {exc}", "bold red")
            return
        self.app.call_from_thread(self._opened, session)

    def _opened(self, session: Session) -> None:
        self.session, self.recorder = session, session.recorder
        self.app.use_session(session)
        self.set_instruction(self.opening_instruction())
        if not getattr(self, "_timer_started", False):
            self._timer_started = True
            self.set_interval(self.app.refresh_interval, self.tick)

    def tick(self) -> None:
        if self.session is None or self.recorder is None:
            return
        stats = self.session.stats()
        if not self.finished:
            chunk = self.recorder.poll()
            if chunk.lost:  # cannot happen with a lossless reader; never hide it
                self.log_event(f"{chunk.lost} samples were lost before the procedure saw them", "bold red")
            for _, missing in chunk.gaps:
                self.log_event(f"the device reported a gap ({missing if missing >= 0 else 'unknown'} samples missing)",
                               "yellow")
            if chunk.n:
                try:
                    events = self.feed_chunk(chunk)
                except AccelrigError as exc:
                    self.set_instruction(str(exc), "bold red")
                    self.finished = True
                    return
                self.handle(events)
            if not chunk.n and stats.state == State.ENDED and not self._finished_source:
                # a finite source (replay, scripted simulation) delivered everything:
                # let the procedure close what is in progress (e.g. the last still pose)
                self._finished_source = True
                self.handle(self.source_ended())
            if self.procedure_done():
                self.finished = True
                self.recorder.close()
                self.compute()
        line = (f"{self.url}   {stats.state.value}   {stats.delivered_rate:.1f} Hz   "
                f"captured {self.recorder.samples} samples   drops {stats.missing}   gaps {stats.gap_events}")
        if line != self._stream_line:  # an idle screen does no work
            self._stream_line = line
            self.query_one("#wizard-stream", Static).update(line)
        self.report_state(stats)

    def handle(self, events: list) -> None:
        for event in events:
            kind = getattr(event, "kind", "progress")
            message = getattr(event, "message", str(event))
            self.log_event(message, EVENT_STYLES.get(kind, ""))
            if kind in ("instruction", "problem", "ready"):
                self.set_instruction(message, EVENT_STYLES.get(kind, "bold"))
            progress = getattr(event, "progress", None)
            if progress is not None:
                self.query_one("#progress", ProgressBar).update(progress=float(progress))
        self.show_events(events)

    def report_state(self, stats) -> None:
        if stats.state == self.reported_state:
            return
        self.reported_state = stats.state
        alarm = self.query_one("#wizard-alarm", Static)
        if stats.state in (State.DISCONNECTED, State.FAILED) and not (self.finished or self.result_shown):
            alarm.update(
                f"DEVICE LOST: {stats.last_error}\n{self.recorder.samples} captured samples are kept: "
                "w writes them to a file, escape returns to connect again."
            )
            alarm.add_class("alarm")
            self.set_instruction("the device disconnected", "bold red")
        elif stats.state == State.ENDED and not (self.finished or self.result_shown or self.computing):
            alarm.update("the source ended before the procedure had enough data (w writes what was captured)")
            alarm.add_class("alarm")
        else:
            alarm.update("")
            alarm.remove_class("alarm")

    def alarm_clear(self) -> None:
        alarm = self.query_one("#wizard-alarm", Static)
        alarm.update("")
        alarm.remove_class("alarm")

    # ------------------------------------------------------------------ fit
    def compute(self) -> None:
        if self.computing:
            return
        self.computing = True
        self.set_instruction("enough data: computing the calibration ...", "bold green")
        self._fit()

    @work(thread=True, exclusive=True, group="wizard-fit")
    def _fit(self) -> None:
        try:
            result = self.compute_result()
        except AccelrigError as exc:
            self.computing = False
            self.app.call_from_thread(self.fit_failed, str(exc))
            return
        recording = self.recorder.recording()
        self.computing = False
        self.app.call_from_thread(self._show, result, recording)

    def fit_failed(self, message: str) -> None:
        self.set_instruction(f"calibration failed: {message}", "bold red")
        self.log_event(f"calibration failed: {message}", "bold red")

    def _show(self, result, recording) -> None:
        self.result_shown = True
        self.alarm_clear()
        self.set_instruction("done: results are shown (escape on the results returns here)", "bold green")
        self.app.push_screen(self.result_screen(result, recording))

    def result_screen(self, result, recording) -> Screen:
        from accelrig.tui.screens.results import ResultsScreen

        return ResultsScreen(result, recording, self.session)

    # ------------------------------------------------------------------ operator actions
    def action_cancel(self) -> None:
        self.cancel_flow()

    @work(exclusive=True, group="wizard-cancel")
    async def cancel_flow(self) -> None:
        if not self.finished and self.recorder is not None and self.recorder.samples:
            if not await self.app.push_screen_wait(ConfirmScreen("Leave this calibration? The data taken so far are "
                                                                 "dropped unless written first (w).", "Leave", "Stay")):
                return
        if self.recorder is not None:
            self.recorder.close()
        self.app.pop_screen()

    def action_write_capture(self) -> None:
        self.write_flow()

    @work(exclusive=True, group="wizard-write")
    async def write_flow(self) -> None:
        if self.recorder is None or not self.recorder.samples:
            self.log_event("nothing captured yet", "yellow")
            return
        default = str(Path(self.app.profile_dir) / f"{self.capture_name}-capture.csv")
        path = await self.app.push_screen_wait(PathScreen("Write the captured samples to (.csv or .npz):", default))
        if path is None:
            return
        try:
            save_recording(self.recorder.recording(), path)
        except (AccelrigError, OSError) as exc:
            self.log_event(f"not written: {exc}", "bold red")
            return
        self.log_event(f"{self.recorder.samples} samples written to {path}", "green")

