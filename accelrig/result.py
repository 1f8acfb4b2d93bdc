"""The shared vocabulary (ground floor): estimates, the canonical correction, a procedure's result.

Everything above imports these from here; this module imports only numpy.
``to_plain`` and ``to_json`` are the one way any of them (or a report dict)
becomes JSON or YAML.
"""

from __future__ import annotations

import json
import math
import numbers
from dataclasses import dataclass, field

import numpy as np


def significant(u: float, digits: int = 2) -> int:
    """Decimals that show ``u`` to ``digits`` significant digits (the value is shown to the same place)."""
    if not math.isfinite(u) or u <= 0:
        return 6
    decimals = max(0, digits - 1 - math.floor(math.log10(u)))
    # a u that rounds up into the next decade (0.0999996 -> 0.100) keeps two digits there (0.10)
    if decimals > 0 and round(u, decimals) >= 10.0 ** (digits - decimals):
        decimals -= 1
    return decimals


# Numbers this small or this large are written with a power of ten, the value and its u sharing the
# exponent: "1.3156e-6  0.0041e-6 rad/s⁴" reads where "0.0000013156  0.0000000041" hides the digits in zeros.
# From 1e-3 down (not 1e-4): the wheel's omega2 (about 3e-4 rad/s³) read "0.000333313  0.000000055".
SCIENTIFIC_BELOW = 1e-3
SCIENTIFIC_FROM = 1e6


def format_value(value: float, u: float) -> tuple[str, str]:
    """The value and its uncertainty, rounded together (GUM 7.2.6: u to two significant digits, the value to
    the same place); below SCIENTIFIC_BELOW or from SCIENTIFIC_FROM both as mantissa e exponent, one exponent
    (the larger of the two's), so they still line up digit for digit.  Every face (TUI, CLI text,
    certificate, the procedures' own sentences) formats an estimate here."""
    if not (isinstance(value, numbers.Real) and isinstance(u, numbers.Real)):
        return str(value), str(u)
    value, u = float(value), float(u)   # numpy's float32 too, rounded like any other
    if not math.isfinite(u) or u <= 0:
        return f"{value:.6g}", ("0" if u == 0 else str(u))
    size = max(abs(value), u)
    if not math.isfinite(size) or SCIENTIFIC_BELOW <= size < SCIENTIFIC_FROM:
        d = significant(u)
        return f"{value:.{d}f}", f"{u:.{d}f}"
    exponent = math.floor(math.log10(size))
    d = significant(u / 10.0 ** exponent)
    if round(size / 10.0 ** exponent, d) >= 10.0:   # 9.99996e-5 rounds to 10.000e-5: one place up
        exponent += 1
        d = significant(u / 10.0 ** exponent)
    scale = 10.0 ** exponent
    return f"{value / scale:.{d}f}e{exponent:+d}", f"{u / scale:.{d}f}e{exponent:+d}"


@dataclass
class Estimate:
    """A value with its standard uncertainty (k = 1).  Scalars or equal-length vectors."""

    value: float | list[float]
    uncertainty: float | list[float]
    unit: str

    def to_dict(self) -> dict:
        return {"value": to_plain(self.value), "uncertainty": to_plain(self.uncertainty), "unit": self.unit}

    def for_display(self) -> tuple[float | list[float], float | list[float], str]:
        """(value, uncertainty, unit) as a person reads them: angles in degrees (estimated in radians)."""
        if self.unit == "rad":
            return (to_plain(np.degrees(self.value)), to_plain(np.degrees(self.uncertainty)), "deg")
        return self.value, self.uncertainty, self.unit


