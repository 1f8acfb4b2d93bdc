"""The Textual user interface (``accelrig tui``).

The only part of accelrig that imports textual: screens and widgets here show
what the acquisition Session and the procedure objects report and hold no
calibration logic of their own.
"""
