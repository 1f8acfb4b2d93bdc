"""Estimation core: least squares with covariance, sine fits, Cramér-Rao bounds."""