@dataclass
class Correction:
    """The canonical correction every method produces: calibrated = C @ (raw - b).

    raw and calibrated in m/s^2 (raw = counts x nominal scale).  ``covariance``
    is the 12 x 12 covariance of ``[C.ravel() (row-major), b]``.
    """

    matrix: np.ndarray
    bias: np.ndarray
    covariance: np.ndarray

    def __post_init__(self) -> None:
        self.matrix = np.asarray(self.matrix, dtype=float).reshape(3, 3)
        self.bias = np.asarray(self.bias, dtype=float).reshape(3)
        self.covariance = np.asarray(self.covariance, dtype=float).reshape(12, 12)

    @classmethod
    def identity(cls) -> Correction:
        return cls(np.eye(3), np.zeros(3), np.zeros((12, 12)))

    def with_gravity_uncertainty(self, g: float, u_g: float) -> Correction:
        """This correction with u(g) of the local gravity it was scaled to added to its covariance.

        Every gravity-referenced calibration makes calibrated vectors read g: C is proportional to the g
        used and b does not depend on it, so an error dg moves C by C dg / g (fully correlated entries)."""
        if not u_g:
            return self
        d = np.concatenate([self.matrix.ravel(), np.zeros(3)]) * (u_g / g)
        return Correction(self.matrix, self.bias, self.covariance + np.outer(d, d))

    def scale_uncertainty(self, direction) -> float:
        """Relative u of the scale this correction gives a signal along ``direction`` (calibrated frame).

        A reading a n (a along the unit vector n) calibrates to a n; an error dC moves it by
        dC C^-1 a n, whose part along n is a (n . dC C^-1 n): relative u from the covariance of C's entries,
        whose gradient is outer(n, C^-1 n).  b does not enter: it moves a signal's mean, not its size."""
        n = np.asarray(direction, dtype=float).reshape(3)
        n = n / np.linalg.norm(n)
        gradient = np.outer(n, np.linalg.solve(self.matrix, n)).ravel()
        return float(np.sqrt(max(gradient @ self.covariance[:9, :9] @ gradient, 0.0)))

    @property
    def matrix_uncertainty(self) -> np.ndarray:
        return np.sqrt(np.clip(np.diag(self.covariance)[:9], 0, None)).reshape(3, 3)

    @property
    def bias_uncertainty(self) -> np.ndarray:
        return np.sqrt(np.clip(np.diag(self.covariance)[9:], 0, None))

    def apply(self, raw: np.ndarray) -> np.ndarray:
        """Calibrate samples (n, 3) in m/s^2."""
        return (np.asarray(raw, dtype=float) - self.bias) @ self.matrix.T

    def sample_covariances(self, raw: np.ndarray) -> np.ndarray:
        """(n, 3, 3) covariance of each calibrated sample due to the correction's uncertainty.

        y = C (x - b); dy/dC_ij = (x - b)_j e_i, dy/db = -C, i.e. the Jacobian
        [kron(I, (x - b)^T), -C] sandwiching the covariance, in closed form so
        a stream of millions of samples costs a few array operations.
        """
        d = np.asarray(raw, dtype=float).reshape(-1, 3) - self.bias
        cov = self.covariance
        s_cc = cov[:9, :9].reshape(3, 3, 3, 3)   # [i, j, k, l] = cov(C_ij, C_kl)
        s_cb = cov[:9, 9:].reshape(3, 3, 3)      # [i, j, m] = cov(C_ij, b_m)
        s_bb = cov[9:, 9:]
        c = self.matrix
        term_cc = np.einsum("nj,ijkl,nl->nik", d, s_cc, d, optimize=True)
        a = np.einsum("nj,ijm->nim", d, s_cb, optimize=True) @ c.T   # cov(dC d, C b) part
        return term_cc - a - np.swapaxes(a, 1, 2) + c @ s_bb @ c.T

    def to_dict(self) -> dict:
        return {
            "matrix": self.matrix.tolist(),
            "bias": self.bias.tolist(),
            "matrix_uncertainty": self.matrix_uncertainty.tolist(),
            "bias_uncertainty": self.bias_uncertainty.tolist(),
            "covariance": self.covariance.tolist(),
        }


