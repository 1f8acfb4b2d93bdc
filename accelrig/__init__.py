"""accelrig: calibrate 3-axis MEMS accelerometers with cheap rigs."""

__version__ = "0.1.0"
