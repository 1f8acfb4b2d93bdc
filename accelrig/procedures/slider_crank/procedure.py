"""The slider-crank verification on the Procedure contract: live stands and recorded files go through one object.

The operator sets each motor speed; each step is taken by the shared step
capture (a stand that marks its steps in a ``step`` channel, or a timed
capture on ``act("capture")``) and analysed as it comes; ``result()`` is the
verification over all steps.  Files are fed the same way, one source at a
time (``open_source``), which is what ``verify_slider_crank`` does.
"""

from __future__ import annotations

from accelrig.errors import AccelrigError, DataError
from accelrig.procedures.contract import Event, Procedure
from accelrig.procedures.slider_crank.analysis import (
    StepResult,
    analyse_step,
    check_geometry,
    clipped_samples,
    verify_steps,
)
from accelrig.procedures.slider_crank.settings import DEFAULT_HARMONICS, SETTINGS
from accelrig.procedures.steps import Step, StepCapture
from accelrig.recording import Recording
from accelrig.result import CalibrationResult, Correction


class SliderCrankProcedure(Procedure):
    """Tells the next motor speed, takes each step, analyses it as it comes.

    ``speeds`` are the commanded motor speeds in Hz (None: the operator
    chooses each and says when enough steps are taken; the roll-off is then
    judged from the measured speeds alone).  ``correction`` is the
    calibration under test, applied to every step first.
    """

    name = "slider-crank"
    title = "slider-crank verification"
    settings = SETTINGS
    actions = {"capture": "capture the next step for the set seconds (a stand that marks no steps)",
               "skip": "skip the step due (its speed is left out; go on to the next)",
               "verify": "verify with the steps taken so far"}
    closing_actions = ("verify",)

    def __init__(self, values: dict, device: dict, correction: Correction | None = None):
        check_geometry(values["crank_radius"], values["rod_length"], values["clearance"])
        self.crank_radius = float(values["crank_radius"])
        self.rod_length = float(values["rod_length"])
        self.clearance = float(values["clearance"])
        self.schedule = None if values["speeds"] is None else [float(s) for s in values["speeds"]]
        self.seconds = values.get("seconds")
        self.harmonics = int(values["harmonics"])
        self.profile = values["profile"]
        self.correction = correction
        self.device = dict(device)
        self.steps: list[StepResult] = []
        self.skipped: list[tuple[int, str]] = []   # (0-based position in the schedule, why)
        self.source: str | None = None   # the file being fed; None for a live stream
        self._queued: list[Step] = []
        self._verify_requested = False
        self.capture = StepCapture(self.device)
        self.marked = "step" in self.device.get("channels", ())

    # ------------------------------------------------------------------ what the operator reads
    def instruction(self) -> str:
        """What to do now."""
        i = self.position
        if self.schedule is None:
            text = f"Step {i + 1}: set the next motor speed, wait until it runs steadily, then capture."
        elif i >= len(self.schedule):
            return "all steps captured"
        else:
            speed = self.schedule[i]
            text = (f"Step {i + 1} of {len(self.schedule)}: set the motor to {speed:g} Hz ({speed * 60:.0f} rpm), "
                    "wait until it runs steadily, then capture at least 1 s.")
        if self.marked:
            return text + " (the stand marks the step: it is taken when it ends)"
        return text + f" Press space to capture {self.seconds:g} s."

    @property
    def position(self) -> int:
        """The 0-based step due: steps kept plus steps skipped."""
        return len(self.steps) + len(self.skipped)

    @property
    def progress(self) -> float:
        if not self.schedule:
            return 0.0
        return min((self.position + (self.capture.progress or 0.0)) / len(self.schedule), 1.0)

    @property
    def done(self) -> bool:
        complete = self.schedule is not None and self.position >= len(self.schedule)
        return complete or self._verify_requested

    # ------------------------------------------------------------------ samples
    def open_source(self, label: str, meta: dict) -> None:
        """Feed a recorded file next: its steps by its ``step`` column, or the whole file as one step."""
        self.source = label
        self.capture = StepCapture(meta, where=label)
        self.capture.arm(None)
        self._queued = []

    def feed(self, chunk) -> list[Event]:
        steps = self.capture.feed(chunk)
        if self.source is not None:
            self._queued += steps  # a file's steps are named once its step count is known (finish)
            return []
        return [event for step in steps for event in self._take_live(step)]

    def act(self, action: str, **arguments) -> list[Event]:
        if action == "verify":
            if not self.steps:
                return [Event("problem", "no step taken yet: capture at least one")]
            self._verify_requested = True
            return [Event("ready", f"verifying with {len(self.steps)} steps")]
        if action == "skip":
            if self.schedule is None:
                return [Event("problem", "no speeds were planned: set another speed and capture, or verify")]
            if self.done:
                return []
            return self._skip("skipped by the operator")
        if action != "capture":
            return super().act(action, **arguments)
        if self.done:
            return []
        if self.marked or self.capture.marked:
            return [Event("problem", "this stand marks its steps in its 'step' channel: each is taken when it ends")]
        self.capture.arm(self.seconds)
        return [Event("instruction", f"capturing step {len(self.steps) + 1} for {self.seconds:g} s: keep the speed ...")]

    def finish(self) -> list[Event]:
        if self.source is not None:
            steps = self._queued + self.capture.finish()
            if self.capture.marked and not self.capture.taken:
                raise DataError(f"{self.source}: the step column marks no step (all values negative: settling only)")
            for step in steps:
                label = f"{self.source} step {step.index + 1:g}" if len(steps) > 1 else self.source   # 1-based
                self.add_step(step.recording, label)
            self.source, self._queued = None, []
            return []
        interrupted = self.capture.armed
        events = [event for step in self.capture.finish() for event in self._take_live(step)]
        if interrupted:
            events.append(Event("problem", "the source ended during the capture: the step was not taken"))
        return events

    def _take_live(self, step: Step) -> list[Event]:
        if self.done:
            return []
        n = self.position
        if step.index is not None and step.index != n:
            return [Event("problem", f"the stand ran step {step.index + 1} while step {n + 1} was due: ignored")]
        try:
            result = self.add_step(step.recording, f"step {n + 1}")
        except AccelrigError as exc:
            why = str(exc).removeprefix(f"step {n + 1}: ")
            if step.index is not None:   # the stand goes on to its next step: this one is left out
                return self._skip(why)
            return [Event("problem", f"step {n + 1} not kept: {why}; press space to capture it again"
                                     + (", or skip it" if self.schedule else ""))]
        events = [Event("captured", f"step {n + 1}: {result.frequency_hz.value:.3f} Hz, first harmonic "
                                    f"{result.amplitude.value:.3f} ± {result.amplitude.uncertainty:.2g} m/s², radius "
                                    f"{result.radius_m.value * 1e3:.4f} ± {result.radius_m.uncertainty * 1e3:.2g} mm",
                        self.progress if self.schedule else None,
                        {"step": n, "frequency_hz": result.frequency_hz.value,
                         "amplitude": result.amplitude.value, "model_amplitude": result.model_amplitude})]
        if self.done:
            events.append(Event("ready", "all steps captured"))
        else:
            events.append(Event("instruction", self.instruction()))
        return events

    def _skip(self, why: str) -> list[Event]:
        n = self.position
        self.skipped.append((n, why))
        events = [Event("problem", f"step {n + 1} skipped ({why})", self.progress, {"step": n, "skipped": True})]
        if self.done:
            events.append(Event("ready", f"all steps done ({len(self.steps)} kept, {len(self.skipped)} skipped)"))
        else:
            events.append(Event("instruction", self.instruction()))
        return events

    def add_step(self, rec: Recording, label: str) -> StepResult:
        """Analyse one step.  A bad step raises DataError and is not kept (capture it again)."""
        index = self.position
        rec = rec.to_si()
        clipped = clipped_samples(rec)
        if clipped:
            raise DataError(
                f"{label}: {clipped} samples at the sensor's full scale (clipping)",
                "choose a larger range (e.g. 8 g) or a lower speed",
            )
        acc = self.correction.apply(rec.acc) if self.correction is not None else rec.acc
        commanded = None if self.schedule is None or index >= len(self.schedule) else self.schedule[index]
        result = analyse_step(
            rec.t, acc, index=index, label=label, crank_radius=self.crank_radius,
            rod_length=self.rod_length, clearance=self.clearance, commanded_hz=commanded, harmonics=self.harmonics,
        )
        self.steps.append(result)
        return result

    def result(self) -> CalibrationResult:
        if self.schedule is not None and self.position != len(self.schedule) and not self._verify_requested:
            raise DataError(f"{len(self.schedule)} commanded speeds for {len(self.steps)} steps",
                            "give one speed per step")
        if not self.steps:
            raise DataError("no step was kept", "; ".join(f"step {n + 1} {why}" for n, why in self.skipped)
                            or "capture at least one step")
        result = verify_steps(self.steps, self.crank_radius, self.rod_length, self.clearance, self.profile,
                              self.correction)
        result.warnings = [f"step {n + 1} left out: {why}" for n, why in self.skipped] + list(result.warnings)
        return result


def verify_slider_crank(
    recordings: list[tuple[str, Recording]],
    crank_radius: float,
    rod_length: float,
    clearance: float = 0.0,
    correction: Correction | None = None,
    speeds: list[float] | None = None,
    harmonics: int = DEFAULT_HARMONICS,
    profile: str | None = None,
) -> CalibrationResult:
    """Batch form: (label, recording) pairs, each one step or several by their ``step`` column."""
    values = {"crank_radius": crank_radius, "rod_length": rod_length, "clearance": clearance, "speeds": speeds,
              "harmonics": harmonics, "profile": profile}
    procedure = SliderCrankProcedure(values, {}, correction)
    for label, rec in recordings:
        procedure.open_source(label, rec.meta)
        procedure.feed(rec.to_si())
        procedure.finish()
    return procedure.result()
