"""Rotary oscillating bench (paper 001): ``settings`` (light), ``bench`` (one test), ``campaign`` (many tests,
one report), ``procedure`` (the operator flow on the Procedure contract)."""
