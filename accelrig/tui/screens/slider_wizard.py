"""The slider-crank wizard: drives accelrig.procedures.slider_crank.SliderCrankProcedure.

Asks the stand's geometry (caliper crank radius, rod length, clearance), the
motor speed steps and the seconds to capture per step, lists the steps, tells
the operator the next speed, and takes each step's samples one of two ways:

* a stand that marks its steps (a ``step`` channel carrying the index of the
  step running steadily, -1 while the motor settles): each step as its index
  ends, no key needed;
* any other device (a real rig without step marks): the operator sets the
  speed, waits until the motor runs steadily and presses space; the next
  seconds of the stream are the step.

Each step is analysed by the procedure as it is taken and the frequency
response plot fills in; after the last step the verification opens.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from textual import work
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import VerticalScroll
from textual.screen import Screen
from textual.widgets import DataTable, Footer, Header, Static

from accelrig.errors import AccelrigError
from accelrig.procedures.slider_crank import DEFAULT_STEPS_HZ, SliderCrankProcedure
from accelrig.recording import Recording
from accelrig.tui.screens.legacy_wizard import LegacyWizard, SetupForm
from accelrig.tui.widgets.plot import LinePlot, Series


# Seconds of steady running captured per step with space: the procedure needs at least 1 s;
# twice that halves the variance of the first harmonic and is still quick at the bench.
DEFAULT_CAPTURE_SECONDS = 2.0


@dataclass
class Note:
    """An event for the wizard's log (the procedure itself returns step results, not events)."""

    kind: str
    message: str
    progress: float | None = None


def parse_number(text: str, what: str, low: float, high: float, default: float | None = None) -> float:
    text = text.strip()
    if not text:
        if default is None:
            raise ValueError(f"{what} is needed")
        return default
    try:
        value = float(text)
    except ValueError:
        raise ValueError(f"{what} {text!r} is not a number") from None
    if not low <= value <= high:
        raise ValueError(f"{what} {value:g} is outside {low:g} .. {high:g}")
    return value


def parse_steps(text: str) -> list[float]:
    text = text.strip()
    if not text:
        return list(DEFAULT_STEPS_HZ)
    try:
        steps = [float(item) for item in text.replace(" ", ",").split(",") if item]
    except ValueError:
        raise ValueError(f"steps {text!r} are not numbers (write them like 2.5,4,6)") from None
    if not steps or any(s <= 0 for s in steps):
        raise ValueError("steps must be positive speeds in Hz")
    return steps


class SliderSetupScreen(SetupForm):
    """The stand's geometry and the speed steps."""

    FIELDS = (("radius", "Caliper crank radius, m:", "e.g. 0.00635"),
              ("rod", "Connecting rod length, m:", "e.g. 0.0353"),
              ("clearance", "Clearance on the radius, m (blank: 0):", "e.g. 0.0001"),
              ("steps", "Motor speed steps, Hz (blank: " + ",".join(f"{s:g}" for s in DEFAULT_STEPS_HZ) + "):",
               "e.g. 2.5,4,6,8"),
              ("seconds", f"Seconds captured per step with space, for a device that marks no steps "
               f"(blank: {DEFAULT_CAPTURE_SECONDS:g}):", f"{DEFAULT_CAPTURE_SECONDS:g}"),
              ("profile", "Profile whose calibration is verified (blank: raw data):", "e.g. sensor.yaml"))

    def parse(self, value: dict[str, str]) -> dict:
        answer = {
            "radius": parse_number(value["radius"], "crank radius", 1e-4, 1.0),
            "rod": parse_number(value["rod"], "rod length", 1e-4, 10.0),
            "clearance": parse_number(value["clearance"], "clearance", 0.0, 0.1, default=0.0),
            "steps": parse_steps(value["steps"]),
            "seconds": parse_number(value["seconds"], "seconds per step", 0.5, 600.0,
                                    default=DEFAULT_CAPTURE_SECONDS),
            "profile": value["profile"] or None,
            "correction": None,
        }
        if answer["profile"]:
            from accelrig.profiles import load_profile

            answer["correction"] = load_profile(answer["profile"]).correction
        return answer


