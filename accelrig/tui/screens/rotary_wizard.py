"""The rotary bench wizard: drives accelrig.procedures.rotary_session.RotaryBenchProcedure.

Asks the mounting (tangential and radial axes) and the plan (frequency and
peak-to-peak angle steps, repeats, seconds per step).  For each step it says
what to set on the bench; space records the step's seconds from the stream
(raw counts with the encoder angle ``theta`` the device delivers beside
them), the procedure analyses it in a worker and the sensitivity of each
axis appears as it comes.  After the last step the campaign report opens.
"""

from __future__ import annotations

import numpy as np
import yaml
from textual import work
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import VerticalScroll
from textual.screen import Screen
from textual.widgets import Footer, Header, Static

from accelrig.errors import AccelrigError, DeviceError
from accelrig.result import to_plain
from accelrig.procedures.rotary_bench import PAPER_PLAN
from accelrig.procedures.rotary_session import RotaryBenchProcedure
from accelrig.recording import Recording
from accelrig.tui.screens.legacy_wizard import LegacyWizard, SetupForm
from accelrig.tui.screens.slider_wizard import Note
from accelrig.tui.widgets.plot import LinePlot, Series


def parse_plan(text: str) -> tuple[tuple[float, float], ...]:
    """'5:34,8:13' -> ((5, 34), (8, 13)); blank: the paper's plan."""
    text = text.strip()
    if not text:
        return PAPER_PLAN
    plan = []
    for item in text.replace(" ", "").split(","):
        try:
            frequency, angle = (float(v) for v in item.split(":"))
        except ValueError:
            raise ValueError(f"plan step {item!r} is not FREQUENCY:DEGREES (e.g. 5:34)") from None
        if frequency <= 0 or angle <= 0:
            raise ValueError(f"plan step {item!r}: frequency and angle must be positive")
        plan.append((frequency, angle))
    return tuple(plan)


class RotarySetupScreen(SetupForm):
    FIELDS = (("tangential", "Tangential axis (blank: x):", "x"),
              ("radial", "Radial axis (blank: y):", "y"),
              ("plan", "Steps FREQUENCY:DEGREES peak to peak (blank: the paper's "
               + ",".join(f"{f:g}:{a:g}" for f, a in PAPER_PLAN) + "):", "e.g. 5:34,8:13"),
              ("repeats", "Repeats of each step (blank: 6):", "6"),
              ("seconds", "Seconds recorded per step (blank: 40):", "40"))

    def parse(self, value: dict[str, str]) -> dict:
        return {
            "tangential": value["tangential"] or "x",
            "radial": value["radial"] or "y",
            "plan": parse_plan(value["plan"]),
            "repeats": int(value["repeats"] or 6),
            "seconds": float(value["seconds"] or 40),
        }


