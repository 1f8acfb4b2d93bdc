"""The slider-crank verification's settings, declared once for the CLI flags and the TUI form (ground floor only)."""

from __future__ import annotations

from accelrig.settings import REQUIRED, Setting

DEFAULT_HARMONICS = 4  # the exact law has harmonics 1, 2, 4, 6, ...; the 4th is ~lambda^3/4 of the 1st

# A bench slider-crank: a crank of at most half a metre, a rod of at most two.
CRANK_RADIUS = Setting("crank_radius", "caliper crank radius", unit="m", default=REQUIRED, low=0.0, low_open=True,
                       high=0.5, example="0.00635", hint="give it in metres, e.g. 0.00635")
ROD_LENGTH = Setting("rod_length", "connecting rod length", unit="m", default=REQUIRED, low=0.0, low_open=True,
                     high=2.0, example="0.0353", hint="give it in metres, e.g. 0.0353")
CLEARANCE = Setting("clearance", "mechanical clearance +- on the radius", unit="m", default=0.0, low=0.0, high=0.1,
                    example="0.0001")
SPEEDS = Setting("speeds", "commanded motor speed of each step, judges the roll-off (blank: you set each speed)",
                 unit="Hz", kind="floats", low=0.0, low_open=True, example="2.5,4,6,8",
                 hint="e.g. --speeds 2.5,4,6,8")
HARMONICS = Setting("harmonics", "harmonics sharing the frequency in the fit", kind="int", default=DEFAULT_HARMONICS,
                    low=1, high=20)
PROFILE = Setting("profile", "device profile whose calibration is applied first (the one verified; blank: raw data)",
                  kind="path", example="sensor.yaml")
# The one compatibility override of accelrig.profiles.apply.check_compatible (CLI flag and TUI field alike).
FORCE = Setting("force", "apply the profile even if it names another device, chip, range or unit (warned)",
                kind="flag", default=False, remembered=False)
# Seconds of steady running captured per key press: the analysis needs at least 1 s; twice that halves the
# variance of the first harmonic and is still quick at the bench.
SECONDS = Setting("seconds", "seconds captured per step on a key press, for a stand that marks no steps", unit="s",
                  default=2.0, low=0.5, high=600.0)

# What a recorded file needs (the CLI's flags) and what a live stand adds.
FILE_SETTINGS = (CRANK_RADIUS, ROD_LENGTH, CLEARANCE, SPEEDS, HARMONICS, PROFILE, FORCE)
SETTINGS = (CRANK_RADIUS, ROD_LENGTH, CLEARANCE, SPEEDS, SECONDS, HARMONICS, PROFILE, FORCE)
