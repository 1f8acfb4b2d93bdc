"""Tilted-wheel dynamic calibration (paper 002, Pedersini), at the Cramer-Rao bound: ``settings`` (light),
``model`` (eq. 1-7 and their Jacobian), ``checks`` (the survey and capture checks), ``paper`` (the paper's
four steps), ``fit`` (the joint maximum-likelihood fit and its CRB), ``plan`` (the CRB of a planned run),
``procedure`` (the operator flow on the Procedure contract, and ``calibrate_wheel`` for files)."""
