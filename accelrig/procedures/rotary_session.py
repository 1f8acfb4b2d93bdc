"""The rotary bench as operator steps, for the TUI (no UI code here).

The operator sets the motor to a frequency and an oscillation angle, records,
and sees the sensitivity of each step as it comes; at the end the steps are
a campaign (repeatability, linearity, budget).  The TUI drives
:class:`RotaryBenchProcedure`; the CLI's campaign runs the same analysis.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass

import numpy as np

from accelrig.errors import DataError
from accelrig.procedures.rotary_bench import (
    PAPER_PLAN,
    RATE_METHODS,
    EncoderLog,
    RotarySetup,
    RotaryTest,
    analyse_test,
    parse_axis_name,
)
from accelrig.procedures.rotary_campaign import Campaign, CampaignTest, analyse_campaign
from accelrig.recording import Recording


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


class RotaryBenchProcedure:
    """Steps through (frequency, amplitude) x repeats for one mounting of one sensor."""

    name = "rotary"

    def __init__(
        self,
        tangential: str,
        radial: str,
        nominal_rate: float,
        plan=PAPER_PLAN,
        repeats: int = 6,
        seconds: float = 40.0,
        setup: RotarySetup | None = None,
        rate_method: str = "fit",
        sensor: str = "sensor",
        correlation: float = 1.0,
    ):
        parse_axis_name(tangential, "tangential")
        parse_axis_name(radial, "radial")
        if rate_method not in RATE_METHODS:
            raise DataError(f"rate method {rate_method!r} is not one of {', '.join(RATE_METHODS)}")
        if repeats < 1 or seconds <= 0 or not plan:
            raise DataError("a rotary session needs a plan, at least one repeat and a positive length")
        self.tangential, self.radial = tangential, radial
        self.nominal_rate = float(nominal_rate)
        self.setup = setup or RotarySetup()
        self.rate_method = rate_method
        self.sensor = sensor
        self.correlation = correlation
        self.steps = [
            RotaryStep(i * repeats + r, float(f), float(a), r + 1, float(seconds))
            for i, (f, a) in enumerate(plan) for r in range(repeats)
        ]
        self.results: list[tuple[RotaryStep, RotaryTest]] = []

    @property
    def done(self) -> bool:
        return len(self.results) == len(self.steps)

    def next_step(self) -> RotaryStep | None:
        return None if self.done else self.steps[len(self.results)]

    def submit(self, mems: Recording, encoder: EncoderLog | None = None) -> RotaryTest:
        """Analyse the recording of the current step; on a DataError the step stays pending (record again)."""
        step = self.next_step()
        if step is None:
            raise DataError("every step of this rotary session is done")
        result = analyse_test(mems, encoder, self.tangential, self.radial, self.nominal_rate,
                              step.frequency, self.rate_method, self.setup)
        self.results.append((step, result))
        return result

    def run(self, acquire: Callable[[RotaryStep], tuple[Recording, EncoderLog | None]]
            ) -> Iterator[tuple[RotaryStep, RotaryTest]]:
        """Drive every pending step: ``acquire(step)`` records it; yields each result as it comes."""
        while (step := self.next_step()) is not None:
            mems, encoder = acquire(step)
            yield step, self.submit(mems, encoder)

    def report(self) -> dict:
        """The campaign statistics of the steps done so far (needs two amplitudes for linearity)."""
        if not self.results:
            raise DataError("no step of this rotary session is done yet")
        tests = [
            CampaignTest(step.index, self.sensor, f"{step.frequency:g}hz_{step.amplitude_deg:g}deg_r{step.repeat}",
                         "(live)", None, {"tangential": self.tangential, "radial": self.radial,
                                          "nominal_rate": self.nominal_rate, "rate_method": self.rate_method},
                         self.setup)
            for step, _ in self.results
        ]
        campaign = Campaign(name=f"{self.sensor} live session", tests=tests, correlation=self.correlation)
        return analyse_campaign(campaign, [r for _, r in self.results])

    def sensitivities(self) -> dict[str, np.ndarray]:
        """Per axis, the sensitivities of the steps done so far (for a live plot)."""
        out: dict[str, list[float]] = {}
        for _, result in self.results:
            for axis, s in result.sensitivity.items():
                out.setdefault(axis, []).append(s.value)
        return {k: np.asarray(v) for k, v in out.items()}
