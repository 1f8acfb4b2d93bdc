"""A sensor lying still: the recording for noise figures (Allan deviation) and smoke tests."""

from __future__ import annotations

import numpy as np

from accelrig.acquisition.url import DeviceURL
from accelrig.errors import DeviceError
from accelrig.sim.rigs.base import Rig
from accelrig.units import STANDARD_GRAVITY

_AXES = {"+x": (0, 1.0), "-x": (0, -1.0), "+y": (1, 1.0), "-y": (1, -1.0), "+z": (2, 1.0), "-z": (2, -1.0)}


class StillRig(Rig):
    name = "still"
    description = "sensor at rest on a level table (noise figures, smoke tests)"
    options = {
        "up": "sensor axis pointing up: +x, -x, +y, -y, +z (default) or -z",
        "seconds": "length of the run in s (default: endless)",
    }

    def __init__(self, up: str = "+z", duration: float | None = None, g: float = STANDARD_GRAVITY):
        if up not in _AXES:
            raise DeviceError(f"up={up!r} is not an axis", "use one of +x, -x, +y, -y, +z, -z")
        self.up = up
        self.g = g
        self.duration = duration
        axis, sign = _AXES[up]
        self._force = np.zeros(3)
        self._force[axis] = sign * g

    @classmethod
    def from_url(cls, url: DeviceURL, rng: np.random.Generator) -> "StillRig":
        return cls(up=url.get_str("up", "+z").replace(" ", "+"), duration=url.get_float("seconds"))

    def specific_force(self, t: np.ndarray) -> np.ndarray:
        return np.broadcast_to(self._force, (np.size(t), 3)).copy()

    def truth(self) -> dict:
        return {"rig": self.name, "up": self.up, "g": self.g, "specific_force": self._force.tolist()}
