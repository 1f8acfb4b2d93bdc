"""The one contract every rig's procedure meets; the CLI and the TUI drive procedures only through it.

A procedure is a live object.  It is made from its declared ``settings`` (the
values a person typed, already parsed by ``accelrig.settings``) and the facts
of the device or file the samples come from (``device``: the recording / device
metadata dict: rate, range_g, scale, channels, identity, ...).  Then:

    feed(chunk) -> events      new samples: ``chunk.t`` (n,) s, ``chunk.acc`` (n, 3) m/s^2
                               (uncalibrated, counts x nominal scale), ``chunk.channels``
                               ({name: (n,)}, e.g. ``step``, ``theta``).  A ring-buffer Chunk
                               and an SI Recording both qualify: a file is fed as one chunk.
    act(action) -> events      an operator action named in ``actions`` (capture a step, redo a face)
    finish() -> events         the source ended: close what is in progress
    progress                   0..1 towards enough data
    done                       enough data: ``result()`` may be called
    complete                   the guided sequence is through (a face computes on its own); ``done``
                               unless the procedure asks for more than the minimum (static: the drift check)
    result()                   the estimate: a CalibrationResult (accelrig.result), with its
                               uncertainty, warnings and arrays to plot

``Event`` is the only thing a procedure says to a person.  Faces (CLI, TUI)
hold no calibration logic: they render settings, feed chunks, show events, map
keys to ``actions`` and show the result.
"""

from __future__ import annotations

import abc
from dataclasses import dataclass, field
from typing import ClassVar

from accelrig.errors import DataError
from accelrig.settings import Setting

# Event kinds, from least to most urgent.  A display may style them; code may branch on them.
EVENT_KINDS = ("progress", "captured", "instruction", "ready", "problem")


@dataclass
class Event:
    """One thing to tell the operator.

    kind      progress | captured | instruction | ready | problem (see EVENT_KINDS)
    message   for people, one sentence, numbers with units
    progress  0..1 towards enough data, when the event moves it
    data      the event's figures as numbers, for displays (face, step, turns, speed, ...)
    """

    kind: str
    message: str
    progress: float | None = None
    data: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.kind not in EVENT_KINDS:
            raise ValueError(f"event kind {self.kind!r} is not one of {EVENT_KINDS}")


class Procedure(abc.ABC):
    """Base of the four rigs' procedures (static, wheel, slider-crank, rotary)."""

    name: ClassVar[str]                     # 'static', 'wheel', 'slider-crank', 'rotary'
    title: ClassVar[str]                    # for people: 'six-face static calibration'
    settings: ClassVar[tuple[Setting, ...]] = ()
    # what the settings need together that no one field says (the wheel: the radius, the tilt, or both);
    # the settings form shows it under its title
    settings_note: ClassVar[str] = ""
    actions: ClassVar[dict[str, str]] = {}  # action -> what it does, for keys and help
    # actions that need no new samples (finish with what was taken): still possible once the source ended
    closing_actions: ClassVar[tuple[str, ...]] = ()
    channels_needed: ClassVar[tuple[str, ...]] = ()  # device channels the procedure cannot do without

    @classmethod
    def create(cls, values: dict, device: dict, **arguments) -> Procedure:
        """A fresh procedure from parsed setting values (every declared name present) and device facts;
        ``arguments``: what a rig takes beyond them (the slider-crank's correction under test)."""
        return cls(values, device, **arguments)

    @abc.abstractmethod
    def feed(self, chunk) -> list[Event]:
        """Take new samples; return what the operator should be told."""

    def act(self, action: str, **arguments) -> list[Event]:
        """Carry out an operator action listed in ``actions``."""
        raise DataError(f"{self.title} has no action {action!r}",
                        f"its actions are: {', '.join(self.actions) or 'none'}")

    def finish(self) -> list[Event]:
        """The source ended (a file, a scripted rig): close what is in progress."""
        return []

    @property
    @abc.abstractmethod
    def progress(self) -> float:
        """0..1 towards enough data."""

    @property
    @abc.abstractmethod
    def done(self) -> bool:
        """Enough data for ``result()``."""

    @property
    def complete(self) -> bool:
        """The guided sequence is through: what a face waits for before computing on its own."""
        return self.done

    @abc.abstractmethod
    def result(self):
        """The estimate with its uncertainty (a CalibrationResult); raises CalibrationError/DataError if it cannot."""
