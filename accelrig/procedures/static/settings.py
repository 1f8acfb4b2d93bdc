"""What a person sets for a static calibration, declared once for the CLI flags and the TUI form."""

from __future__ import annotations

from accelrig.settings import GRAVITY_SETTINGS, Setting

MODELS = ("paper", "affine")                           # the exact-face models of accelrig.procedures.static.fit
MODEL_CHOICES = ("auto", "six-face", "multi-position", *MODELS)
METHODS = ("vp", "paper")
# = accelrig.estimation.gravity_fit.DEFAULT_POSE_FLATNESS_DEG (a test holds them equal; this module stays light)
POSE_FLATNESS_DEG = 1.0

SETTINGS = (
    Setting("model", "six-face = the paper's 9 parameters with each pose's tilt from its face a nuisance "
            "(flatness prior); multi-position = |C (raw - b)| = g from >= 9 orientations (imu_tk); "
            "paper / affine = exact faces (9 / 12 parameters, no tilt); auto = six-face when every pose is "
            "near a face, multi-position when not", kind="choice", choices=MODEL_CHOICES, default="auto",
            label="model (multi-position: hold it still in any orientation)"),
    Setting("method", "for the exact-face models (paper, affine): vp = variable projection + "
            "Levenberg-Marquardt; paper = the paper's Nelder-Mead over the angles (paper model only).  six-face "
            "and multi-position have one fit each, named in the result: map (tilts with their flatness prior) "
            "and lm", kind="choice", choices=METHODS, default="vp", label="method (paper/affine models only)"),
    *GRAVITY_SETTINGS,
    Setting("pose_flatness_deg", "sd of each pose's tilt from its face (six-face Type B term); a pose more "
            "than 5 x this from a face is refused in six-face mode", unit="deg", default=POSE_FLATNESS_DEG,
            low=0.0, low_open=True, high=10.0, label="pose flatness"),
    Setting("min_hold", "shortest usable pose", unit="s", default=2.0, low=0.0, low_open=True, high=600.0,
            label="shortest pose"),
    Setting("still_threshold", "dispersion below which the sensor counts as still", unit="m/s^2", default=0.25,
            low=0.0, low_open=True, high=10.0, label="still threshold"),
)
