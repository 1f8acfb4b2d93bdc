"""The rotary bench's settings, declared once for the CLI flags and the TUI form (ground floor only)."""

from __future__ import annotations

from accelrig.settings import REQUIRED, Setting

RATE_METHODS = ("fit", "scan")
# The paper's test plan (section 2.4) plus lower amplitudes for the linearity line:
# (frequency Hz, oscillation angle in degrees PEAK TO PEAK)
PAPER_PLAN = ((5.0, 34.0), (5.0, 20.0), (8.0, 13.0), (8.0, 6.0))

TANGENTIAL = Setting("tangential", "sensor axis along the motion: x, y or z", default=REQUIRED, kind="text", example="x")
RADIAL = Setting("radial", "sensor axis towards the rotation axis: x, y or z (the third sees gravity)", default=REQUIRED,
                 kind="text", example="y")
RADIUS = Setting("radius", "sensor distance from the rotation axis", unit="m", default=REQUIRED, low=0.0,
                 low_open=True, high=2.0, example="0.170", hint="give it in metres, e.g. 0.170")
RADIUS_UNCERTAINTY = Setting("radius_uncertainty", "standard uncertainty of the radius (paper 001)", unit="m",
                             default=0.0005, low=0.0)
REF_RADIUS = Setting("ref_radius", "radius of the reference accelerometer", unit="m", default=0.145, low=0.0)
NOMINAL_RATE = Setting("nominal_rate", "nominal MEMS rate (a live device: its own)", unit="Hz", low=0.0,
                       low_open=True, example="1660")
FREQUENCY = Setting("frequency", "excitation frequency (blank: from the encoder)", unit="Hz", low=0.0, low_open=True)
RATE_METHOD = Setting("rate_method", "true sampling rate by a sample-index sine fit or the paper's 1 Hz FFT scan",
                      kind="choice", choices=RATE_METHODS, default="fit")
PLAN = Setting("plan", "steps FREQUENCY:DEGREES, the frequency in Hz and the angle in degrees peak to peak "
               "(blank: the paper's " + ",".join(f"{f:g}:{a:g}" for f, a in PAPER_PLAN) + ")", kind="text",
               example="5:34,8:13", label="steps FREQUENCY:DEGREES, in Hz:degrees peak to peak")
REPEATS = Setting("repeats", "repeats of each step", kind="int", default=6, low=1, high=100)
SECONDS = Setting("seconds", "seconds recorded per step", unit="s", default=40.0, low=1.0, high=3600.0)

# One test from files (the CLI's flags) and a live session at the bench.
TEST_SETTINGS = (RADIUS, RADIUS_UNCERTAINTY, REF_RADIUS, TANGENTIAL, RADIAL, NOMINAL_RATE, FREQUENCY, RATE_METHOD)
SETTINGS = (RADIUS, TANGENTIAL, RADIAL, RADIUS_UNCERTAINTY, REF_RADIUS, RATE_METHOD, PLAN, REPEATS, SECONDS)
