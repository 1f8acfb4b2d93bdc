"""The rotary bench at the bench, on the Procedure contract (no UI code here).

The operator sets the motor to a frequency and an oscillation angle and arms
a capture (``act("capture")``); the shared step capture takes the step's
seconds from the stream, raw samples with the ``theta`` encoder angle beside
them, and each step's sensitivity comes as an event.  ``result()`` is the
campaign over the steps done (repeatability, linearity, budget), the same
analysis as ``accelrig calibrate rotary --campaign``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from accelrig.errors import AccelrigError, DataError, DeviceError
from accelrig.procedures.contract import Event, Procedure
from accelrig.procedures.rotary.bench import RotarySetup, RotaryTest, analyse_test, parse_axis_name
from accelrig.procedures.rotary.campaign import Campaign, CampaignTest, analyse_campaign
from accelrig.procedures.rotary.settings import PAPER_PLAN, SETTINGS
from accelrig.procedures.steps import StepCapture
from accelrig.result import CalibrationResult

# how far the swing the encoder measures may be from the plan's angle (relative; at least 1 degree): a motor
# set by hand to the plan's angle lands within a few per cent; a step run at another angle is caught
AMPLITUDE_TOLERANCE = 0.10


@dataclass(frozen=True)
class RotaryStep:
    """One thing for the operator to do: run the motor at ``frequency`` and ``amplitude_deg``."""

    index: int
    frequency: float  # Hz
    amplitude_deg: float  # peak to peak, as the paper's oscillation angle
    repeat: int
    seconds: float

    @property
    def instruction(self) -> str:
        return (f"Set the motor to {self.frequency:g} Hz, {self.amplitude_deg:g} degrees peak to peak; "
                f"record {self.seconds:g} s (repeat {self.repeat})")


def parse_plan(text: str | None) -> tuple[tuple[float, float], ...]:
    """'5:34,8:13' -> ((5, 34), (8, 13)); blank: the paper's plan."""
    if not text or not text.strip():
        return PAPER_PLAN
    plan = []
    for item in text.replace(" ", "").split(","):
        try:
            frequency, angle = (float(v) for v in item.split(":"))
        except ValueError:
            raise DataError(f"plan step {item!r} is not FREQUENCY:DEGREES", "e.g. 5:34,8:13") from None
        if frequency <= 0 or angle <= 0:
            raise DataError(f"plan step {item!r}: frequency and angle must be positive")
        plan.append((frequency, angle))
    return tuple(plan)


