"""What a planned wheel run would reach (CRB, k = 1), before spinning: ``accelrig plan wheel``."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from accelrig.errors import CalibrationError, DataError
from accelrig.procedures.wheel.checks import MIN_TURNS
from accelrig.procedures.wheel.fit import ROTATION_NAMES, reported_names, reported_values, wheel_crb
from accelrig.procedures.wheel.model import (
    TABLE_I_OMEGA,
    TABLE_I_THETA0_DEG,
    FreeSet,
    WheelState,
    phase,
    rotation_from_euler,
)
from accelrig.procedures.wheel.procedure import GRAVITY_SCALED
from accelrig.units import LocalGravity, local_gravity


@dataclass
class PlanRow:
    name: str
    value: float
    sd: float      # what the calibration would state: the CRB with u(g) where the parameter scales with g
    unit: str
    crb: float     # the Cramer-Rao bound alone (the noise's share)


def plan_state(radius: float, tilt_deg: float, speed: float, seconds: float,
               mount_deg=(30.0, 20.0, 25.0)) -> WheelState:
    """The nominal wheel for a plan: a perfect sensor (gains 1, offsets 0) mounted at
    ``mount_deg``, coasting down along the paper's Table I profile scaled to ``speed``
    and stretched over ``seconds``."""
    stretch = 90.0 / seconds
    omega = TABLE_I_OMEGA * (speed / TABLE_I_OMEGA[0]) * stretch ** np.arange(4)
    return WheelState(np.deg2rad(TABLE_I_THETA0_DEG), omega, np.deg2rad(tilt_deg), radius,
                      rotation_from_euler(np.deg2rad(mount_deg)), np.ones(3), np.zeros(3))


def plan_wheel(radius: float, tilt_deg: float, noise: float, rate: float, seconds: float, speed: float,
               mount_deg=(30.0, 20.0, 25.0), gravity: LocalGravity | None = None) -> list[PlanRow]:
    """The uncertainty each parameter would reach (k = 1) on a planned run, radius given: the CRB, and for
    the gains the local gravity's u(g) as the calibration adds it (``gravity``: the same settings as the
    calibration's, default standard gravity with its u for anywhere on Earth)."""
    gravity = local_gravity() if gravity is None else gravity
    for label, value in (("radius", radius), ("noise", noise), ("rate", rate), ("seconds", seconds), ("speed", speed)):
        if not value > 0:
            raise DataError(f"--{label} {value} must be positive")
    if not 0 < tilt_deg < 90:
        raise DataError(f"--tilt-deg {tilt_deg} must lie strictly between 0 and 90")
    state = plan_state(radius, tilt_deg, speed, seconds, mount_deg)
    turns = abs(phase(np.array([seconds]), 0.0, state.omega)[0][0]) / (2 * np.pi)
    if turns < MIN_TURNS:
        raise CalibrationError(
            f"the planned run makes {turns:.1f} turns, the calibration needs at least {MIN_TURNS:.0f}",
            "plan a faster spin (--speed) or a longer run (--seconds)",
        )
    t = np.arange(int(round(seconds * rate))) / rate
    free = FreeSet(radius_free=False, tilt_free=True)
    cov = wheel_crb(t, state, free, noise, gravity.value)
    sd = np.sqrt(np.diag(cov))
    values = reported_values(state, free)
    rows = []
    deg = {"theta0", "tilt", *ROTATION_NAMES}
    units = {"theta0": "deg", "omega0": "rad/s", "omega1": "rad/s^2", "omega2": "rad/s^3", "omega3": "rad/s^4",
             "tilt": "deg", "gain_x": "1", "gain_y": "1", "gain_z": "1"}
    for name, value, s in zip(reported_names(free), values, sd, strict=True):
        factor = np.rad2deg(1.0) if name in deg else 1.0
        # u(g) as the calibration adds it (CalibrationResult.with_local_gravity, the same GRAVITY_SCALED rule);
        # the radius, given in a plan, is not estimated
        power = GRAVITY_SCALED.get(name.rsplit("_", 1)[0] if name.startswith("gain_") else name, 0)
        u = float(np.hypot(s, abs(value * power) * gravity.u / gravity.value))
        rows.append(PlanRow(name + ("_deg" if name in deg else ""), value * factor, u * factor,
                            units.get(name, "deg" if name in deg else "m/s^2"), s * factor))
    return rows
