"""Estimation: least squares with covariance, sine fits, CRB, GUM budgets and statistics."""
