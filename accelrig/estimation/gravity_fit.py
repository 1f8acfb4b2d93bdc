"""Static calibration from still poses: gravity-magnitude (multi-position) and tilt-robust six-face fits.

Input is pose statistics, not recordings, so these estimators are
independent of how the still poses were found: per pose the mean raw vector
(m/s^2), the covariance of one sample (or its sd), the number of samples and,
for six-face mode, the nominal face down.  Output is the canonical correction
``calibrated = C (raw - b)`` with its 12 x 12 covariance.  docs/static-tilt-notes.md
gives the reasoning; the short form:

multi-position (Tedaldi, Pretto, Menegatti, ICRA 2014; imu_tk)
    minimise sum_p (|C (m_p - b)| - g)^2 / s_p^2 over an upper-triangular C
    (6) and b (3).  |C x| is unchanged by C -> Q C for any rotation Q, so 3 of
    the 12 entries are a gauge; C = Q R (QR, positive diagonal) is unique, and
    the upper-triangular gauge (imu_tk's) puts the calibrated x axis on the
    sensor's x axis and y in the sensor's xy plane.  s_p^2 = u^T C V_p C^T u is
    the variance of the pose's magnitude from the mean's covariance V_p.
    Gauss-Newton / LM with the analytic Jacobian, started from an algebraic
    ellipsoid fit; covariance (J^T W J)^-1, chi^2 against P - 9 dof.
six-face, tilt-robust (MAP, flatness prior)
    the true down direction of pose p is its face direction tilted by an
    unknown small angle (2 nuisance parameters per pose) with a Gaussian prior
    of sd ``pose_flatness_deg``; the prior enters as pseudo-observations and
    the fit is the exact nonlinear MAP (model and tilts jointly).  The
    covariance of the model parameters is the block of the inverse
    information, i.e. the tilts are marginalised (to first order at the MAP
    point) and the flatness is the Type B term.  With flatness 0 it is the
    paper's exact-face model.
Ferraris pairing (as imucal)
    C = 2 g (U_- - U_+)^-1 from opposite faces, b_k = mean of axis k on its two faces.

Uncertainty: when chi^2 rejects the model (p < ``CHI2_ALPHA``) the observed
scatter inflates it, one of two ways (``inflation``), and the fit says which
(``uncertainty_source``):
  "repeatability" (default)  an additive per-pose error of sd sigma_r (isotropic,
      independent between poses: drift, hand pressure, re-seating) is added to
      every pose mean's covariance and solved so that chi^2 = dof (Paule-Mandel); that variance is
      estimated from the few dof of the poses, so it is widened by the Student factor of those dof (as
      the observed flatness is), keeping +-2u a 95 % interval; the fit is redone with those weights.
  "birge"  the covariance is multiplied by the Birge ratio squared chi^2/dof.
``wander_var`` (both fits): an additive per-pose variance known before the fit (the still-noise check's
slow-noise wander between poses, accelrig.procedures.static.noise); the repeatability solved from the
scatter replaces it when the scatter asks for more (a floor, like the stated flatness).
``between`` (both fits): the covariance between different poses' means (noise slower than a hold, which
neighbouring holds share; the static procedure's model of it, ``noise.SlowNoise``): the weights stay each
pose's own, and the shared part is added to the covariance through a sandwich (``_between_poses``).
On real hand-held sessions the excess sits in a few poses (a sensor drifting
between repeats of one face), which the uniform Birge factor spreads thin; the
additive term puts it where it is (docs/static-tilt-notes.md).
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares

from accelrig.errors import CalibrationError
from accelrig.estimation.crb import propagate_covariance, unidentifiable_direction
from accelrig.estimation.distributions import chi2 as chi2_dist
from accelrig.geometry import AXES, FACES, face_down_direction, rotation_xyz, rotation_xyz_derivatives
from accelrig.result import Correction
from accelrig.units import STANDARD_GRAVITY

# A hand pressing a housing on an ordinary bench: bench not levelled (0.5 deg is common for tables and
# floors), housing face and sensor mounting in it (0.5 deg), rocking of the hand (0.2 deg): root sum of
# squares about 0.7 deg, rounded up.  Per tilt component (two per pose), standard uncertainty.
DEFAULT_POSE_FLATNESS_DEG = 1.0
# A pose further from its face than this many flatness sd is not a face pose (probability e^-12.5 under the prior).
FACE_REFUSE_SD = 5.0
CHI2_ALPHA = 0.01            # chi^2 p-value below which the model is rejected and the scatter inflation applied
INFLATIONS = ("repeatability", "birge", "none")
MULTI_MIN_DISTINCT = 9       # 9 parameters: at least 9 distinct orientations
# The wizard asks for more: 9 orientations fix the 9 parameters exactly and leave nothing to test the fit with
MULTI_ASKED = 12
MULTI_ASKED_WHY = "so the fit has orientations to spare and can test itself (9 fix its 9 unknowns exactly)"
DISTINCT_DEG = 10.0          # two poses closer than this repeat (nearly) the same orientation
MULTI_MIN_RCOND = 1e-6       # reciprocal condition of the column-scaled Jacobian below which we refuse

UPPER_INDEX = (0, 1, 2, 4, 5, 8)          # C.ravel() entries free in the upper-triangular gauge
MULTI_NAMES = ["C_xx", "C_xy", "C_xz", "C_yy", "C_yz", "C_zz", "b_x", "b_y", "b_z"]
AFFINE_K_NAMES = [f"K_{r}{c}" for r in AXES for c in AXES] + [f"o_{a}" for a in AXES]
PAPER_NAMES = [f"angle_{a}" for a in AXES] + [f"gain_{a}" for a in AXES] + [f"offset_{a}" for a in AXES]
CORRECTION_NAMES = [f"C_{r}{c}" for r in AXES for c in AXES] + [f"b_{a}" for a in AXES]


# ------------------------------------------------------------------ inputs

@dataclass
class PoseStats:
    """Sufficient statistics of one still pose.

    mean  (3,) raw m/s^2;  cov  (3, 3) covariance of ONE sample (or a scalar sd
    per axis);  n  number of samples (the mean's covariance is cov / n; pass an
    effective n when the samples are correlated);  face  nominal face down
    ("+z": z points down, reads -g) for six-face mode;  name  for messages.
    """

    mean: np.ndarray
    cov: np.ndarray | float
    n: float
    face: str | None = None
    name: str = ""

    def __post_init__(self) -> None:
        self.mean = np.asarray(self.mean, dtype=float).reshape(3)
        cov = np.asarray(self.cov, dtype=float)
        self.cov = np.eye(3) * float(cov) ** 2 if cov.ndim == 0 else cov.reshape(3, 3)
        self.n = float(self.n)
        if self.n < 1 or not np.all(np.isfinite(self.mean)) or not np.all(np.isfinite(self.cov)):
            raise CalibrationError(f"pose {self.name or '?'}: needs a finite mean, covariance and n >= 1")
        if self.face is not None and self.face not in FACES:
            raise CalibrationError(f"pose {self.name or '?'}: {self.face!r} is not a face", "faces are +x, -x, +y, -y, +z, -z")

    @classmethod
    def from_samples(cls, samples: np.ndarray, face: str | None = None, name: str = "") -> PoseStats:
        x = np.asarray(samples, dtype=float).reshape(-1, 3)
        if len(x) < 2:
            raise CalibrationError(f"pose {name or '?'}: needs at least 2 samples")
        return cls(x.mean(axis=0), np.cov(x.T), len(x), face, name)

    @property
    def mean_cov(self) -> np.ndarray:
        """Covariance of the mean (m/s^2)^2, floored so a noiseless pose stays usable."""
        v = self.cov / self.n
        return v + np.eye(3) * max(1e-12, 1e-9 * np.trace(v))


def _names(poses: Sequence[PoseStats]) -> list[str]:
    return [p.name or f"pose {k + 1}" for k, p in enumerate(poses)]


# ------------------------------------------------------------------ result

@dataclass
class GravityFit:
    """One fit: the correction with its covariance, the model's own parameters, and the quality figures.

    ``magnitude_residuals``: |C (m_p - b)| - g per pose (m/s^2).  ``tilts_deg``: for six-face fits the
    estimated angle of each pose's gravity from its face (degrees).  ``uncertainty_source`` says what the
    covariance holds: "noise", "noise + flatness prior (Type B)", and "x Birge ratio" when chi^2 rejected.
    ``gauge``: which correction entries are fixed by convention (their covariance rows are zero).
    """

    model: str
    correction: Correction
    names: list[str]
    values: np.ndarray
    covariance: np.ndarray
    chi2: float
    dof: int
    birge: float
    inflated: bool
    uncertainty_source: str
    magnitude_residuals: np.ndarray
    pose_names: list[str]
    g: float
    pose_flatness_deg: float | None = None
    tilts_deg: np.ndarray | None = None
    gauge: str = "none: the faces fix the orientation of C"
    n_evaluations: int = 0
    seconds: float = 0.0
    repeatability_sd: float = 0.0   # sigma_r (m/s^2) of the "repeatability" inflation, 0 when not applied
    chi2_before: float | None = None  # chi^2 before inflation (equals chi2 for Birge or none)
    # d [values, C.ravel(), b] / d s (k, parameters + 12) along each of the pose means' shifts s asked of the fit
    # (fit_six_face's ``mean_shifts``), None when none were
    mean_response: np.ndarray | None = None
    extra: dict = field(default_factory=dict)

    @property
    def uncertainty(self) -> np.ndarray:
        return np.sqrt(np.clip(np.diag(self.covariance), 0.0, None))

    @property
    def p_value(self) -> float:
        """p-value of the lack of fit before any inflation."""
        c = self.chi2 if self.chi2_before is None else self.chi2_before
        return float(chi2_dist.sf(c, self.dof)) if self.dof > 0 else float("nan")


def _birge(chi2: float, dof: int) -> tuple[float, bool]:
    """Birge ratio sqrt(chi^2/dof) and whether it is applied (chi^2 rejects the model at CHI2_ALPHA)."""
    if dof <= 0:
        return 1.0, False
    ratio = float(np.sqrt(chi2 / dof))
    rejected = chi2_dist.sf(chi2, dof) < CHI2_ALPHA
    return ratio, bool(rejected and ratio > 1.0)


def _solve_repeatability(chi2_of, dof: int) -> float:
    """Additive variance v >= 0 with chi2_of(v) = dof (chi2_of decreasing in v): Paule-Mandel by bracketing."""
    from scipy.optimize import brentq

    lo, hi = 0.0, 1e-8
    while chi2_of(hi) > dof:
        lo, hi = hi, hi * 10.0
        if hi > 1e4:
            raise CalibrationError("the pose scatter is too large to calibrate (repeatability above 100 m/s^2)")
    return float(brentq(lambda v: chi2_of(v) - dof, lo, hi, xtol=1e-14, rtol=1e-6))


def _wander_note(wander_var: float) -> str:
    return (f" + slow-noise wander between the poses {np.sqrt(wander_var):.2g} m/s^2 (1/f, extrapolated from the "
            "poses' halves)") if wander_var > 0 else ""


def _between_poses(covariance: np.ndarray, data_jacobian: np.ndarray, sensitivity: np.ndarray,
                   between: np.ndarray | None) -> np.ndarray:
    """The fit's covariance with the pose means' covariance between poses added (a sandwich): the fit weighs each
    pose by its own mean's covariance as if the poses were independent; noise slower than a hold makes the means
    of nearby poses share part of it (``between``, (3 P, 3 P), the diagonal blocks zero).  The estimate moves
    by A dr (A = covariance J_d^T, J_d the whitened data rows of the Jacobian) for a change dr = S dm of those
    rows from a change dm of the pose means (``sensitivity`` S), so the shared part adds A S B S^T A^T.  The
    weights stay the fit's: the noise's correlation time is known to a factor of about 2, which a GLS fit would
    turn into weights as uncertain, where the sandwich only needs it for the added term."""
    if between is None or not np.any(between):
        return covariance
    influence = covariance @ data_jacobian.T @ sensitivity
    added = influence @ between @ influence.T
    return covariance + 0.5 * (added + added.T)


def _check_inflation(inflation: str) -> None:
    if inflation not in INFLATIONS:
        raise CalibrationError(f"unknown inflation {inflation!r}", "use repeatability, birge or none")


def _magnitudes(correction: Correction, poses: Sequence[PoseStats], g: float) -> np.ndarray:
    return np.linalg.norm(correction.apply(np.array([p.mean for p in poses])), axis=1) - g


# ------------------------------------------------------------------ gauge helpers

def upper_gauge(matrix: np.ndarray) -> np.ndarray:
    """The upper-triangular R with positive diagonal such that C = Q R (Q a rotation or reflection).

    |C x| = |R x| for every x: the representative of C a gravity-magnitude fit can see.
    """
    q, r = np.linalg.qr(np.asarray(matrix, dtype=float))
    signs = np.sign(np.diag(r))
    signs[signs == 0] = 1.0
    return signs[:, None] * r


def distinct_orientations(means: np.ndarray, min_angle_deg: float = DISTINCT_DEG) -> int:
    """Number of pose directions more than ``min_angle_deg`` apart (greedy clustering)."""
    dirs = np.asarray(means, dtype=float)
    dirs = dirs / np.linalg.norm(dirs, axis=1, keepdims=True)
    cos_lim = np.cos(np.radians(min_angle_deg))
    centres: list[np.ndarray] = []
    for d in dirs:
        if not any(d @ c > cos_lim for c in centres):
            centres.append(d)
    return len(centres)


# ------------------------------------------------------------------ multi-position

def _upper(x: np.ndarray) -> np.ndarray:
    c = np.zeros(9)
    c[list(UPPER_INDEX)] = x[:6]
    return c.reshape(3, 3)


def _multi_residual_jacobian(x: np.ndarray, means: np.ndarray, g: float):
    """r_p = |C (m_p - b)| - g and dr/dx (analytic): dr/dC_ij = u_i (m - b)_j, dr/db = -C^T u."""
    c_mat, b = _upper(x), x[6:9]
    d = means - b
    v = d @ c_mat.T
    norm = np.linalg.norm(v, axis=1)
    u = v / norm[:, None]
    dc = (u[:, :, None] * d[:, None, :]).reshape(-1, 9)[:, list(UPPER_INDEX)]
    db = -u @ c_mat
    return norm - g, np.hstack([dc, db]), u


def _ellipsoid_start(means: np.ndarray, g: float) -> np.ndarray:
    """Algebraic fit of the quadric (m - b)^T A (m - b) = 1 (least squares on the 10 coefficients), as start."""
    x = means / g
    design = np.column_stack([x[:, 0] ** 2, x[:, 1] ** 2, x[:, 2] ** 2, 2 * x[:, 0] * x[:, 1],
                              2 * x[:, 0] * x[:, 2], 2 * x[:, 1] * x[:, 2], 2 * x, np.ones(len(x))])
    coef = np.linalg.svd(design)[2][-1]
    a = np.array([[coef[0], coef[3], coef[4]], [coef[3], coef[1], coef[5]], [coef[4], coef[5], coef[2]]])
    if np.trace(a) < 0:
        a, coef = -a, -coef
    q, c0 = coef[6:9], coef[9]
    try:
        centre = -np.linalg.solve(a, q)
        k = centre @ a @ centre - c0
        c_mat = np.linalg.cholesky(a / k).T          # upper triangular, positive diagonal
    except np.linalg.LinAlgError:
        centre, c_mat = np.zeros(3), np.eye(3)
    if not np.all(np.isfinite(c_mat)):
        centre, c_mat = np.zeros(3), np.eye(3)
    return np.concatenate([c_mat.ravel()[list(UPPER_INDEX)], centre * g])


def _multi_covariance_to_correction(cov9: np.ndarray) -> np.ndarray:
    idx = list(UPPER_INDEX) + [9, 10, 11]
    full = np.zeros((12, 12))
    full[np.ix_(idx, idx)] = cov9
    return full


def fit_multiposition(poses: Sequence[PoseStats], g: float = STANDARD_GRAVITY,
                      min_distinct: int = MULTI_MIN_DISTINCT, inflation: str = "repeatability",
                      wander_var: float = 0.0, spent_dof: int = 0, between: np.ndarray | None = None) -> GravityFit:
    """Tedaldi et al. (imu_tk) multi-position fit: |C (m_p - b)| = g, C upper triangular (9 parameters).

    Refuses (CalibrationError) with fewer than ``min_distinct`` orientations more than DISTINCT_DEG apart,
    or when the poses leave a parameter combination undetermined (column-scaled Jacobian's reciprocal
    condition below MULTI_MIN_RCOND).  The correction's covariance has zero rows for C_yx, C_zx, C_zy
    (fixed to 0 by the gauge).  ``inflation``: see the module docstring.  ``between``: the covariance between
    different poses' means (3 P, 3 P, pose-major, diagonal blocks zero), added through ``_between_poses``.
    """
    start = time.perf_counter()
    _check_inflation(inflation)
    poses = list(poses)
    means = np.array([p.mean for p in poses]).reshape(-1, 3)
    n_distinct = distinct_orientations(means) if len(poses) else 0
    if n_distinct < min_distinct:
        raise CalibrationError(
            f"{len(poses)} still poses in {n_distinct} distinct orientations: the multi-position fit "
            f"(9 parameters) needs at least {min_distinct} orientations more than {DISTINCT_DEG:.0f} degrees apart",
            "hold the sensor still in more orientations, between the faces too, or use six-face mode")
    covs = [p.mean_cov for p in poses]
    x_start = _ellipsoid_start(means, g)
    n_eval = 0

    def sds(x, extra_var):
        _, _, u = _multi_residual_jacobian(x, means, g)
        c_mat = _upper(x)
        return np.sqrt([uk @ c_mat @ v @ c_mat.T @ uk + extra_var for uk, v in zip(u, covs, strict=True)])

    def solve(extra_var):
        nonlocal n_eval
        x = x_start
        for _ in range(3):                   # weights s_p from the current C (they change little)
            s = sds(x, extra_var)
            sol = least_squares(lambda y, s=s: _multi_residual_jacobian(y, means, g)[0] / s, x,
                                jac=lambda y, s=s: _multi_residual_jacobian(y, means, g)[1] / s[:, None],
                                method="lm", xtol=1e-14, ftol=1e-14, gtol=1e-14, max_nfev=500)
            x, n_eval = sol.x, n_eval + int(sol.nfev)
        signs = np.sign(np.diag(_upper(x)))  # the sign of a row of C is a gauge too: keep the diagonal positive
        signs[signs == 0] = 1.0
        x = np.concatenate([(signs[:, None] * _upper(x)).ravel()[list(UPPER_INDEX)], x[6:9]])
        s = sds(x, extra_var)
        resid, jac_raw, _ = _multi_residual_jacobian(x, means, g)
        return x, resid, jac_raw / s[:, None], float(np.sum((resid / s) ** 2))

    x, resid, jw, chi2 = solve(wander_var)
    norms = np.linalg.norm(jw, axis=0)
    sv = np.linalg.svd(jw / norms, compute_uv=False)
    problem = unidentifiable_direction(jw, MULTI_NAMES)
    if problem or sv[-1] < MULTI_MIN_RCOND * sv[0]:
        raise CalibrationError(
            f"the {len(poses)} poses ({n_distinct} orientations) do not span the sphere enough to determine "
            f"C and b ({problem or f'reciprocal condition {sv[-1] / sv[0]:.1e}'})",
            "add poses in orientations far from the ones held, e.g. tilted between two faces")
    dof = len(poses) - 9 - spent_dof
    # the scatter is judged without the wander floor (a floor must never turn the repeatability off)
    chi2_before = chi2 if wander_var == 0 else solve(0.0)[3]
    birge, rejected = _birge(chi2_before, dof)
    source, sigma_r = "noise of the pose means" + ("" if rejected else _wander_note(wander_var)), 0.0
    cov_scale, final_var = 1.0, wander_var
    if rejected and inflation == "repeatability":
        v = max(_solve_repeatability(lambda var: solve(var)[3], dof) * _student_variance_factor(dof), wander_var)
        x, resid, jw, chi2 = solve(v)
        final_var = v
        sigma_r = float(np.sqrt(v))
        replaces = "; it replaces the slow-noise wander" if wander_var else ""
        source += (f" + pose repeatability {sigma_r:.2g} m/s^2 from the scatter (χ² was {chi2_before:.3g} for "
                   f"{dof} degrees of freedom; Student-widened{replaces})")
    elif rejected and inflation == "birge":
        cov_scale = birge**2
        source += f" x Birge ratio {birge:.3g} (χ² = {chi2:.3g} for {dof} degrees of freedom)"
    cov9 = np.linalg.inv(jw.T @ jw)
    if between is not None:
        # a magnitude residual moves by u_p^T C dm_p / s_p for a change dm_p of its pose's mean
        _, _, u = _multi_residual_jacobian(x, means, g)
        s = sds(x, final_var)
        sensitivity = np.zeros((len(poses), 3 * len(poses)))
        for i in range(len(poses)):
            sensitivity[i, 3 * i:3 * i + 3] = u[i] @ _upper(x) / s[i]
        cov9 = _between_poses(cov9, jw, sensitivity, between)
        source += "; the poses' shared slow noise added (sandwich)"
    cov9 = cov9 * cov_scale
    cov9 = 0.5 * (cov9 + cov9.T)
    correction = Correction(_upper(x), x[6:9], _multi_covariance_to_correction(cov9))
    return GravityFit("multi-position", correction, list(MULTI_NAMES), x.copy(), cov9, chi2, dof, birge,
                      bool(rejected and inflation != "none"), source, resid, _names(poses), g,
                      gauge="C upper triangular (C_yx = C_zx = C_zy = 0 exactly, zero covariance): "
                            "calibrated x on the sensor's x axis, y in its xy plane",
                      n_evaluations=n_eval, seconds=time.perf_counter() - start, repeatability_sd=sigma_r,
                      chi2_before=chi2_before, extra={"n_distinct": n_distinct, "rcond": float(sv[-1] / sv[0])})


def multiposition_crb(matrix: np.ndarray, bias: np.ndarray, directions: np.ndarray, counts, sigma: float,
                      g: float = STANDARD_GRAVITY) -> np.ndarray:
    """CRB (12 x 12, correction order, upper-triangular gauge) of a planned multi-position run.

    matrix, bias  the expected correction (any gauge: it is reduced to upper_gauge(matrix));
    directions    (P, 3) directions of the specific force in the frame of ``matrix`` (the axis up reads +g);
    counts        samples per pose (scalar or P);  sigma  white noise sd per raw axis (m/s^2).
    """
    r = upper_gauge(matrix)
    dirs = np.asarray(directions, dtype=float).reshape(-1, 3)
    dirs = dirs / np.linalg.norm(dirs, axis=1, keepdims=True)
    counts = np.broadcast_to(np.asarray(counts, dtype=float), (len(dirs),))
    means = np.linalg.solve(np.asarray(matrix, dtype=float), (g * dirs).T).T + np.asarray(bias, dtype=float)
    x = np.concatenate([r.ravel()[list(UPPER_INDEX)], bias])
    _, jac, u = _multi_residual_jacobian(x, means, g)
    s = np.sqrt([sigma**2 / n * (uk @ r @ r.T @ uk) for uk, n in zip(u, counts, strict=True)])
    jw = jac / s[:, None]
    problem = unidentifiable_direction(jw, MULTI_NAMES)
    if problem:
        raise CalibrationError(f"these orientations cannot determine the 9 parameters: {problem}",
                               f"plan at least {MULTI_MIN_DISTINCT} orientations spread over the sphere")
    return _multi_covariance_to_correction(np.linalg.inv(jw.T @ jw))


# ------------------------------------------------------------------ six faces: models

class _Model:
    """Forward model raw = K f + o of a six-face fit, in the model's own parameters, with dK/dp, do/dp."""

    def __init__(self, kind: str):
        if kind not in ("affine", "paper"):
            raise CalibrationError(f"unknown six-face model {kind!r}", "use affine or paper")
        self.kind = kind
        self.names = AFFINE_K_NAMES if kind == "affine" else PAPER_NAMES
        self.size = 12 if kind == "affine" else 9

    def forward(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(K, o, dKo) with dKo (12, size): derivative of [K.ravel(), o] with respect to p."""
        if self.kind == "affine":
            return p[:9].reshape(3, 3), p[9:12], np.eye(12)
        angles, gains, offs = p[:3], p[3:6], p[6:9]
        r = rotation_xyz(angles)
        ginv = 1.0 / gains
        k = r.T * ginv[None, :]                       # R^T diag(1/G)
        o = -k @ offs
        # dK / d angle_j = dR_j^T diag(1/G); dK / d gain_j = column j of R^T times -1/G_j^2 (arrays: the fit
        # evaluates this some twenty times per solve)
        dk = np.zeros((6, 3, 3))
        dk[:3] = np.transpose(rotation_xyz_derivatives(angles), (0, 2, 1)) * ginv[None, None, :]
        dk[3 + np.arange(3), :, np.arange(3)] = -r * ginv[:, None] ** 2      # row j: column j of R^T
        d = np.zeros((12, 9))
        d[:9, :6] = dk.reshape(6, 9).T
        d[9:, :6] = -(dk @ offs).T
        d[9:, 6:9] = -k
        return k, o, d

    def to_correction(self, p: np.ndarray) -> np.ndarray:
        k, o, _ = self.forward(p)
        return np.concatenate([np.linalg.inv(k).ravel(), o])

    def correction_jacobian(self, p: np.ndarray) -> np.ndarray:
        """d [C.ravel(), b] / d p (12, size) of ``to_correction``, from forward's dK/dp, do/dp: C = K^-1 moves
        by -C dK C, b = o.  (Analytic: the central differences it replaces cost as much as a third of a fit.)"""
        k, _, dko = self.forward(p)
        c = np.linalg.inv(k)
        dk = dko[:9].T.reshape(-1, 3, 3)
        return np.vstack([(-c @ dk @ c).reshape(-1, 9).T, dko[9:]])

    def start(self, k: np.ndarray, o: np.ndarray) -> np.ndarray:
        if self.kind == "affine":
            return np.concatenate([k.ravel(), o])
        c = np.linalg.inv(k)
        gains = np.linalg.norm(c, axis=1)
        return np.concatenate([np.zeros(3), gains, -c @ o])


def _tangents(e: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    k = int(np.argmax(np.abs(e)))
    others = [j for j in range(3) if j != k]
    return np.eye(3)[others[0]], np.eye(3)[others[1]]


def _affine_exact_start(poses: Sequence[PoseStats], g: float) -> tuple[np.ndarray, np.ndarray]:
    """Least squares of raw = K f + o with f the exact face references (closed form start)."""
    f = np.array([-g * face_down_direction(p.face) for p in poses])
    design = np.column_stack([f, np.ones(len(poses))])
    w = np.sqrt([p.n for p in poses])
    sol = np.linalg.lstsq(design * w[:, None], np.array([p.mean for p in poses]) * w[:, None], rcond=None)[0]
    return sol[:3].T, sol[3]


def _six_face_system(model: _Model, poses: Sequence[PoseStats], g: float, tau: float, extra_var: float = 0.0):
    """Residual and Jacobian of the MAP problem: whitened pose means (3 per pose) and tilt priors (2 per pose);
    and the whitening (P, 3, 3) of each pose's mean.  All poses at once (arrays, no loop over poses: the fit
    evaluates this some twenty times per solve)."""
    downs = np.array([face_down_direction(p.face) for p in poses])
    tangents = np.array([_tangents(e) for e in downs])                       # (P, 2, 3)
    whiten = np.array([np.linalg.inv(np.linalg.cholesky(p.mean_cov + extra_var * np.eye(3))) for p in poses])
    means = np.array([p.mean for p in poses])
    n_pose, n_m = len(poses), model.size
    n_t = 2 * n_pose if tau > 0 else 0
    poses_ix = np.arange(n_pose)

    def system(x):
        p, t = x[:n_m], x[n_m:]
        k_mat, o, dko = model.forward(p)
        if tau > 0:
            v = downs + np.einsum("pj,pjk->pk", t.reshape(n_pose, 2), tangents)
            nv = np.linalg.norm(v, axis=1)
            d = v / nv[:, None]
            # d direction / d (tilt a, tilt b): the tangents projected off the direction, over its length
            dd = (tangents - np.einsum("pk,pj->pjk", d, np.einsum("pjk,pk->pj", tangents, d))) / nv[:, None, None]
        else:
            d = downs
        f = -g * d                                                            # (P, 3)
        pred = f @ k_mat.T + o
        res = np.zeros(3 * n_pose + n_t)
        jac = np.zeros((3 * n_pose + n_t, n_m + n_t))
        res[:3 * n_pose] = np.einsum("pij,pj->pi", whiten, means - pred).ravel()
        # d pred / d p: K_ab -> f_b in row a, o -> I, through d [K.ravel(), o] / d p
        dpred = np.einsum("pb,abn->pan", f, dko[:9].reshape(3, 3, n_m)) + dko[9:][None]
        jac[:3 * n_pose, :n_m] = -np.einsum("pij,pjn->pin", whiten, dpred).reshape(3 * n_pose, n_m)
        if tau > 0:
            # pose i's residual on its own two tilts: -W_i K (-g d direction / d tilt)
            tilt_cols = g * np.einsum("pij,jk,pmk->pim", whiten, k_mat, dd)    # (P, 3, 2)
            block = np.zeros((n_pose, 3, n_pose, 2))
            block[poses_ix, :, poses_ix, :] = tilt_cols
            jac[:3 * n_pose, n_m:] = block.reshape(3 * n_pose, n_t)
            res[3 * n_pose:] = t / tau
            jac[3 * n_pose:, n_m:] = np.eye(n_t) / tau
        return res, jac

    return system, n_t, whiten


def _mean_response(model: _Model, system, x: np.ndarray, res: np.ndarray, jac: np.ndarray, inverse: np.ndarray,
                   whiten: np.ndarray, shifts: np.ndarray) -> np.ndarray:
    """d [values, C.ravel(), b] / d s (k, size + 12): the MAP solution's first-order response to shifts s of the
    pose means, ``shifts`` (k, P, 3), from the fit's own Jacobian at its solution x (implicit function theorem;
    the weights and flatness held at the solve's).  The residual r = W (m - pred(x)) moves by W dm, so
    dx = -H^-1 J^T W dm with H = J^T J + sum_i r_i d^2 r_i / dx^2.  J^T J alone (``inverse`` is its inverse: the
    fit's covariance) misses the second term, 1e-3 to 1e-2 of the response with a hand's tilts and noise: it is
    added by fixed-point steps dx <- -(J^T J)^-1 (J^T W dm + S dx), S dx from J's change along dx (one evaluation
    per shift, forward difference of 1e-6 of the parameters' scale), each of which shrinks the error by the
    term's size: two or three bring it to about 1e-6.  What it replaces: a refit per shift (the static
    procedure's drift terms, 3 rates and 3 curvatures: six refits), the costliest part of the static calibration.  Checked against refits in tests/test_static_drift_jacobian.py."""
    n_pose, n_rows = len(whiten), len(res)
    data_shift = np.zeros((n_rows, len(shifts)))
    data_shift[:3 * n_pose] = np.einsum("pij,kpj->pik", whiten, shifts).reshape(3 * n_pose, len(shifts))
    gradient = jac.T @ data_shift                      # d (J^T r) / d s at fixed x
    dx = -inverse @ gradient                           # Gauss-Newton
    scale = np.maximum(np.abs(x), 1e-2)
    for _ in range(5):
        second = np.zeros_like(dx)
        for k in range(dx.shape[1]):
            size = float(np.max(np.abs(dx[:, k]) / scale))
            if size == 0.0:
                continue
            eps = 1e-6 / size
            # (J(x + eps dx) - J(x))^T r / eps: the residuals' curvature along dx, weighted by the residuals
            second[:, k] = (system(x + eps * dx[:, k])[1] - jac).T @ res / eps
        updated = -inverse @ (gradient + second)
        change = np.max(np.abs(updated - dx) / scale[:, None]) / max(np.max(np.abs(updated) / scale[:, None]), 1e-300)
        dx = updated
        if change < 1e-7:     # converged: the step's own error (about 1e-6) is larger than what is left
            break
    dp = dx[:model.size]
    return np.vstack([dp, model.correction_jacobian(x[:model.size]) @ dp]).T


def _require_faces(poses: Sequence[PoseStats]) -> None:
    missing = [f for f in FACES if not any(p.face == f for p in poses)]
    unnamed = [n for p, n in zip(poses, _names(poses), strict=True) if p.face is None]
    if unnamed:
        raise CalibrationError(f"six-face mode needs the face of every pose; {', '.join(unnamed)} has none",
                               "classify the poses first (face_tilts) or use the multi-position fit")
    if missing:
        raise CalibrationError(f"six-face mode needs all six faces; missing {', '.join(missing)} down",
                               "put the sensor down on the missing faces too")


def magnitude_z(correction_vec: np.ndarray, poses: Sequence[PoseStats], g: float,
                extra_var: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """The gravity magnitudes' residuals |C (m_p - b)| - g per pose, and the same in units of their sd from
    each mean's covariance (plus ``extra_var`` per axis): (z, residuals)."""
    c_mat, b = correction_vec[:9].reshape(3, 3), correction_vec[9:12]
    means, covs = _means_and_covs(poses, extra_var)
    v = (means - b) @ c_mat.T
    norm = np.linalg.norm(v, axis=1)
    w = (v / norm[:, None]) @ c_mat                    # C^T u: the magnitude's gradient in the raw mean
    var = np.einsum("pi,pij,pj->p", w, covs, w)
    resid = norm - g
    return resid / np.sqrt(var), resid


def magnitude_z_response(correction_vec: np.ndarray, d_correction: np.ndarray, poses: Sequence[PoseStats],
                         d_means: np.ndarray, g: float, extra_var: float = 0.0) -> np.ndarray:
    """d z / d s (P, k) of ``magnitude_z``'s z along k joint changes of the correction (``d_correction`` (k, 12),
    [C.ravel(), b]) and of the pose means (``d_means`` (k, P, 3)); the means' covariances held.  Analytic: with
    v = C (m - b), u = v / |v|, w = C^T u, var = w^T V w, z = (|v| - g) / sqrt(var)."""
    c_mat, b = correction_vec[:9].reshape(3, 3), correction_vec[9:12]
    d_c, d_b = d_correction[:, :9].reshape(-1, 3, 3), d_correction[:, 9:12]
    means, covs = _means_and_covs(poses, extra_var)
    v = (means - b) @ c_mat.T
    norm = np.linalg.norm(v, axis=1)
    u = v / norm[:, None]
    w = u @ c_mat
    var = np.einsum("pi,pij,pj->p", w, covs, w)
    dv = np.einsum("kij,pj->kpi", d_c, means - b) + np.einsum("ij,kpj->kpi", c_mat, d_means - d_b[:, None, :])
    d_norm = np.einsum("pi,kpi->kp", u, dv)
    du = (dv - u[None] * d_norm[..., None]) / norm[None, :, None]
    dw = np.einsum("kji,pj->kpi", d_c, u) + du @ c_mat
    d_var = 2.0 * np.einsum("pi,pij,kpj->kp", w, covs, dw)
    d_z = d_norm / np.sqrt(var) - (norm - g) * d_var / (2.0 * var ** 1.5)
    return d_z.T


def _means_and_covs(poses: Sequence[PoseStats], extra_var: float) -> tuple[np.ndarray, np.ndarray]:
    return (np.array([p.mean for p in poses]),
            np.array([p.mean_cov for p in poses]) + extra_var * np.eye(3))


def _magnitude_chi2(correction_vec: np.ndarray, poses: Sequence[PoseStats], g: float, extra_var: float) -> tuple[float, np.ndarray]:
    """chi^2 of the gravity magnitudes |C (m_p - b)| - g against their variance from each mean's covariance."""
    z, resid = magnitude_z(correction_vec, poses, g, extra_var)
    return float(z @ z), resid


def fit_six_face(poses: Sequence[PoseStats], model: str = "affine",
                 pose_flatness_deg: float = DEFAULT_POSE_FLATNESS_DEG, g: float = STANDARD_GRAVITY,
                 inflation: str = "repeatability", wander_var: float = 0.0, spent_dof: int = 0,
                 between: np.ndarray | None = None, mean_shifts: np.ndarray | None = None) -> GravityFit:
    """Six-face fit with every pose's gravity direction a nuisance tilted from its face (MAP, flatness prior).

    model "affine" (12: C, b) or "paper" (9: angles, gains, offsets, calibrated = G R raw + c).
    ``pose_flatness_deg``: sd of each of the two tilt components of a pose (0: the paper's exact faces).

    Two lack-of-fit tests, because a tilt prior that is conservative makes the overall chi^2 small while
    the gravity magnitudes may still disagree:
      tilts      sum (tilt / flatness)^2 against its null distribution (_tilt_statistic_null: only the
                 tilt combinations the data can tell from the model count, 6 of 12 for six affine faces,
                 9 for the paper model); the observed flatness, flatness x sqrt(chi^2 / null mean) widened
                 by the Student factor of those few dof, replaces the stated one when it is larger (the
                 stated flatness is a floor) and the fit is redone; a warning when p < CHI2_ALPHA;
      magnitudes |C (m_p - b)| - g against P - 6 dof (tilt-free: what the data say beyond the faces):
                 when it rejects, ``inflation`` ("repeatability": an additive per-pose sd, or "birge").
    With flatness 0 (exact faces) the test is the whole chi^2 against 3 P - parameters.
    ``spent_dof``: degrees of freedom the pose means already gave to something fitted out of them (a drift
    referred to the middle of the run): the magnitudes' test has that many fewer.  ``between``: the covariance
    between different poses' means (3 P, 3 P, pose-major, diagonal blocks zero: noise slower than a hold),
    added through ``_between_poses``.  ``mean_shifts`` (k, P, 3): directions in which the pose means may move
    (the static procedure's drift terms); the fit's first-order response to each, d [values, C, b] per unit
    along it, is returned as ``mean_response`` (``_mean_response``: from the fit's own Jacobian, no refit).
    """
    start = time.perf_counter()
    _check_inflation(inflation)
    poses = list(poses)
    _require_faces(poses)
    if pose_flatness_deg < 0 or not np.isfinite(pose_flatness_deg):
        raise CalibrationError(f"pose flatness must be >= 0 degrees, got {pose_flatness_deg}")
    m = _Model(model)
    k0, o0 = _affine_exact_start(poses, g)
    n_eval = 0
    n_pose = len(poses)

    def solve(flat_deg, extra_var):
        nonlocal n_eval
        tau = float(np.tan(np.radians(flat_deg)))
        system, n_t, whiten = _six_face_system(m, poses, g, tau, extra_var)
        x0 = np.concatenate([m.start(k0, o0), np.zeros(n_t)])
        sol = least_squares(lambda x: system(x)[0], x0, jac=lambda x: system(x)[1], method="lm",
                            xtol=1e-15, ftol=1e-15, gtol=1e-15, max_nfev=400)
        n_eval += int(sol.nfev)
        res, jac = system(sol.x)
        corr = m.to_correction(sol.x[:m.size])
        if tau > 0:
            chi2_t = float(np.sum((sol.x[m.size:] / tau) ** 2))
            chi2_m = _magnitude_chi2(corr, poses, g, extra_var)[0]
        else:
            chi2_t, chi2_m = 0.0, float(res @ res)
        return sol.x, jac, chi2_m, chi2_t, n_t, (system, whiten, res)

    flat = float(pose_flatness_deg)
    x, jac, chi2_m, chi2_t, n_t, last = solve(flat, wander_var)
    names = list(m.names) + [f"tilt{k}" for k in range(n_t)]
    problem = unidentifiable_direction(jac, names)
    if problem:
        raise CalibrationError(f"the six-face poses do not determine the {model} model: {problem}")
    notes = []
    source = "noise" if flat == 0 else f"noise + flatness prior {flat:g} deg (Type B)"
    tilt_mean, tilt_scale, tilt_dof = _tilt_statistic_null(jac, n_t)
    # the six-face model's own test of fit: do the tilts the poses need stay within the stated flatness?
    # the statistic as tested: chi2_t / tilt_scale follows chi^2 with tilt_dof degrees of freedom, so this one
    # figure, its dof and its p are said together (the warning and the check line), before any refit
    tilt_stat = chi2_t / tilt_scale if tilt_scale > 0 else 0.0
    tilt_p = float(chi2_dist.sf(tilt_stat, tilt_dof)) if flat > 0 and tilt_dof > 0 else float("nan")
    # The flatness the tilts show: method of moments (the statistic scales with flatness^2, its null mean is
    # tilt_mean), widened by the Student factor of its tilt_dof degrees of freedom so that +-2u stays a
    # 95 % interval although the flatness is estimated from a few tilt combinations.
    observed = (flat * float(np.sqrt(chi2_t / tilt_mean * _student_variance_factor(tilt_dof)))
                if tilt_mean > 0 else 0.0)
    tilts_rejected = False
    if flat > 0 and observed > flat and inflation != "none":
        # The stated flatness is a floor: the tilts the data show can only widen it.  Said as a warning only
        # when they are beyond what the stated flatness explains (p < CHI2_ALPHA); the source says it always.
        if tilt_p < CHI2_ALPHA:
            tilts_rejected = True
            notes.append(f"tilts exceed the stated flatness {flat:g} deg (χ² = {tilt_stat:.3g} for {tilt_dof:.3g} "
                         f"degrees of freedom, p = {tilt_p:.3g}): flatness {observed:.2g} deg from the observed "
                         "tilts used")
        source = f"noise + observed flatness {observed:.2g} deg (stated {flat:g}, Type B)"
        flat = observed
        x, jac, chi2_m, chi2_t, n_t, last = solve(flat, wander_var)
    dof = (n_pose - 6 if flat > 0 else 3 * n_pose - m.size) - spent_dof
    # the scatter is judged without the wander floor (a floor must never turn the repeatability off)
    chi2_before = chi2_m if wander_var == 0 else solve(flat, 0.0)[2]
    birge, rejected = _birge(chi2_before, dof)
    cov_scale, sigma_r = 1.0, 0.0
    source += "" if rejected else _wander_note(wander_var)
    if rejected and inflation == "repeatability":
        v = max(_solve_repeatability(lambda var: solve(flat, var)[2], dof) * _student_variance_factor(dof), wander_var)
        x, jac, chi2_m, chi2_t, n_t, last = solve(flat, v)
        sigma_r = float(np.sqrt(v))
        replaces = "; it replaces the slow-noise wander" if wander_var else ""
        source += (f" + pose repeatability {sigma_r:.2g} m/s^2 from the scatter (χ² was {chi2_before:.3g} for "
                   f"{dof} degrees of freedom; Student-widened{replaces})")
    elif rejected and inflation == "birge":
        cov_scale = birge**2
        source += f" x Birge ratio {birge:.3g} (χ² = {chi2_m:.3g} for {dof} degrees of freedom)"
    full_cov = np.linalg.inv(jac.T @ jac)
    system, whiten, res = last
    response = None if mean_shifts is None else _mean_response(m, system, x, res, jac, full_cov, whiten, mean_shifts)
    cov = full_cov
    if between is not None:
        # the data rows are the pose means whitened by each pose's own covariance (as the last solve weighed them)
        whiten_all = np.zeros((3 * n_pose, 3 * n_pose))
        for i in range(n_pose):
            whiten_all[3 * i:3 * i + 3, 3 * i:3 * i + 3] = whiten[i]
        cov = _between_poses(cov, jac[:3 * n_pose], whiten_all, between)
        source += "; the poses' shared slow noise added (sandwich)"
    cov = cov[:m.size, :m.size] * cov_scale
    p = x[:m.size]
    corr_values, corr_jac = m.to_correction(p), m.correction_jacobian(p)
    corr_cov = corr_jac @ cov @ corr_jac.T
    corr_cov = 0.5 * (corr_cov + corr_cov.T)
    if flat > 0 and model == "affine":
        corr_cov = corr_cov + _diagonal_second_order(corr_cov)
    correction = Correction(corr_values[:9].reshape(3, 3), corr_values[9:], corr_cov)
    tilts = (np.degrees(np.arctan(np.hypot(x[m.size::2], x[m.size + 1::2]))) if n_t
             else np.zeros(n_pose))
    label = f"six-face {model}" if pose_flatness_deg > 0 else f"exact-face {model}"
    return GravityFit(label, correction, list(m.names), p, 0.5 * (cov + cov.T), chi2_m, dof, birge,
                      bool(rejected and inflation != "none") or tilts_rejected, source,
                      _magnitudes(correction, poses, g), _names(poses), g, pose_flatness_deg=flat,
                      tilts_deg=tilts, n_evaluations=n_eval, seconds=time.perf_counter() - start,
                      repeatability_sd=sigma_r, chi2_before=chi2_before, mean_response=response,
                      extra={"chi2_tilts": tilt_stat, "tilt_dof": round(tilt_dof, 2), "tilt_p_value": tilt_p,
                             "notes": notes,
                             "stated_flatness_deg": float(pose_flatness_deg)})


def _diagonal_second_order(corr_cov: np.ndarray) -> np.ndarray:
    """The second-order term of C's diagonal that the linearised covariance misses (12 x 12, added).

    The faces fix every calibrated vector's length: for the poses on axis k, |(I + S) e_k| = 1 with S the
    relative error of C, so S_kk = -sum_j S_jk^2 / 2 (j != k): an error e_jk of the off-diagonal entries
    in column k moves the diagonal entry by -sum e_jk^2 / 2, which a first-order propagation shows as 0.
    With e_jk ~ N(0, v_jk) (their stated variances) that is a mean of sum v / 2 and a variance of
    sum v^2 / 2; their mean square is added to var(C_kk).  Affine model only: there a face pair's tilt
    difference is its shear, so the off-diagonal entries are known only as well as the flatness (at one
    degree the term is 1e-4, at three it is the main uncertainty of the gains).  In the paper model the
    off-diagonal entries are a rotation and the gains are read along gravity; what it leaves is the
    posterior variance of the common-rotation part of the tilts, about 1/P of this, and is neglected.
    """
    extra = np.zeros_like(corr_cov)
    var = np.clip(np.diag(corr_cov)[:9], 0.0, None).reshape(3, 3)
    for k in range(3):
        column = np.delete(var[:, k], k)
        extra[4 * k, 4 * k] = (column.sum() / 2) ** 2 + np.sum(column**2) / 2
    return extra


def _tilt_statistic_null(jac: np.ndarray, n_t: int) -> tuple[float, float, float]:
    """Null distribution of sum (tilt / flatness)^2 at the MAP, to first order: (mean, scale, dof).

    The statistic is the part of the whitened residual in the prior's rows (the last ``n_t`` rows of the
    MAP system).  With the hat matrix H of the whitened Jacobian it is a quadratic form in (I - H)
    restricted to those rows, M: mean trace M, and Satterthwaite's scale x chi^2(dof) matches its first
    two moments (scale = tr M^2 / tr M, dof = (tr M)^2 / tr M^2).  Tilt combinations that the data cannot
    tell from the model (in the affine model a face pair's tilt difference is its shear) have a residual
    of zero whatever the tilts are, so they do not count: with six faces the affine model sees 6 of the
    12 tilt components and the paper model 9 (the 3 of a common rotation are its angles).
    """
    if n_t == 0:
        return 0.0, 1.0, 0.0
    q, _ = np.linalg.qr(jac)
    qs = q[-n_t:]
    mat = np.eye(n_t) - qs @ qs.T
    tr, tr2 = float(np.trace(mat)), float(np.sum(mat * mat))
    if tr <= 1e-9:
        return 0.0, 1.0, 0.0
    return tr, tr2 / tr, tr * tr / tr2


def _student_variance_factor(dof: float) -> float:
    """(k_t / 2)^2: how much a variance estimated with ``dof`` degrees of freedom is widened so that +-2u
    keeps the normal +-2 sd coverage (95.45 %): k_t the Student t quantile at that coverage."""
    from accelrig.estimation.distributions import normal_cdf, student_t_quantile

    return float((student_t_quantile(normal_cdf(2.0), dof) / 2.0) ** 2) if dof > 0 else 1.0


def six_face_crb(model: str, matrix: np.ndarray, bias: np.ndarray, faces: Sequence[str], counts, sigma: float,
                 pose_flatness_deg: float = DEFAULT_POSE_FLATNESS_DEG, g: float = STANDARD_GRAVITY,
                 params: np.ndarray | None = None, draws: int = 0, seed: int = 0,
                 drift_times=None, drift_axes: Sequence[int] = (),
                 curvature_anchors: dict[int, tuple[float, float]] | None = None) -> np.ndarray:
    """Bound (12 x 12, correction order) of a planned six-face run with the flatness prior.

    The hybrid CRB: the inverse of the data information at zero tilt plus the prior information of the
    tilts, marginal block of the model parameters, propagated to the correction (``draws`` > 0 averages
    the data information over tilts drawn from the prior instead: the Van Trees form).  Both are first
    order: the affine model's offsets carry a further ~ g s^2 / 2 from the product of the unknown tilt
    difference of a face pair and its shear (docs/static-tilt-notes.md), which no first-order bound shows.
    With flatness 0 it is the plain CRB.
    ``params`` gives the paper model's parameters (else derived from ``matrix``, ``bias`` with zero angles).
    ``drift_times``, ``drift_axes``: the poses' centre times (s) and the raw axes (0-2) whose offset drifts at
    an unknown constant rate, nuisance parameters as the static procedure fits them for the axes held twice
    (the offsets then stand for the count-weighted mean of the times, as there).  ``curvature_anchors``:
    per raw axis whose drift's curvature is fitted too (a face held three times), the first and last of
    that face's hold times: the pose means gain kappa_k (q(t_i) - mean q), q(t) = (t - t_a)(t - t_b) / 2, as
    the static procedure refers them (the offsets stand for the run's average).
    """
    m = _Model(model)
    counts = np.broadcast_to(np.asarray(counts, dtype=float), (len(faces),))
    c = np.asarray(matrix, dtype=float)
    k_true, o_true = np.linalg.inv(c), np.asarray(bias, dtype=float)
    poses = [PoseStats(k_true @ (-g * face_down_direction(f)) + o_true, sigma, n, f) for f, n in zip(faces, counts, strict=True)]
    tau = float(np.tan(np.radians(pose_flatness_deg)))
    system, n_t, _ = _six_face_system(m, poses, g, tau)
    p = np.asarray(params, dtype=float) if params is not None else m.start(k_true, o_true)
    rng = np.random.default_rng(seed)
    samples = [np.zeros(n_t)] if n_t == 0 or draws == 0 else [tau * rng.standard_normal(n_t) for _ in range(draws)]
    bends = sorted((curvature_anchors or {}).items())
    drift = np.zeros((3 * len(faces) + n_t, len(drift_axes) + len(bends)))
    if len(drift_axes) or bends:
        # pose i's mean on axis k gains r_k (t_i - t_mid) (+ kappa_k (q(t_i) - mean q)); the residual is
        # whitened by sqrt(n) / sigma
        times = np.asarray(drift_times, dtype=float)
        for c, k in enumerate(drift_axes):
            drift[k:3 * len(faces):3, c] = -np.sqrt(counts) / sigma * (times - np.average(times, weights=counts))
        for c, (k, (t_a, t_b)) in enumerate(bends, start=len(drift_axes)):
            q = (times - t_a) * (times - t_b) / 2.0
            drift[k:3 * len(faces):3, c] = -np.sqrt(counts) / sigma * (q - np.average(q, weights=counts))
    info = np.zeros((m.size + n_t + drift.shape[1],) * 2)
    for t in samples:
        jac = np.hstack([system(np.concatenate([p, t]))[1], drift])
        info += jac.T @ jac / len(samples)
    cov = np.linalg.inv(info)[:m.size, :m.size]
    corr_jac = m.correction_jacobian(p)
    out = corr_jac @ cov @ corr_jac.T
    return 0.5 * (out + out.T)


# ------------------------------------------------------------------ Ferraris pairing

def fit_ferraris(poses: Sequence[PoseStats], g: float = STANDARD_GRAVITY, repeatability_sd: float = 0.0) -> GravityFit:
    """Opposite-face pairing of Ferraris et al. (1995) as imucal implements it (poses of one face pooled).

    U_d = [m(-k down) - m(+k down)]_k (columns), C = 2 g U_d^-1, b_k = (m(-k)_k + m(+k)_k) / 2.
    Uncertainty: the noise of the pose means propagated (the method states none), plus an optional
    per-pose ``repeatability_sd`` (e.g. the one a fit of the same session found); no tilt term.
    """
    start = time.perf_counter()
    poses = list(poses)
    _require_faces(poses)
    pooled = {}
    for f in FACES:
        group = [p for p in poses if p.face == f]
        n = sum(p.n for p in group)
        extra = repeatability_sd**2 * np.eye(3)
        pooled[f] = (sum(p.n * p.mean for p in group) / n, sum(p.n**2 * (p.mean_cov + extra) for p in group) / n**2)
    x = np.concatenate([pooled[f][0] for f in FACES])             # +x, -x, +y, -y, +z, -z
    vx = np.zeros((18, 18))
    for k, f in enumerate(FACES):
        vx[3 * k:3 * k + 3, 3 * k:3 * k + 3] = pooled[f][1]

    def correction_of(y):
        m = y.reshape(6, 3)
        u_d = np.column_stack([m[2 * k + 1] - m[2 * k] for k in range(3)])
        bias = np.array([(m[2 * k + 1][k] + m[2 * k][k]) / 2 for k in range(3)])
        return np.concatenate([(2 * g * np.linalg.inv(u_d)).ravel(), bias])

    values, cov = propagate_covariance(correction_of, x, vx)
    correction = Correction(values[:9].reshape(3, 3), values[9:], cov)
    return GravityFit("ferraris", correction, list(CORRECTION_NAMES), values, cov, float("nan"), 0, 1.0, False,
                      "noise of the pose means" + (f" + pose repeatability {repeatability_sd:.2g} m/s^2"
                                                   if repeatability_sd else ""), _magnitudes(correction, poses, g), _names(poses), g,
                      seconds=time.perf_counter() - start)


# ------------------------------------------------------------------ face classifier

@dataclass
class FaceTilt:
    name: str
    face: str
    angle_deg: float


def face_tilts(poses: Sequence[PoseStats], g: float = STANDARD_GRAVITY) -> list[FaceTilt]:
    """How far each pose's gravity is from the nearest face, in degrees.

    The means are first corrected by per-axis gains and offsets from an axis-aligned gravity-magnitude fit
    (|D (m - o)| = g, D diagonal: insensitive to tilts, so a 25-degree pose does not bias it), which
    needs at least 6 poses with both ends of every axis; otherwise the raw means are used.  Then the one
    rotation that best turns the poses near a face (within DISTINCT_DEG) onto their faces is removed
    (Kabsch): the sensor's misalignment in its housing is common to every pose and is a parameter of the
    six-face models (the paper's R), not a tilt of the poses.  What is left (the poses' own tilts and the
    axes' non-orthogonality, typically tenths of a degree) is the angle.
    """
    means = np.array([p.mean for p in poses]).reshape(-1, 3)
    aligned = axis_aligned_fit(means, g)
    corrected = means if aligned is None else (means - aligned[1]) * aligned[0]
    corrected = corrected @ _common_rotation(corrected).T
    out = []
    for name, v in zip(_names(poses), corrected, strict=True):
        k = int(np.argmax(np.abs(v)))
        angle = float(np.degrees(np.arccos(min(abs(v[k]) / np.linalg.norm(v), 1.0))))
        out.append(FaceTilt(name, ("+" if v[k] < 0 else "-") + AXES[k], angle))
    return out


def axis_aligned_fit(means: np.ndarray, g: float = STANDARD_GRAVITY) -> tuple[np.ndarray, np.ndarray] | None:
    """Per-axis gains D and offsets o with |D (m - o)| = g over the pose means (least squares on the magnitudes:
    insensitive to the poses' tilts); None without at least 6 poses reaching both ends of every axis."""
    means = np.asarray(means, dtype=float).reshape(-1, 3)
    dominant = np.argmax(np.abs(means), axis=1)
    both_ends = all(np.any((dominant == k) & (means[:, k] > 0)) and np.any((dominant == k) & (means[:, k] < 0))
                    for k in range(3))
    if len(means) < 6 or not both_ends:
        return None
    hi = np.array([means[(dominant == k) & (means[:, k] > 0), k].mean() for k in range(3)])
    lo = np.array([means[(dominant == k) & (means[:, k] < 0), k].mean() for k in range(3)])
    x0 = np.concatenate([2 * g / (hi - lo), (hi + lo) / 2])

    def fun(x):
        return np.linalg.norm((means - x[3:]) * x[:3], axis=1) - g

    sol = least_squares(fun, x0, method="lm")
    if not sol.success or not np.all(sol.x[:3] > 0):
        return None
    return sol.x[:3], sol.x[3:]


def _common_rotation(vectors: np.ndarray) -> np.ndarray:
    """The rotation R that best maps the unit vectors of the poses within DISTINCT_DEG of a face onto that
    face's axis (Kabsch); the identity unless such poses lie on at least two axes."""
    units = vectors / np.linalg.norm(vectors, axis=1, keepdims=True)
    k = np.argmax(np.abs(units), axis=1)
    targets = np.eye(3)[k] * np.sign(units[np.arange(len(units)), k])[:, None]
    near = np.einsum("ij,ij->i", units, targets) > np.cos(np.radians(DISTINCT_DEG))
    if len(set(k[near])) < 2:
        return np.eye(3)
    u, _, vt = np.linalg.svd(targets[near].T @ units[near])
    d = np.sign(np.linalg.det(u @ vt))
    return u @ np.diag([1.0, 1.0, d]) @ vt


def check_faces(poses: Sequence[PoseStats], pose_flatness_deg: float = DEFAULT_POSE_FLATNESS_DEG,
                g: float = STANDARD_GRAVITY, refuse_sd: float = FACE_REFUSE_SD) -> list[FaceTilt]:
    """Six-face mode's gate: refuse (one line, naming the pose and its angle) any pose further than
    ``refuse_sd`` x the flatness from a face; otherwise return the classification (face and angle per pose)."""
    limit = refuse_sd * pose_flatness_deg
    tilts = face_tilts(poses, g)
    bad = [t for t in tilts if t.angle_deg > limit]
    if bad:
        worst = max(bad, key=lambda t: t.angle_deg)
        others = f" ({len(bad)} of {len(tilts)} poses are)" if len(bad) > 1 else ""
        raise CalibrationError(
            f"{worst.name} is {worst.angle_deg:.1f} degrees from {worst.face}, more than {limit:.1f} "
            f"({refuse_sd:g} x the pose flatness {pose_flatness_deg:g} deg){others}",
            "use the multi-position model or place the face flat")
    return tilts
