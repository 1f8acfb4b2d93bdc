"""Least squares with covariance, Cramér-Rao bounds, uncertainty propagation.

Shared by every procedure: ``sinefit`` (IEEE 1057 sine fits with harmonics), ``varpro`` (separable least squares by variable
projection, Kaufman Jacobian, LM), ``crb_covariance`` / ``crb_sd`` (bounds
and fit covariances), ``propagate_covariance`` (GUM law J U J^T).
"""

from accelrig.estimation.crb import (
    crb_covariance,
    crb_sd,
    numerical_jacobian,
    propagate_covariance,
    unidentifiable_direction,
)
from accelrig.estimation.varpro import VarProResult, separable_jacobian, solve_linear, varpro

__all__ = [
    "VarProResult",
    "crb_covariance",
    "crb_sd",
    "numerical_jacobian",
    "propagate_covariance",
    "separable_jacobian",
    "solve_linear",
    "unidentifiable_direction",
    "varpro",
]