@dataclass
class CalibrationResult:
    """A procedure's outcome.

    parameters  name -> Estimate (e.g. gain_x, offset_y, tilt_deg), in a stable order.
    covariance  covariance of the free parameters in ``parameter_names`` order (SI units).
    quality     residual_rms (m/s^2), n_samples, sd_over_crb where known, ...
    arrays      what a person wants to plot (residuals, fitted curves), as arrays.
    settings    the method's settings and rig geometry used (for the profile's provenance).
    warnings    things the operator should know that did not stop the calibration.
    details     procedure-specific tables as plain data (per-step rows, an uncertainty budget, a verdict),
                for reports and JSON.
    parameter_meaning  what the parameters are, in one sentence: the procedures estimate in different
                forms (a static fit's gain and offset correct the reading; the wheel's are the sensor's own,
                the reading's side), so every display names its form next to the canonical correction.
    """

    procedure: str
    method: str
    model: str
    correction: Correction | None
    parameters: dict[str, Estimate]
    covariance: np.ndarray | None = None
    parameter_names: list[str] = field(default_factory=list)
    quality: dict = field(default_factory=dict)
    arrays: dict[str, np.ndarray] = field(default_factory=dict)
    settings: dict = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)
    details: dict = field(default_factory=dict)
    parameter_meaning: str = ""

    def with_local_gravity(self, gravity, scaled: dict[str, int] | None = None) -> CalibrationResult:
        """Record the local gravity used (``accelrig.units.LocalGravity``: g, u(g), where it came from) and put
        u(g) into the correction's covariance (``Correction.with_gravity_uncertainty``), in place.

        ``scaled``: the parameters that scale with g, and the power they scale by (the wheel's gains +1:
        gravity is their reference; its radius -1: the centripetal term is read in the gains' scale; static's
        gains, C_ij and calibrated-domain offsets +1, K_ij -1); u(g) enters their u and the parameter
        covariance, fully correlated."""
        if self.correction is not None:
            self.correction = self.correction.with_gravity_uncertainty(gravity.value, gravity.u)
        if gravity.u and scaled:
            self._scale_with_gravity(gravity.u / gravity.value, scaled)
        self.settings.update(gravity.to_dict())
        if gravity.warning and gravity.warning not in self.warnings:
            self.warnings.append(gravity.warning)
        if gravity.u:
            note = f"local gravity u(g) {gravity.u:.2g} m/s^2 ({gravity.u / gravity.value:.1e} of the gains)"
            # appended to what the procedure says u holds, under the key it uses (the wheel's is "uncertainty")
            key = "uncertainty" if "uncertainty" in self.quality else "uncertainty_source"
            source = self.quality.get(key)
            self.quality[key] = f"{source}; + {note}" if source else f"+ {note}"
        return self

    def _scale_with_gravity(self, relative: float, scaled: dict[str, int]) -> None:
        """Add u(g)/g x |value| to the u of each ``scaled`` parameter (scalar or per axis), and the fully
        correlated term to the covariance rows named ``NAME`` or ``NAME_x/y/z``."""
        d = np.zeros(len(self.parameter_names))
        for base, power in scaled.items():
            est = self.parameters.get(base)
            if est is None:
                continue
            values = np.ravel(np.asarray(est.value, dtype=float))
            rows = {base: values[0]} if values.size == 1 else dict(zip((f"{base}_{a}" for a in "xyz"), values, strict=True))
            for j, name in enumerate(self.parameter_names):
                if name in rows:
                    d[j] = rows[name] * power * relative
            u = np.hypot(np.asarray(est.uncertainty, dtype=float), np.abs(np.asarray(est.value, dtype=float)) * relative)
            self.parameters[base] = Estimate(est.value, to_plain(u), est.unit)
        if self.covariance is not None and np.size(self.covariance) and d.any():
            self.covariance = np.asarray(self.covariance, dtype=float) + np.outer(d, d)

    def to_json_dict(self, include_arrays: bool = False) -> dict:
        out = {
            "procedure": self.procedure,
            "method": self.method,
            "model": self.model,
            "correction": self.correction.to_dict() if self.correction is not None else None,
            "parameters": {k: v.to_dict() for k, v in self.parameters.items()},
            "parameter_meaning": self.parameter_meaning,
            "residual_rms": to_plain(self.quality.get("residual_rms")),
            "quality": {k: to_plain(v) for k, v in self.quality.items()},
            "settings": {k: to_plain(v) for k, v in self.settings.items()},
            "warnings": list(self.warnings),
        }
        if self.details:
            out["details"] = to_plain(self.details)
        if include_arrays:
            out["arrays"] = {k: to_plain(v) for k, v in self.arrays.items()}
        return out


def to_plain(value):
    """Turn numpy values (and containers of them) into JSON/YAML-friendly Python values."""
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, dict):
        return {k: to_plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [to_plain(v) for v in value]
    return value


def to_json(value, indent: int | None = 2, sort_keys: bool = False) -> str:
    """The JSON every ``--json`` output and metadata line uses: numpy made plain.

    NaN and infinities are written as JSON's NaN/Infinity (Python's json reads them back) rather than
    refused, because a quality figure may honestly be undefined.
    """
    return json.dumps(to_plain(value), indent=indent, sort_keys=sort_keys)
