"""Procedures: one per rig.  Each knows its operator steps, its capture checks and its estimator."""
