"""Six-face static calibration (paper 000), in four modules light to heavy.

settings   the declared settings (model, method, g, min_hold, still_threshold):
           imports no numerical code, so ``accelrig calibrate static --help``
           and the TUI's form stay cheap
poses      still-pose detection on the raw stream: hysteresis, face, capture checks
fit        the estimators (variable projection, the paper's Nelder-Mead, affine) and the CRB
procedure  StaticProcedure, the Procedure contract over poses + fit, and the
           batch form for files, calibrate_static()

This package imports none of them: import the one you need.
"""