class RotaryWizard(LegacyWizard):
    wizard_title = "rotary bench calibration"
    capture_name = "rotary"
    progress_label = "steps"
    BINDINGS = [Binding("space", "record_step", "Record step")]

    def __init__(self, session):
        super().__init__(session)
        self.setup: dict | None = None
        self.armed = False        # recording the current step
        self.analysing = False
        self._parts: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []

    def make_procedure(self) -> RotaryBenchProcedure:
        info = (self.session or self.app.session).info
        if "theta" not in info.channels:
            raise DeviceError(f"{info.url} delivers no encoder angle (no 'theta' channel)",
                              "record each step with its encoder log and use 'accelrig calibrate rotary'")
        self.meta = {k: v for k, v in info.to_dict().items() if k != "extra"}
        self.armed, self.analysing, self._parts = False, False, []
        return RotaryBenchProcedure(self.setup["tangential"], self.setup["radial"], info.nominal_rate,
                                    plan=self.setup["plan"], repeats=self.setup["repeats"],
                                    seconds=self.setup["seconds"])

    def compose_body(self) -> ComposeResult:
        yield Static("", id="rotary-setup")
        yield LinePlot("sensitivity per step (counts per m/s²)", x_label="step", id="sensitivity-plot")

    def begin(self) -> None:
        self.ask_setup()

    @work(exclusive=True, group="rotary-setup")
    async def ask_setup(self) -> None:
        answer = await self.app.push_screen_wait(RotarySetupScreen())
        if answer is None:
            self.app.pop_screen()
            return
        self.setup = answer
        self.query_one("#rotary-setup", Static).update(
            f"tangential {answer['tangential']}   radial {answer['radial']}   "
            f"{len(answer['plan'])} settings x {answer['repeats']} repeats x {answer['seconds']:g} s")
        self.start()

    def opening_instruction(self) -> str:
        return self.procedure.next_step().instruction + ": press space when the bench runs steadily"

    # ------------------------------------------------------------------ recording steps
    def action_record_step(self) -> None:
        if self.procedure is None or self.procedure.done or self.analysing or self.session is None:
            return
        self.armed = True
        self._parts = []
        step = self.procedure.next_step()
        self.set_instruction(f"recording {step.seconds:g} s at {step.frequency:g} Hz, "
                             f"{step.amplitude_deg:g} degrees ...")

    def feed_chunk(self, chunk) -> list:
        if not self.armed:
            return []  # between steps the stream is only watched
        self._parts.append((chunk.t, chunk.counts, chunk.channels["theta"]))
        t = np.concatenate([p[0] for p in self._parts])
        step = self.procedure.next_step()
        if t[-1] - t[0] < step.seconds:
            return [Note("progress", "", min((t[-1] - t[0]) / step.seconds, 1.0))]
        keep = t - t[0] <= step.seconds
        counts = np.concatenate([p[1] for p in self._parts])[keep]
        theta = np.concatenate([p[2] for p in self._parts])[keep]
        self.armed = False
        self.analysing = True
        recording = Recording(t[keep] - t[0], counts.astype(float), "counts", {"theta": theta}, dict(self.meta))
        self.analyse(recording)
        return [Note("instruction", f"analysing step {step.index + 1} ...", 1.0)]

    @work(thread=True, exclusive=True, group="rotary-analyse")
    def analyse(self, recording: Recording) -> None:
        step = self.procedure.next_step()
        try:
            result = self.procedure.submit(recording)
        except AccelrigError as exc:
            self.app.call_from_thread(self.step_failed, step, str(exc))
            return
        self.app.call_from_thread(self.step_done, step, result)

    def step_failed(self, step, message: str) -> None:
        self.analysing = False
        self.handle([Note("problem", f"step {step.index + 1} not kept: {message}; press space to record it again")])

    def step_done(self, step, result) -> None:
        self.analysing = False
        figures = "   ".join(f"{axis}: {s.value:.2f} ± {s.uncertainty:.2g}" for axis, s in result.sensitivity.items())
        notes = [Note("captured", f"step {step.index + 1} ({step.frequency:g} Hz, {step.amplitude_deg:g} deg, "
                                  f"repeat {step.repeat}): sensitivity {figures} counts per m/s²")]
        notes += [Note("problem", w) for w in result.warnings]
        following = self.procedure.next_step()
        if following is not None:
            notes.append(Note("instruction", following.instruction + ": press space when the bench runs steadily"))
        else:
            notes.append(Note("ready", "all steps recorded"))
        self.handle(notes)
        styles = ("red", "green", "dodger_blue1")
        series = [Series(np.arange(1, len(v) + 1, dtype=float), v, styles["xyz".index(axis)] if axis in "xyz" else "white",
                         axis, join=len(v) > 1)
                  for axis, v in self.procedure.sensitivities().items()]
        self.query_one("#sensitivity-plot", LinePlot).set_series(series)
        self.query_one("#progress").update(progress=len(self.procedure.results) / len(self.procedure.steps))

    def handle(self, events: list) -> None:
        super().handle([e for e in events if e.message])
        for event in events:
            if not event.message and event.progress is not None:
                self.query_one("#progress").update(progress=(len(self.procedure.results) + event.progress)
                                                   / len(self.procedure.steps))

    def compute_result(self):
        return self.procedure.report()

    def result_screen(self, result, recording) -> Screen:
        return CampaignScreen(result)


class CampaignScreen(Screen):
    """The campaign statistics of the steps recorded (repeatability, linearity, budget), as given."""

    BINDINGS = [Binding("escape", "close", "Close")]

    def __init__(self, report: dict):
        super().__init__()
        self.report = report

    def compose(self) -> ComposeResult:
        yield Header()
        with VerticalScroll(id="results"):
            yield Static("[b]rotary bench: campaign report[/b] (values k = 1 unless labelled)")
            yield Static(yaml.safe_dump(to_plain(self.report), sort_keys=False, width=100), id="campaign-report",
                         markup=False)
        yield Footer()

    def on_mount(self) -> None:
        self.sub_title = "campaign"

    def action_close(self) -> None:
        self.app.pop_screen()
