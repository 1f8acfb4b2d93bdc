"""What a person sets for a static calibration, declared once for the CLI flags and the TUI form."""

from __future__ import annotations

from accelrig.settings import GRAVITY, Setting

MODELS = ("paper", "affine")
METHODS = ("vp", "paper")

SETTINGS = (
    Setting("model", "model fitted: paper = G R raw + c (9 parameters), affine = full matrix + offset (12), "
            "auto = the one with the lower AIC", kind="choice", choices=(*MODELS, "auto"), default="auto",
            label="model"),
    Setting("method", "vp = variable projection + Levenberg-Marquardt; paper = the paper's Nelder-Mead over "
            "the angles (9-parameter model only)", kind="choice", choices=METHODS, default="vp", label="method"),
    GRAVITY,
    Setting("min_hold", "shortest usable pose", unit="s", default=2.0, low=0.0, low_open=True, high=600.0,
            label="shortest pose"),
    Setting("still_threshold", "dispersion below which the sensor counts as still", unit="m/s^2", default=0.25,
            low=0.0, low_open=True, high=10.0, label="still threshold"),
)
