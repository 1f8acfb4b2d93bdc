"""The interface every simulated rig implements."""

from __future__ import annotations

import abc
from typing import ClassVar

import numpy as np

from accelrig.acquisition.url import DeviceURL


class Rig(abc.ABC):
    """Physics of a rig: the true specific force at the sensor, as a function of time.

    The calibration rigs describe the sensor's trajectory, ``position(t)`` and
    ``orientation(t)``, and leave the specific force to accelrig.sim.kinematics:
    no rig writes down its own acceleration, so no estimator's equation is
    restated in the truth it is judged against.

    ``specific_force`` and ``channels`` are pure functions of time (any random
    script, such as the operator's handling between poses, is drawn once in
    ``from_url`` from the seeded generator), so a rig can be sampled in blocks
    of any size and gives the same answer.
    """

    name: ClassVar[str]
    description: ClassVar[str]
    # URL option -> one-line help; the sim driver refuses any other option.
    options: ClassVar[dict[str, str]] = {}
    # extra per-sample channels this rig delivers (e.g. "theta", "step")
    channel_names: tuple[str, ...] = ()
    # seconds of scripted scenario; None for an endless one
    duration: float | None = None
    # the full scale (g) of a sim:// sensor on this rig when the URL gives no range=: one the rig's motion fits in
    default_range_g: ClassVar[float] = 2.0

    @classmethod
    @abc.abstractmethod
    def from_url(cls, url: DeviceURL, rng: np.random.Generator) -> Rig:
        """Build the rig from its URL options, drawing any random script from ``rng``."""

    @abc.abstractmethod
    def specific_force(self, t: np.ndarray) -> np.ndarray:
        """True specific force at the sensor, body frame, m/s^2, shape (n, 3).

        Sign convention: at rest the axis pointing up reads +g.
        """

    def channels(self, t: np.ndarray) -> dict[str, np.ndarray]:
        """Extra channels at the (true) sample times."""
        return {}

    @abc.abstractmethod
    def truth(self) -> dict:
        """JSON-serialisable ground truth of the rig (geometry, script, motion law)."""