class SliderCrankWizard(LegacyWizard):
    wizard_title = "slider-crank verification"
    capture_name = "slider-crank"
    progress_label = "steps"
    BINDINGS = [Binding("space", "capture_step", "Capture step")]

    def __init__(self, session):
        super().__init__(session)
        self.setup: dict | None = None
        self.marked = False      # the device marks its steps (a 'step' channel)
        self.armed = False       # space pressed: the coming seconds are the step
        self._pending_t: list[np.ndarray] = []
        self._pending_acc: list[np.ndarray] = []
        self._pending_step: list[np.ndarray] = []

    def make_procedure(self) -> SliderCrankProcedure:
        info = (self.session or self.app.session).info
        self.marked = "step" in info.channels
        self.armed = False
        self._pending_t, self._pending_acc, self._pending_step = [], [], []
        self.meta = {k: v for k, v in info.to_dict().items() if k != "extra"}
        return SliderCrankProcedure(self.setup["radius"], self.setup["rod"], self.setup["clearance"],
                                    steps=self.setup["steps"], correction=self.setup["correction"],
                                    profile=self.setup["profile"])

    def compose_body(self) -> ComposeResult:
        yield Static("", id="slider-geometry")
        yield Static("", id="slider-steps")
        yield LinePlot("frequency response: first harmonic (m/s²)", x_label="Hz", id="fr-plot")

    def begin(self) -> None:
        self.ask_setup()

    @work(exclusive=True, group="slider-setup")
    async def ask_setup(self) -> None:
        answer = await self.app.push_screen_wait(SliderSetupScreen())
        if answer is None:
            self.app.pop_screen()
            return
        self.setup = answer
        self.query_one("#slider-geometry", Static).update(
            f"crank {answer['radius'] * 1e3:g} mm   rod {answer['rod'] * 1e3:g} mm   "
            f"clearance ±{answer['clearance'] * 1e3:g} mm   "
            + (f"verifying {answer['profile']}" if answer["profile"] else "raw data (no profile)"))
        self.start()
        if self.procedure is not None:
            self.show_steps()

    def opening_instruction(self) -> str:
        return self.step_prompt(self.procedure.next_step())

    def step_prompt(self, step) -> str:
        if self.marked:
            return step.text + " (the stand marks the step: it is taken when it ends)"
        return step.text + f" Press space to capture {self.setup['seconds']:g} s."

    # ------------------------------------------------------------------ taking steps
    def action_capture_step(self) -> None:
        if self.procedure is None or self.procedure.done or self.session is None or self.finished:
            return
        if self.marked:
            self.log_event("this stand marks its steps in its 'step' channel: each is taken when it ends", "yellow")
            return
        if self._finished_source:
            self.log_event("the source has ended: there is nothing more to capture (escape, then connect again)",
                           "yellow")
            return
        self.armed = True
        self._pending_t, self._pending_acc = [], []
        step = self.procedure.next_step()
        self.set_instruction(f"capturing step {step.index + 1} for {self.setup['seconds']:g} s: keep the speed ...")

    def feed_chunk(self, chunk) -> list:
        if not self.marked:
            return self._capture_manual(chunk)
        self._pending_t.append(chunk.t)
        self._pending_acc.append(chunk.acceleration())
        self._pending_step.append(chunk.channels["step"])
        return self._take_complete_steps(end_of_data=False)

    def source_ended(self) -> list:
        if not self.marked:
            if self.armed:
                self.armed = False
                return [Note("problem", "the source ended during the capture: the step was not taken")]
            return []
        return self._take_complete_steps(end_of_data=True)

    def _capture_manual(self, chunk) -> list:
        """Between space presses the stream is only watched; after one, the next seconds are the step."""
        if not self.armed:
            return []
        self._pending_t.append(chunk.t)
        self._pending_acc.append(chunk.acceleration())
        t = np.concatenate(self._pending_t)
        seconds = self.setup["seconds"]
        if t[-1] - t[0] < seconds:
            return []
        keep = t - t[0] <= seconds
        acc = np.concatenate(self._pending_acc)[keep]
        self.armed = False
        self._pending_t, self._pending_acc = [], []
        return self._add_step(Recording(t[keep], acc, "m/s^2", {}, dict(self.meta)))

    def _take_complete_steps(self, end_of_data: bool) -> list:
        if not self._pending_t:
            return []
        t = np.concatenate(self._pending_t)
        acc = np.concatenate(self._pending_acc)
        step = np.concatenate(self._pending_step)
        notes: list[Note] = []
        # runs of a constant step value; the last run is complete only at the end of the data
        edges = np.flatnonzero(np.diff(step)) + 1
        starts = np.concatenate([[0], edges])
        stops = np.concatenate([edges, [step.size]])
        if not end_of_data:
            starts, stops = starts[:-1], stops[:-1]
        consumed = 0
        for a, b in zip(starts, stops):
            consumed = b
            value = int(step[a])
            if value < 0 or self.procedure.done:
                continue  # the motor settling between steps
            expected = self.procedure.next_step().index
            if value != expected:
                notes.append(Note("problem", f"the stand ran step {value} while step {expected} was due: ignored"))
                continue
            notes += self._add_step(Recording(t[a:b], acc[a:b], "m/s^2", {}, dict(self.meta)))
        self._pending_t = [t[consumed:]]
        self._pending_acc = [acc[consumed:]]
        self._pending_step = [step[consumed:]]
        return notes

    def _add_step(self, recording: Recording) -> list[Note]:
        index = len(self.procedure.results)
        total = len(self.procedure.schedule)
        try:
            result = self.procedure.add_step(recording, label=f"step {index + 1}")
        except AccelrigError as exc:
            again = "" if self.marked else "; press space to capture it again"
            return [Note("problem", f"step {index + 1} not kept: {exc}{again}")]
        self.show_steps()
        self.show_response()
        notes = [Note("captured", f"step {index + 1}: {result.frequency_hz.value:.3f} Hz, first harmonic "
                                  f"{result.amplitude.value:.3f} ± {result.amplitude.uncertainty:.2g} m/s², radius "
                                  f"{result.radius_m.value * 1e3:.4f} ± {result.radius_m.uncertainty * 1e3:.2g} mm",
                      (index + 1) / total)]
        following = self.procedure.next_step()
        if following is not None:
            notes.append(Note("instruction", self.step_prompt(following)))
        else:
            notes.append(Note("ready", "all steps captured"))
        return notes

    def show_steps(self) -> None:
        done = len(self.procedure.results)
        cells = []
        for i, speed in enumerate(self.procedure.schedule):
            mark = "[green]✓[/]" if i < done else ("[b]▶[/]" if i == done else "·")
            cells.append(f"{mark} {speed:g}")
        self.query_one("#slider-steps", Static).update("steps (Hz): " + "  ".join(cells))

    def show_response(self) -> None:
        steps = self.procedure.results
        f = np.array([s.frequency_hz.value for s in steps])
        measured = np.array([s.amplitude.value for s in steps])
        model = np.array([s.model_amplitude for s in steps])
        self.query_one("#fr-plot", LinePlot).set_series([
            Series(f, model, "dodger_blue1", "model r ω²"),
            Series(f, measured, "yellow", "measured", join=False),
        ])

    def compute_result(self):
        return self.procedure.finish()

    def result_screen(self, result, recording) -> Screen:
        return VerificationScreen(result)


