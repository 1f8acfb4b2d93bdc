"""A timing-truth rig for the chip emulators: x ramps linearly, so every sample says when it was taken.

Not a calibration rig (not in RIGS): tests and benchmarks of the I2C driver's
sample timing decode the true sample time from the x reading,
t = (x - start) / slope (modulo ``period``), and compare it with the time the
driver assigned.  Use it with an ideal sensor at +-16 g.
"""

from __future__ import annotations

import numpy as np

from accelrig.sim.rigs.base import Rig
from accelrig.units import STANDARD_GRAVITY


class RampRig(Rig):
    name = "ramp"
    description = "x ramps linearly (a sawtooth of the given period): sample timing truth"

    def __init__(self, start: float = -125.0, slope: float = 25.0, period: float | None = None):
        self.start = start
        self.slope = slope
        self.period = period

    @classmethod
    def from_url(cls, url, rng):
        return cls()

    def specific_force(self, t):
        t = np.asarray(t, dtype=float)
        phase = t if self.period is None else np.mod(t, self.period)
        return np.stack([self.start + self.slope * phase, np.zeros_like(t), np.full_like(t, STANDARD_GRAVITY)], axis=1)

    def decode(self, x: np.ndarray, t_estimate: np.ndarray) -> np.ndarray:
        """True sample times from x readings (m/s^2), unwrapped with the driver's own estimate."""
        phase = (np.asarray(x, dtype=float) - self.start) / self.slope
        if self.period is None:
            return phase
        return phase + self.period * np.round((np.asarray(t_estimate) - phase) / self.period)

    def truth(self):
        return {"rig": self.name, "start": self.start, "slope": self.slope, "period": self.period}