class RotaryProcedure(Procedure):
    """Steps through (frequency, amplitude) x repeats for one mounting of one sensor."""

    name = "rotary"
    title = "rotary bench calibration"
    settings = SETTINGS
    actions = {"capture": "record the current step's seconds from now (the bench runs steadily)",
               "finish": "end the session: the campaign of the steps recorded so far"}
    closing_actions = ("finish",)
    channels_needed = ("theta",)

    def __init__(self, values: dict, device: dict):
        if "theta" not in device.get("channels", ()):
            raise DeviceError(f"{device.get('url', 'the device')} delivers no encoder angle (no 'theta' channel)",
                              "record each step with its encoder log and use 'accelrig calibrate rotary'")
        parse_axis_name(values["tangential"], "tangential")
        parse_axis_name(values["radial"], "radial")
        self.tangential, self.radial = values["tangential"], values["radial"]
        self.nominal_rate = float(device["nominal_rate"])
        self.setup = RotarySetup(radius=values["radius"], radius_uncertainty=values["radius_uncertainty"],
                                 ref_radius=values["ref_radius"])
        self.rate_method = values["rate_method"]
        repeats, seconds = values["repeats"], values["seconds"]
        self.steps = [RotaryStep(i * repeats + r, float(f), float(a), r + 1, float(seconds))
                      for i, (f, a) in enumerate(parse_plan(values["plan"])) for r in range(repeats)]
        self.results: list[tuple[RotaryStep, RotaryTest]] = []
        # what each kept step was computed from, for the certificate's traceability (hash, samples, when)
        self.records: list[dict] = []
        # the device's name stands for the sensor in the campaign's tables and its certificate
        self.sensor = str(device.get("identity") or device.get("url") or "sensor")
        self.capture = StepCapture(device)
        self._finish_requested = False

    def next_step(self) -> RotaryStep | None:
        return None if self.done else self.steps[len(self.results)]

    def instruction(self) -> str:
        """What to do now."""
        step = self.next_step()
        if step is None:
            return "all steps recorded"
        return step.instruction + ": press space when the bench runs steadily"

    @property
    def progress(self) -> float:
        return (len(self.results) + (self.capture.progress or 0.0)) / len(self.steps)

    @property
    def done(self) -> bool:
        return len(self.results) == len(self.steps) or self._finish_requested

    def act(self, action: str, **arguments) -> list[Event]:
        if action == "finish":
            if not self.results:
                return [Event("problem", "no step recorded yet: record at least one (space)")]
            self._finish_requested = True
            self.capture.finish()
            return [Event("ready", f"the campaign of the {len(self.results)} of {len(self.steps)} planned steps "
                                   "recorded")]
        if action != "capture":
            return super().act(action, **arguments)
        step = self.next_step()
        if step is None or self.capture.armed:
            return []
        self.capture.arm(step.seconds)
        return [Event("instruction", f"recording {step.seconds:g} s at {step.frequency:g} Hz, "
                                     f"{step.amplitude_deg:g} degrees ...")]

    def feed(self, chunk) -> list[Event]:
        events = []
        for captured in self.capture.feed(chunk):
            events += self._analyse(captured.recording)
        return events

    def finish(self) -> list[Event]:
        if self.capture.armed:
            self.capture.finish()
            return [Event("problem", "the source ended during the recording: the step was not taken")]
        return []

    def _analyse(self, recording) -> list[Event]:
        """One step's test (raw samples with their theta); a DataError leaves the step to record again."""
        step = self.next_step()
        try:
            result = analyse_test(recording, None, self.tangential, self.radial, self.nominal_rate,
                                  step.frequency, self.rate_method, self.setup)
        except AccelrigError as exc:
            return [Event("problem", f"step {step.index + 1} not kept: {exc}; press space to record it again")]
        swing = 2.0 * float(np.degrees(result.theta0.value))   # peak to peak, as the plan gives it
        if abs(swing - step.amplitude_deg) > max(AMPLITUDE_TOLERANCE * step.amplitude_deg, 1.0):
            # the campaign groups and labels the steps by the plan's angles: a step run at another angle would be
            # certified as the plan's and would falsify the linearity between the amplitudes
            return [Event("problem", f"step {step.index + 1} not kept: the encoder shows the bench swinging "
                                     f"{swing:.1f} degrees peak to peak, the plan says {step.amplitude_deg:g}; set "
                                     f"the motor to {step.amplitude_deg:g} degrees and press space to record it "
                                     "again (or change the plan)")]
        self.results.append((step, result))
        self.records.append({"test": step.index + 1, "recording_hash": recording.content_hash(),
                             "samples": len(recording),
                             "captured": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())})
        figures = "   ".join(f"{axis}: {s.value:.2f} ± {s.uncertainty:.2g}" for axis, s in result.sensitivity.items())
        events = [Event("captured", f"step {step.index + 1} ({step.frequency:g} Hz, {step.amplitude_deg:g} deg, "
                                    f"repeat {step.repeat}): sensitivity {figures} counts per m/s²", self.progress,
                        {"step": step.index, **{axis: s.value for axis, s in result.sensitivity.items()}})]
        events += [Event("problem", w) for w in result.warnings]
        events.append(Event("ready", "all steps recorded") if self.done else Event("instruction", self.instruction()))
        return events

    def result(self) -> CalibrationResult:
        """The campaign statistics of the steps done so far (needs two amplitudes for linearity)."""
        if not self.results:
            raise DataError("no step of this rotary session is done yet")
        tests = [
            CampaignTest(step.index + 1, self.sensor, f"{step.frequency:g}hz_{step.amplitude_deg:g}deg_r{step.repeat}",
                         "(live)", None, {"tangential": self.tangential, "radial": self.radial,
                                          "nominal_rate": self.nominal_rate, "rate_method": self.rate_method},
                         self.setup)
            for step, _ in self.results
        ]
        campaign = Campaign(name=f"{self.sensor}: live session", tests=tests)
        result = analyse_campaign(campaign, [r for _, r in self.results])
        result.details["records"] = [dict(r) for r in self.records]
        if len(self.results) < len(self.steps):
            result.warnings.insert(0, f"{len(self.results)} of the {len(self.steps)} planned steps were recorded: "
                                      "the campaign covers those only")
        return result

    def sensitivities(self) -> dict[str, np.ndarray]:
        """Per axis, the sensitivities of the steps done so far (for a live plot)."""
        out: dict[str, list[float]] = {}
        for _, result in self.results:
            for axis, s in result.sensitivity.items():
                out.setdefault(axis, []).append(s.value)
        return {k: np.asarray(v) for k, v in out.items()}
