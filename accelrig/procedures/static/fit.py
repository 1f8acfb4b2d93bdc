"""Estimators of the six-face static calibration (paper 000, sections 2-3), and their CRB.

Measurement model (what both estimators and the CRB assume).  Pose i rests on
a face whose axis is exactly vertical (the paper's levelled granite), so the
true specific force is the known reference f_i (the face's axis reads -g).
Each raw sample is

    raw_ij = K f_i + o + e_ij,   e_ij ~ N(0, sigma^2 I)  (white, per raw axis),

with K = C^-1, o = b of the canonical correction calibrated = C (raw - b).
The per-pose means m_i are sufficient statistics: least squares on the
samples equals least squares on the means weighted by sqrt(n_i), so the
fits run on means (fast) and sigma comes from the pooled within-pose scatter
(thousands of degrees of freedom).  The CRB is sigma^2 (J^T J)^-1 of this
same sample-level model (crb.py).

Because the references are the housing faces, the orientation of C is
observable: there is no gauge freedom here (unlike a fit of |C(raw-b)| = g,
which cannot see a rotation and needs >= 9 generic orientations).  The price:
a pose that is not exactly face-down (table not level, cube not square) is
an error the data cannot reveal beyond the lack-of-fit test reported below.

Models
  paper   calibrated = G R(angles) raw + c, 9 parameters (eq. 3-9).  Forward:
          R raw = G^-1 f - G^-1 c, i.e. per axis k a straight line in f_k with
          slope 1/G_k and intercept -c_k/G_k: the paper's separable form
          (Listing 1).  Solved by variable projection + LM (method "vp") or
          by the paper's Nelder-Mead over the angles (method "paper").
  affine  calibrated = C (raw - b), all 12 entries: raw = K f + o is linear,
          solved in closed form (same code path, no nonlinear parameters).
          Captures non-orthogonal axes (and the gain-after-rotation order of
          a real sensor, raw = diag(gain) T R f + o) that G R cannot.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import minimize

from accelrig.errors import CalibrationError
from accelrig.estimation import crb_covariance, propagate_covariance, separable_jacobian, varpro
from accelrig.estimation.distributions import chi2 as chi2_dist
from accelrig.geometry import AXES, FACES, parse_axis, rotation_xyz, rotation_xyz_derivatives
from accelrig.procedures.static.settings import METHODS, MODELS
from accelrig.result import Correction
from accelrig.units import STANDARD_GRAVITY

PAPER_NAMES = [f"angle_{a}" for a in AXES] + [f"gain_{a}" for a in AXES] + [f"offset_{a}" for a in AXES]
PAPER_UNITS = ["rad"] * 3 + ["1"] * 3 + ["m/s^2"] * 3
AFFINE_NAMES = [f"C_{r}{c}" for r in AXES for c in AXES] + [f"b_{a}" for a in AXES]
AFFINE_UNITS = ["1"] * 9 + ["m/s^2"] * 3


def face_reference(face: str, g: float = STANDARD_GRAVITY) -> np.ndarray:
    """Specific force (body frame) of a level pose with ``face`` down: that axis points down and reads -g."""
    # Built element by element rather than as -g * direction: the product would put -0.0 in the two
    # other axes, which changes the fits' last bits (results must not depend on how this was written).
    axis, sign = parse_axis(face) if face in FACES else (None, None)
    if axis is None:
        raise ValueError(f"not a face: {face!r}")
    f = np.zeros(3)
    f[axis] = -sign * g
    return f


@dataclass
class PoseData:
    """Sufficient statistics of the accepted poses: what every estimator needs."""

    faces: list[str]
    means: np.ndarray         # (P, 3) raw m/s^2
    counts: np.ndarray        # (P,)
    within_ss: np.ndarray     # (P,) sum over samples and axes of squared deviations from the mean
    g: float = STANDARD_GRAVITY

    def __post_init__(self) -> None:
        self.means = np.asarray(self.means, dtype=float).reshape(-1, 3)
        self.counts = np.asarray(self.counts, dtype=float).ravel()
        self.within_ss = np.asarray(self.within_ss, dtype=float).ravel()

    @property
    def references(self) -> np.ndarray:
        return np.array([face_reference(f, self.g) for f in self.faces])

    @property
    def weights(self) -> np.ndarray:
        """sqrt(n_i) per observation (pose i, raw axis j), row order i*3 + j."""
        return np.repeat(np.sqrt(self.counts), 3)

    @property
    def noise_dof(self) -> int:
        return int(3 * np.sum(self.counts - 1))

    @property
    def noise_sd(self) -> float:
        """Pooled within-pose sd per raw axis (m/s^2): sigma of the measurement model."""
        if self.noise_dof <= 0:
            raise CalibrationError("poses too short to estimate the noise")
        return float(np.sqrt(np.sum(self.within_ss) / self.noise_dof))

    @property
    def pose_noise_sd(self) -> np.ndarray:
        return np.sqrt(self.within_ss / np.maximum(3 * (self.counts - 1), 1))


# --------------------------------------------------------------- model algebra

def _paper_columns(r: np.ndarray, refs: np.ndarray) -> np.ndarray:
    n = refs.shape[0]
    slope = np.einsum("kj,ik->ijk", r, refs).reshape(3 * n, 3)
    intercept = np.tile(r.T, (n, 1))
    return np.hstack([slope, intercept])


def _paper_basis(refs: np.ndarray):
    """Phi(angles): observation (i, j) = R^T (c1 * f_i + c2), linear [c1 (3), c2 (3)].

    Returns (basis, basis_derivatives); Phi is linear in R, so dPhi/dangle
    is Phi built from dR/dangle.
    """

    def basis(alpha):
        return _paper_columns(rotation_xyz(alpha), refs)

    def derivatives(alpha):
        return np.array([_paper_columns(d, refs) for d in rotation_xyz_derivatives(np.asarray(alpha, float))])

    return basis, derivatives


def _affine_basis(refs: np.ndarray):
    """Observation (i, j) = K[j] . f_i + o_j, linear [K00 K01 K02 o0, K10 ... o2]."""
    n = refs.shape[0]
    phi = np.zeros((3 * n, 12))
    for j in range(3):
        phi[j::3, 4 * j:4 * j + 3] = refs
        phi[j::3, 4 * j + 3] = 1.0
    return lambda alpha: phi


def paper_internal_to_params(x: np.ndarray) -> np.ndarray:
    """[angles, c1, c2] -> [angles, G = 1/c1, c = -c2/c1]."""
    angles, c1, c2 = x[:3], x[3:6], x[6:9]
    return np.concatenate([angles, 1.0 / c1, -c2 / c1])


def paper_params_to_internal(p: np.ndarray) -> np.ndarray:
    angles, gains, offsets = p[:3], p[3:6], p[6:9]
    return np.concatenate([angles, 1.0 / gains, -offsets / gains])


def paper_params_to_correction(p: np.ndarray) -> np.ndarray:
    """[angles, G, c] -> [C.ravel(), b] with C = G R, b = -C^-1 c (DESIGN.md)."""
    c_mat = np.diag(p[3:6]) @ rotation_xyz(p[:3])
    return np.concatenate([c_mat.ravel(), -np.linalg.solve(c_mat, p[6:9])])


def affine_internal_to_params(x: np.ndarray) -> np.ndarray:
    """[K row 0, o0, K row 1, o1, ...] -> [C.ravel(), b] with C = K^-1, b = o."""
    block = x.reshape(3, 4)
    return np.concatenate([np.linalg.inv(block[:, :3]).ravel(), block[:, 3]])


def affine_params_to_internal(p: np.ndarray) -> np.ndarray:
    k = np.linalg.inv(p[:9].reshape(3, 3))
    return np.column_stack([k, p[9:12]]).ravel()


def params_to_correction(model: str, p: np.ndarray) -> np.ndarray:
    return paper_params_to_correction(p) if model == "paper" else np.asarray(p, dtype=float)


# --------------------------------------------------------------------- fits

@dataclass
class ModelFit:
    """One model fitted to the poses, in its reported parameters."""

    model: str
    method: str
    names: list[str]
    units: list[str]
    values: np.ndarray
    covariance: np.ndarray
    correction: Correction
    rss: float                # weighted residual sum of squares of the means (m/s^2)^2 x samples
    dof: int                  # 3 P - number of parameters
    sigma: float
    residuals: np.ndarray     # (P, 3) raw-domain residual of each pose mean, m/s^2
    seconds: float
    n_evaluations: int
    extra: dict = field(default_factory=dict)

    @property
    def uncertainty(self) -> np.ndarray:
        return np.sqrt(np.clip(np.diag(self.covariance), 0.0, None))

    @property
    def chi2(self) -> float:
        """Lack of fit of the pose means in units of their noise (~ chi^2 with dof if the model holds)."""
        return self.rss / self.sigma**2

    @property
    def p_value(self) -> float:
        return float(chi2_dist.sf(self.chi2, self.dof)) if self.dof > 0 else float("nan")

    @property
    def aic(self) -> float:
        return self.chi2 + 2 * len(self.names)

    def bic(self, n_observations: int) -> float:
        return self.chi2 + len(self.names) * np.log(n_observations)


def _finish(model, method, data: PoseData, internal, cov_internal, rss, to_params, start, n_eval, extra=None):
    names, units = (PAPER_NAMES, PAPER_UNITS) if model == "paper" else (AFFINE_NAMES, AFFINE_UNITS)
    values, cov = propagate_covariance(to_params, internal, cov_internal)
    corr_values, corr_cov = propagate_covariance(lambda p: params_to_correction(model, p), values, cov)
    correction = Correction(corr_values[:9].reshape(3, 3), corr_values[9:], corr_cov)
    predicted = np.linalg.solve(correction.matrix, data.references.T).T + correction.bias
    return ModelFit(model, method, list(names), list(units), values, cov, correction, float(rss),
                    3 * len(data.faces) - len(names), data.noise_sd, data.means - predicted,
                    time.perf_counter() - start, n_eval, extra or {})


def fit_affine(data: PoseData) -> ModelFit:
    start = time.perf_counter()
    fit = varpro(data.means.ravel(), _affine_basis(data.references), (), weights=data.weights,
                 sigma=data.noise_sd)
    return _finish("affine", "vp", data, fit.parameters, fit.covariance, fit.rss, affine_internal_to_params,
                   start, 0)


def fit_paper_vp(data: PoseData) -> ModelFit:
    """The 9-parameter model by variable projection + LM (angles outside, per-axis lines inside)."""
    start = time.perf_counter()
    basis, derivatives = _paper_basis(data.references)
    fit = varpro(data.means.ravel(), basis, np.zeros(3), derivatives, weights=data.weights,
                 sigma=data.noise_sd, alpha_names=PAPER_NAMES[:3],
                 linear_names=[f"slope_{a}" for a in AXES] + [f"intercept_{a}" for a in AXES])
    return _finish("paper", "vp", data, fit.parameters, fit.covariance, fit.rss, paper_internal_to_params,
                   start, fit.n_evaluations, {"message": fit.message})


def _paper_listing_cost(phis_deg: np.ndarray, m: np.ndarray, a: np.ndarray):
    """Listing 1 (costCal), line for line: rotate, per-axis line fit, Frobenius cost / sqrt(numel)."""
    r = rotation_xyz(np.deg2rad(phis_deg))
    mr = r @ m
    gains, offsets, coefs = np.zeros(3), np.zeros(3), np.zeros((3, 2))
    for k in range(3):
        d = np.column_stack([a[k], np.ones(a.shape[1])])
        cfs = np.linalg.lstsq(d, mr[k], rcond=None)[0]
        gains[k] = 1.0 / cfs[0]
        offsets[k] = -cfs[1] / cfs[0]
        coefs[k] = cfs
    ar = np.diag(gains) @ mr + offsets[:, None]
    cost = np.linalg.norm(a - ar, "fro") / np.sqrt(a.size)
    return cost, coefs


def fit_paper_nelder_mead(data: PoseData) -> ModelFit:
    """The paper's own scheme (Listing 2): fminsearch over the angles from zero around Listing 1.

    MATLAB's rotx/roty/rotz take degrees, so the search runs in degrees with
    fminsearch's default tolerances (TolX = TolFun = 1e-4, MaxFunEvals = 200 x 3),
    which scipy's Nelder-Mead reproduces.  The paper reports no uncertainty;
    we evaluate the same least-squares covariance at the point it stops.
    """
    start = time.perf_counter()
    m, a = data.means.T, data.references.T
    sol = minimize(lambda p: _paper_listing_cost(p, m, a)[0], np.zeros(3), method="Nelder-Mead",
                   options={"xatol": 1e-4, "fatol": 1e-4, "maxfev": 600})
    angles = np.deg2rad(sol.x)
    _, coefs = _paper_listing_cost(sol.x, m, a)
    internal = np.concatenate([angles, coefs[:, 0], coefs[:, 1]])
    basis, derivatives = _paper_basis(data.references)
    jac = separable_jacobian(basis, angles, internal[3:], derivatives, weights=data.weights)
    cov = crb_covariance(jac, data.noise_sd)
    resid = data.weights * (data.means.ravel() - basis(angles) @ internal[3:])
    return _finish("paper", "paper", data, internal, cov, float(resid @ resid), paper_internal_to_params,
                   start, int(sol.nfev), {"message": str(sol.message), "converged": bool(sol.success)})


def fit_model(data: PoseData, model: str, method: str = "vp") -> ModelFit:
    if model not in MODELS:
        raise CalibrationError(f"unknown model {model!r}", "use paper, affine or auto")
    if method not in METHODS:
        raise CalibrationError(f"unknown method {method!r}", "use vp or paper")
    if model == "affine":
        return fit_affine(data)
    return fit_paper_nelder_mead(data) if method == "paper" else fit_paper_vp(data)


# ---------------------------------------------------------------------- CRB

def static_crb(model: str, params: np.ndarray, faces: list[str], counts, sigma: float,
               g: float = STANDARD_GRAVITY) -> np.ndarray:
    """Cramér-Rao covariance of a model's reported parameters for a planned six-face run.

    params  the true (or expected) parameters in the model's order
            (PAPER_NAMES or AFFINE_NAMES); faces and counts per pose; sigma the
            per-sample white noise sd of each raw axis (m/s^2).  The bound is
            for exactly the data and noise model the fits use.
    """
    counts = np.asarray(counts, dtype=float)
    if counts.size == 1 and len(faces) > 1:
        counts = np.full(len(faces), float(counts))
    refs = np.array([face_reference(f, g) for f in faces])
    weights = np.repeat(np.sqrt(counts), 3)
    params = np.asarray(params, dtype=float)
    if model == "paper":
        internal = paper_params_to_internal(params)
        basis, derivatives = _paper_basis(refs)
        jac = separable_jacobian(basis, internal[:3], internal[3:], derivatives, weights=weights)
        to_params = paper_internal_to_params
    elif model == "affine":
        internal = affine_params_to_internal(params)
        jac = weights[:, None] * _affine_basis(refs)(())
        to_params = affine_internal_to_params
    else:
        raise CalibrationError(f"unknown model {model!r}")
    cov_internal = crb_covariance(jac, sigma)
    return propagate_covariance(to_params, internal, cov_internal)[1]
