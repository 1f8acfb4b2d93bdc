"""Slider-crank dynamic verification (paper 000): ``settings`` (light), ``analysis`` (per step and over
steps), ``procedure`` (the operator flow on the Procedure contract, and the batch form for files)."""
