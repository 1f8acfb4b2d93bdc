"""The tilted wheel's settings, declared once for the CLI flags and the TUI form (ground floor only)."""

from __future__ import annotations

import math
from dataclasses import replace

from accelrig.settings import GRAVITY, GRAVITY_SETTINGS, REQUIRED, Setting

METHODS = ("joint", "paper")
DEFAULT_BOOTSTRAP = 20
# The wheel cannot observe the sensor's own cross-axis sensitivity: a skew of its axes is absorbed
# by the mounting rotation R (eq. 1-7 carry only diag(gain) R).  The correction keeps C off-diagonal
# at 0 but with this prior sd: the MPU-9250 and ICM-20948 datasheets bound cross-axis sensitivity by
# +-2 %, read as a uniform distribution (sd = 0.02 / sqrt(3)).
DEFAULT_CROSS_AXIS_SD = 0.02 / math.sqrt(3)

# The null space of the paper's section II-C: of the radius and the tilt, one must be known.
NEEDS_RADIUS_OR_TILT = "give the radius, the tilt, or both: the one left blank is estimated (one is needed)"
RADIUS = Setting("radius", "distance from the sensor to the wheel axis (give it, the tilt, or both: the one not "
                 "given is estimated)", unit="m", low=0.0, low_open=True, high=2.0, label="radius", example="0.28",
                 hint="give it in metres, e.g. 0.28")
TILT_DEG = Setting("tilt_deg", "tilt of the wheel axis from the vertical (give it, the radius, or both: the one not "
                   "given is estimated)", unit="deg", low=0.0, low_open=True, high=90.0, label="tilt", example="45")
METHOD = Setting("method", "joint maximum likelihood or the paper's four steps", kind="choice", choices=METHODS,
                 default="joint")
# Each run is one fit (about 0.1 s): 1000 runs pin a standard uncertainty to 2 %; more only waits.
BOOTSTRAP = Setting("bootstrap", "runs of the parametric bootstrap giving the paper method's uncertainties",
                    kind="int", default=DEFAULT_BOOTSTRAP, low=5, high=1000)
CROSS_AXIS_SD = Setting("cross_axis_sd", "prior sd of the correction's off-diagonal (cross-axis) terms, which the "
                        "wheel does not observe; the default reads the datasheet +-2 percent as a uniform bound",
                        default=DEFAULT_CROSS_AXIS_SD, low=0.0, low_open=True)
# Local gravity, declared once for every procedure (default standard gravity, 9.7 .. 9.9 m/s^2).
G = GRAVITY

SETTINGS = (RADIUS, TILT_DEG, METHOD, BOOTSTRAP, CROSS_AXIS_SD, *GRAVITY_SETTINGS)   # g, latitude, height, g_u

# A planned run (accelrig plan wheel): the radius given, the tilt estimated, a perfect sensor.
PLAN_SETTINGS = (
    replace(RADIUS, help="distance from the sensor to the wheel axis", default=REQUIRED),
    replace(TILT_DEG, help="tilt of the wheel axis from the vertical", default=45.0),
    Setting("noise", "sensor noise sd per sample", unit="m/s^2", default=0.08, low=0.0, low_open=True),
    Setting("rate", "sample rate", unit="Hz", default=200.0, low=0.0, low_open=True),
    Setting("seconds", "length of the run", unit="s", default=90.0, low=0.0, low_open=True),
    Setting("speed", "initial angular velocity", unit="rad/s", default=9.0, low=0.0, low_open=True),
    Setting("mount_deg", "mounting Euler angles theta,phi,psi (tilted, as the paper advises)", unit="deg",
            kind="floats", default=(30.0, 20.0, 25.0)),
    *GRAVITY_SETTINGS,   # the calibration's u(g) is in the gains' planned u
)