class VerificationScreen(Screen):
    """A slider-crank verification: verdict, radius from the motion, steps, frequency response."""

    BINDINGS = [Binding("escape", "close", "Close")]

    def __init__(self, verification):
        super().__init__()
        self.verification = verification

    def compose(self) -> ComposeResult:
        v = self.verification
        colour = {"holds": "green", "does not hold": "red"}.get(v.verdict, "yellow")
        yield Header()
        with VerticalScroll(id="results"):
            yield Static(f"[b]slider-crank verification: [{colour}]{v.verdict}[/][/b]\n{v.verdict_reason}",
                         id="verdict")
            yield Static(f"radius from the motion {v.radius_m.value * 1e3:.4f} ± {v.radius_m.uncertainty * 1e3:.2g} mm "
                         f"(k = 1, chi² {v.radius_chi2:.3g} for {v.radius_dof} dof); caliper "
                         f"{v.crank_radius * 1e3:g} ± {v.clearance * 1e3:g} mm"
                         + (f"; motor tops out near {v.rolloff_hz:.2f} Hz" if v.rolloff_hz is not None else ""),
                         id="verification-radius")
            yield DataTable(id="steps", show_cursor=False, zebra_stripes=True)
            yield LinePlot("frequency response: first harmonic (m/s²)", x_label="Hz", id="verification-plot")
            yield Static("\n".join(f"[yellow]warning:[/] {w}" for w in v.warnings), id="verification-warnings")
        yield Footer()

    def on_mount(self) -> None:
        self.sub_title = "verification"
        table = self.query_one("#steps", DataTable)
        table.add_columns("step", "Hz", "amplitude", "u", "model", "radius mm", "u mm", "flags")
        for s in self.verification.steps:
            flags = [name for name, on_ in (("motor-limited", s.motor_limited), ("backlash", s.backlash),
                                            ("unsteady", s.speed_unsteady), ("outside", not s.within_clearance)) if on_]
            table.add_row(s.label, f"{s.frequency_hz.value:.3f}", f"{s.amplitude.value:.4g}",
                          f"{s.amplitude.uncertainty:.2g}", f"{s.model_amplitude:.4g}",
                          f"{s.radius_m.value * 1e3:.4f}", f"{s.radius_m.uncertainty * 1e3:.2g}", " ".join(flags))
        response = self.verification.frequency_response()
        self.query_one("#verification-plot", LinePlot).set_series([
            Series(response["frequency_hz"], response["model_amplitude"], "dodger_blue1", "model r ω²"),
            Series(response["frequency_hz"], response["amplitude"], "yellow", "measured", join=False),
        ])

    def action_close(self) -> None:
        self.app.pop_screen()
