"""A sensor lying still: the recording for noise figures (Allan deviation) and smoke tests."""

from __future__ import annotations

import numpy as np

from accelrig.acquisition.url import DeviceURL
from accelrig.errors import DeviceError
from accelrig.geometry import FACES, axis_vector
from accelrig.sim import kinematics
from accelrig.sim.rigs.base import Rig
from accelrig.units import STANDARD_GRAVITY


class StillRig(Rig):
    name = "still"
    description = "sensor at rest on a level table (noise figures, smoke tests)"
    options = {
        "up": "sensor axis pointing up: +x, -x, +y, -y, +z (default) or -z",
        "seconds": "length of the run in s (default: endless)",
    }

    def __init__(self, up: str = "+z", duration: float | None = None, g: float = STANDARD_GRAVITY):
        if up not in FACES:
            raise DeviceError(f"up={up!r} is not an axis", "use one of +x, -x, +y, -y, +z, -z")
        self.up = up
        self.g = g
        self.duration = duration
        up_vector = axis_vector(up)
        # any level heading will do: the next axis round points along world x
        self._mounting = kinematics.level_mounting(np.roll(up_vector, 1), up_vector)
        # Nothing here depends on time, so the kinematics are evaluated once (at t = 0) and the
        # result repeated: a device streaming 2048 Hz for weeks should not differentiate a
        # constant position five times per sample (this was most of an emulated chip's CPU).
        self._force = kinematics.specific_force(kinematics.at_origin, self.orientation, np.zeros(1), self.g)[0]

    @classmethod
    def from_url(cls, url: DeviceURL, rng: np.random.Generator) -> StillRig:
        return cls(up=url.get_str("up", "+z").replace(" ", "+"), duration=url.get_float("seconds", low=0.0, low_open=True,
                                                                                        high=86400.0, unit="s"))

    def orientation(self, t: np.ndarray) -> np.ndarray:
        return np.broadcast_to(self._mounting, (np.size(t), 3, 3))

    def specific_force(self, t: np.ndarray) -> np.ndarray:
        return np.tile(self._force, (np.size(t), 1))

    def truth(self) -> dict:
        return {"rig": self.name, "up": self.up, "g": self.g,
                "specific_force": self.specific_force(np.zeros(1))[0].tolist()}
