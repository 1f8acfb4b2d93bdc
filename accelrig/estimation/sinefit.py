"""Sine fits with uncertainty: IEEE Std 1057 three- and four-parameter fits, with harmonics.

Model (t in the caller's time axis, seconds or sample indices)::

    y(t) = offset + sum_{k=1..H} A_k cos(2 pi k f t + phi_k)

* ``fit_frequency=False``: the three-parameter fit of IEEE 1057 (frequency
  known), linear least squares on [1, cos, sin] (one pair per harmonic).
* ``fit_frequency=True``: the four-parameter fit, solved by variable projection
  (Golub-Pereyra): the frequency is the only nonlinear parameter; for each trial
  frequency the offset and the cos/sin coefficients are solved exactly by QR and
  Gauss-Newton runs on the projected residual ||P_perp(f) y|| alone.  This needs
  no start values for the linear parameters, converges in a few iterations and
  gives the covariance of every parameter at the end.
* Harmonics k = 2..H share the fundamental frequency.  A slider-crank's motion
  is not a pure sine (its second harmonic is lambda times the first); over a
  non-integer number of cycles the harmonics are not orthogonal to the
  fundamental, so a one-sine fit of such a signal is biased by tens of CRBs.
* Start value (``frequency=None``): an interpolated DFT (Hann window, two-point
  interpolation), error a few hundredths of a bin, not the bare FFT arg-max
  whose error reaches half a bin.  The fit then runs first with one sine and
  then with all harmonics, each stage starting where the previous one ended, so
  a harmonic never sees a start value k times further off than the fundamental.

Time is centred inside (numerical conditioning, and it decorrelates frequency
from phase); reported phases refer to t = 0 of the caller's axis and their
uncertainties include the frequency's contribution over that lever arm.

Uncertainties are standard (k = 1), from the fit's covariance
sigma^2 (J^T J)^-1 with sigma estimated from the residuals (RSS / (n - p)).
With ``check_noise=True`` the residuals are tested for whiteness first
(estimation.residuals); when they are correlated the covariance is the
sandwich instead (batch means, or for a record too short for enough blocks
the AR-spectrum sandwich), and ``covariance_method`` / ``whiteness`` say so.
Needs samples uniform in ``t`` for the AR form (sample indices always are).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from accelrig.errors import DataError
from accelrig.estimation.crb import crb_covariance, normal_covariance
from accelrig.estimation.residuals import Whiteness, checked_covariance, whiteness

MIN_CYCLES = 1.5  # below this the frequency and the offset cannot be told apart (IEEE 1057)
MAX_ITERATIONS = 60
STATISTICAL_TOLERANCE = 1e-3  # Gauss-Newton stops at steps below this share of the frequency's own u
STAGE_SAMPLES = 4096  # a first (one-sine) stage needs no more samples than this to reach the basin


@dataclass
class SineFit:
    """Outcome of :func:`fit_sine`.  Arrays indexed by harmonic: ``amplitude[0]`` is k = 1.

    ``covariance`` is over ``parameter_names``: ``frequency`` (only when fitted),
    ``offset``, then ``amplitude_k``, ``phase_k`` for k = 1..H.
    """

    frequency: float
    frequency_uncertainty: float
    amplitude: np.ndarray
    amplitude_uncertainty: np.ndarray
    phase: np.ndarray
    phase_uncertainty: np.ndarray
    offset: float
    offset_uncertainty: float
    covariance: np.ndarray
    parameter_names: list[str]
    residual_sd: float
    residuals: np.ndarray
    fitted: np.ndarray
    n_iterations: int
    converged: bool
    start_frequency: float = float("nan")
    harmonics: int = 1
    frequency_fitted: bool = True
    covariance_method: str = "white noise: sigma^2 (J'J)^-1"
    whiteness: Whiteness | None = None   # with check_noise=True

    def model(self, t: np.ndarray) -> np.ndarray:
        """Evaluate the fitted model at times ``t`` (same axis as the fit)."""
        t = np.asarray(t, dtype=float)
        y = np.full(t.shape, self.offset)
        for k in range(1, self.harmonics + 1):
            y = y + self.amplitude[k - 1] * np.cos(2 * np.pi * k * self.frequency * t + self.phase[k - 1])
        return y

    def to_dict(self) -> dict:
        return {
            "frequency": self.frequency,
            "frequency_uncertainty": self.frequency_uncertainty,
            "amplitude": self.amplitude.tolist(),
            "amplitude_uncertainty": self.amplitude_uncertainty.tolist(),
            "phase": self.phase.tolist(),
            "phase_uncertainty": self.phase_uncertainty.tolist(),
            "offset": self.offset,
            "offset_uncertainty": self.offset_uncertainty,
            "residual_sd": self.residual_sd,
            "n_iterations": self.n_iterations,
            "converged": self.converged,
            "harmonics": self.harmonics,
            "covariance_method": self.covariance_method,
            **({"whiteness": self.whiteness.to_dict()} if self.whiteness is not None else {}),
        }


@dataclass
class SineCRB:
    """Cramér-Rao bound of a sine (with harmonics) in white noise, same parameters as SineFit."""

    covariance: np.ndarray
    parameter_names: list[str]
    frequency_sd: float
    amplitude_sd: np.ndarray
    phase_sd: np.ndarray
    offset_sd: float
    extra: dict = field(default_factory=dict)


# ---------------------------------------------------------------- input checks

def _as_inputs(t, y) -> tuple[np.ndarray, np.ndarray]:
    y = np.asarray(y, dtype=float)
    if y.ndim != 1:
        raise DataError(f"a sine fit needs one signal (1-D), got shape {y.shape}", "fit each axis separately")
    t = np.arange(y.size, dtype=float) if t is None else np.asarray(t, dtype=float)
    if t.shape != y.shape:
        raise DataError(f"a sine fit needs one time per sample: {t.size} times for {y.size} samples")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(y))):
        bad = int(np.count_nonzero(~(np.isfinite(t) & np.isfinite(y))))
        raise DataError(f"the signal has {bad} NaN or infinite samples", "drop or repair them before fitting")
    if y.size >= 2 and np.any(np.diff(t) <= 0):
        raise DataError("the sample times are not strictly increasing", "sort the samples and drop duplicates")
    return t, y


def _check_harmonics(harmonics: int) -> int:
    if int(harmonics) != harmonics or harmonics < 1:
        raise DataError(f"harmonics must be a whole number >= 1, got {harmonics!r}")
    return int(harmonics)


# ---------------------------------------------------------------- model pieces

def _uniform_step(tc: np.ndarray) -> float | None:
    """The grid's step when every step is exactly the same (sample indices, strided or not), else None."""
    if tc.size < 3:
        return None
    step = tc[1] - tc[0]
    return float(step) if step > 0 and np.all(np.diff(tc) == step) else None


PHASOR_BLOCK = 256  # samples per block of the uniform-grid cos/sin (block phasor times in-block phasor)


def _cos_sin(tc: np.ndarray, frequency: float, step: float | None, out_cos: np.ndarray, out_sin: np.ndarray) -> None:
    """cos and sin of 2 pi f tc into the given columns.

    On a uniform grid (``step``) they come as the real and imaginary parts of the product of
    a phasor per block of PHASOR_BLOCK samples and one per position within a block: one complex
    multiply per sample instead of two transcendentals (10x faster; the angle's rounding is the
    same ~1e-13 rad as computing 2 pi f t directly).
    """
    n = tc.size
    omega = 2 * np.pi * frequency
    if step is None or n < 4 * PHASOR_BLOCK:
        arg = omega * tc
        np.cos(arg, out=out_cos)
        np.sin(arg, out=out_sin)
        return
    blocks = -(-n // PHASOR_BLOCK)
    outer = np.exp(1j * omega * (tc[0] + step * PHASOR_BLOCK * np.arange(blocks)))
    inner = np.exp(1j * omega * step * np.arange(PHASOR_BLOCK))
    z = np.multiply.outer(outer, inner).ravel()[:n]
    out_cos[:] = z.real
    out_sin[:] = z.imag


def _basis(tc: np.ndarray, frequency: float, harmonics: int, derivative: bool = True, step: float | None = None):
    """Design matrix [1, cos wt, sin wt, cos 2wt, sin 2wt, ...] and (``derivative``) its derivative in f.

    Column-major, so each column is one contiguous pass.  One cos and one sin per sample
    (``_cos_sin``; ``step`` when the grid is uniform); the harmonics by the angle-addition
    recurrence (a few multiply-adds instead of a transcendental each: the basis is most of a
    tall fit's time).
    """
    n = tc.size
    phi = np.empty((2 * harmonics + 1, n)).T
    phi[:, 0] = 1.0
    _cos_sin(tc, frequency, step, phi[:, 1], phi[:, 2])
    c1, s1 = phi[:, 1], phi[:, 2]
    for k in range(2, harmonics + 1):
        cp, sp = phi[:, 2 * k - 3], phi[:, 2 * k - 2]
        phi[:, 2 * k - 1] = cp * c1 - sp * s1
        phi[:, 2 * k] = sp * c1 + cp * s1
    if not derivative:
        return phi, None
    dphi = np.zeros_like(phi)
    lever = (2 * np.pi) * tc  # d(arg)/df for k = 1
    for k in range(1, harmonics + 1):
        dphi[:, 2 * k - 1] = -(k * lever) * phi[:, 2 * k]
        dphi[:, 2 * k] = (k * lever) * phi[:, 2 * k - 1]
    return phi, dphi


def _uniform_gram(tc: np.ndarray, step: float, frequency: float, harmonics: int) -> np.ndarray:
    """Phi'Phi of ``_basis`` on a uniform grid, in closed form (O(H^2) instead of a pass over n rows).

    Products of cos/sin of j and k times the angle are half sums of cos/sin of (j +- k) times
    it, and the sum of e^(i m w t) over a uniform grid is geometric: e^(i m w t_mid)
    sin(n m w step / 2) / sin(m w step / 2), with t_mid the grid's midpoint.  Below the Nyquist
    limit (checked by the callers) m w step stays inside (0, 2 pi) for m = 1 .. 2H.
    """
    n = tc.size
    m = np.arange(2 * harmonics + 1)
    half = np.pi * frequency * step * m[1:]           # m w step / 2
    t_mid = tc[0] + step * (n - 1) / 2.0
    sums = np.empty(m.size, dtype=complex)
    sums[0] = n
    sums[1:] = np.exp(2j * np.pi * frequency * m[1:] * t_mid) * (np.sin(n * half) / np.sin(half))
    cos_sum, sin_sum = sums.real, sums.imag              # over m >= 0; cos is even in m, sin odd

    def c(j):
        return cos_sum[abs(j)]

    def s(j):
        return np.sign(j) * sin_sum[abs(j)]

    # column 0 is cos 0 t; columns 2k - 1 and 2k are cos k and sin k
    order = [0] + [k for k in range(1, harmonics + 1) for _ in (0, 1)]
    is_sin = [False] + [kind for _ in range(harmonics) for kind in (False, True)]
    p = 2 * harmonics + 1
    gram = np.empty((p, p))
    for a in range(p):
        for b in range(a, p):
            j, k = order[a], order[b]
            if not is_sin[a] and not is_sin[b]:
                value = 0.5 * (c(j - k) + c(j + k))
            elif is_sin[a] and is_sin[b]:
                value = 0.5 * (c(j - k) - c(j + k))
            elif is_sin[b]:      # cos j sin k
                value = 0.5 * (s(j + k) - s(j - k))
            else:                # sin j cos k
                value = 0.5 * (s(j + k) + s(j - k))
            gram[a, b] = gram[b, a] = value
    return gram


# No QR or SVD of the tall n x p matrix: those run in multithreaded LAPACK,
# which on a loaded machine spends ~50x longer fighting for cores than
# computing.  The normal equations lose nothing here (with the time axis
# centred the columns are close to orthogonal) and need only p x p
# factorisations.  Gram matrices and products with the basis: BLAS for a few
# columns (single-threaded at that size, fastest), einsum for many (BLAS would
# go multithreaded again).
_BLAS_MAX_COLUMNS = 32


def _gram(a: np.ndarray) -> np.ndarray:
    return a.T @ a if a.shape[1] <= _BLAS_MAX_COLUMNS else np.einsum("ni,nj->ij", a, a)


def _gram_factor(phi: np.ndarray, gram: np.ndarray | None = None):
    gram = _gram(phi) if gram is None else gram
    try:
        return np.linalg.cholesky(gram)
    except np.linalg.LinAlgError:
        raise DataError(
            "the sine model is not identifiable from these samples",
            "record more cycles, or fit fewer harmonics",
        ) from None


def _solve_gram(chol: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    return np.linalg.solve(chol.T, np.linalg.solve(chol, rhs))


def _t_times(a: np.ndarray, v: np.ndarray) -> np.ndarray:
    """a' v for a tall a (n, p) and v (n,) or (n, m)."""
    return a.T @ v if a.shape[1] <= _BLAS_MAX_COLUMNS else np.einsum("ni,n...->i...", a, v)


def _times(a: np.ndarray, c: np.ndarray) -> np.ndarray:
    """a c for a tall a (n, p) and c (p,)."""
    return a @ c if a.shape[1] <= _BLAS_MAX_COLUMNS else np.einsum("ni,i->n", a, c)


def _project(phi: np.ndarray, y: np.ndarray, gram: np.ndarray | None = None):
    chol = _gram_factor(phi, gram)
    coef = _solve_gram(chol, _t_times(phi, y))
    resid = y - _times(phi, coef)
    return chol, coef, resid


def _vp_step(tc, y, frequency, harmonics, step=None):
    """Residual, cost and the Golub-Pereyra Jacobian of the projected residual in f.

    The basis's derivative in f is never built: column k of it is +-k lever times the matching
    sin/cos column (lever = 2 pi t), so dPhi c and dPhi' r are products with the basis itself.
    Also returns (basis, dPhi c, linear coefficients, Cholesky factor of the basis's Gram matrix)
    for the caller's final covariance.  ``step``: the grid's step when uniform (``_cos_sin``).
    """
    phi, _ = _basis(tc, frequency, harmonics, derivative=False, step=step)
    chol, coef, resid = _project(phi, y, None if step is None else _uniform_gram(tc, step, frequency, harmonics))
    lever = (2 * np.pi) * tc
    k = np.arange(1, harmonics + 1)
    weights = np.zeros_like(coef)
    weights[1::2] = k * coef[2::2]      # on cos k: k b_k
    weights[2::2] = -k * coef[1::2]     # on sin k: -k a_k
    dc = lever * _times(phi, weights)
    v = _t_times(phi, lever * resid)
    dphi_r = np.zeros_like(coef)
    dphi_r[1::2] = -k * v[2::2]
    dphi_r[2::2] = k * v[1::2]
    # d(P_perp y)/df = -P_perp (dPhi c) - Phi^+T (dPhi^T r); the second term is
    # Golub-Pereyra's, which Kaufman drops; kept since a one-sine fit of a
    # slider-crank signal has large residuals.  Both share Phi G^-1 (.):
    rhs = _t_times(phi, dc) + dphi_r
    jac = -dc + _times(phi, _solve_gram(chol, rhs))
    return resid, float(resid @ resid), jac, (phi, dc, coef, chol)


def _covariance(jac: np.ndarray, sigma2: float, names: list[str]) -> np.ndarray:
    """sigma^2 (J^T J)^-1 by the shared CRB helper, handed the p x p Cholesky factor R of J^T J.

    R^T R = J^T J, so R has J's column norms and singular values: the helper's
    covariance and its rank diagnosis are the same as for J itself.
    """
    gram = _gram(jac)
    try:
        factor = np.linalg.cholesky(gram).T
    except np.linalg.LinAlgError:
        factor = jac  # singular: let the helper name the unidentifiable direction
    # unit sigma then scaled: a noise-free record (sigma2 = 0) still gets its (zero) covariance
    return sigma2 * crb_covariance(factor, 1.0, names)


def _gauss_newton(tc, y, start, harmonics, tol, grid_step=None):
    """One-dimensional Gauss-Newton on the variable projection functional, with step halving.

    Stops when a step is below ``tol`` or below STATISTICAL_TOLERANCE times the frequency's own
    standard uncertainty (sqrt(cost / dof / J'J)): a step a thousand times smaller than the
    uncertainty changes nothing a user could see, so it is not taken and the point already
    evaluated is the answer.  Returns (frequency, iterations, converged, (basis, dPhi c, linear
    coefficients, Gram factor, residuals) at that frequency).  ``grid_step``: see ``_cos_sin``.
    """
    frequency = start
    resid, cost, jac, pieces = _vp_step(tc, y, frequency, harmonics, grid_step)
    dof = max(y.size - 2 * harmonics - 2, 1)
    for iteration in range(1, MAX_ITERATIONS + 1):
        jj = float(jac @ jac)
        if jj <= 0:
            return frequency, iteration, False, (*pieces, resid)
        step = -float(jac @ resid) / jj
        if abs(step) < STATISTICAL_TOLERANCE * np.sqrt(cost / dof / jj):
            return frequency, iteration, True, (*pieces, resid)
        for _ in range(40):
            trial = frequency + step
            if trial > 0:
                t_resid, t_cost, t_jac, t_pieces = _vp_step(tc, y, trial, harmonics, grid_step)
                if t_cost <= cost * (1 + 1e-14):
                    break
            step *= 0.5
        else:
            return frequency, iteration, abs(step) < tol, (*pieces, resid)
        frequency, resid, cost, jac, pieces = trial, t_resid, t_cost, t_jac, t_pieces
        if abs(step) < tol:
            return frequency, iteration, True, (*pieces, resid)
    return frequency, MAX_ITERATIONS, False, (*pieces, resid)


def _full_jacobian(tc, frequency, coef, harmonics, fit_frequency):
    phi, dphi = _basis(tc, frequency, harmonics, derivative=fit_frequency)
    if not fit_frequency:
        return phi
    return np.column_stack([dphi @ coef, phi])


def _internal_names(harmonics: int, fit_frequency: bool) -> list[str]:
    names = (["frequency"] if fit_frequency else []) + ["offset"]
    for k in range(1, harmonics + 1):
        names += [f"cos_{k}", f"sin_{k}"]
    return names


def _to_reported(coef, frequency, t_ref, harmonics, fit_frequency, cov_q):
    """Map [f, c0, a_k, b_k] (a cos + b sin about t_ref) to [f, offset, A_k, phi_k at t = 0]."""
    a, b = coef[1::2], coef[2::2]
    amp = np.hypot(a, b)
    safe = np.where(amp > 0, amp, np.finfo(float).tiny)
    k = np.arange(1, harmonics + 1)
    phase_ref = np.arctan2(-b, a)  # a cos x + b sin x = A cos(x + phase)
    phase = phase_ref - 2 * np.pi * k * frequency * t_ref
    phase = np.angle(np.exp(1j * phase))  # wrap to (-pi, pi]
    nf = 1 if fit_frequency else 0
    p = nf + 1 + 2 * harmonics
    g = np.zeros((p, p))  # d reported / d q
    if fit_frequency:
        g[0, 0] = 1.0
    g[nf, nf] = 1.0
    for i in range(harmonics):
        ia, ib = nf + 1 + 2 * i, nf + 2 + 2 * i
        g[ia, ia] = a[i] / safe[i]
        g[ia, ib] = b[i] / safe[i]
        g[ib, ia] = b[i] / safe[i] ** 2
        g[ib, ib] = -a[i] / safe[i] ** 2
        if fit_frequency:
            g[ib, 0] = -2 * np.pi * (i + 1) * t_ref
    cov = g @ cov_q @ g.T
    names = (["frequency"] if fit_frequency else []) + ["offset"]
    for i in range(1, harmonics + 1):
        names += [f"amplitude_{i}", f"phase_{i}"]
    return amp, phase, cov, names


# ---------------------------------------------------------------- public API

def interpolated_dft_frequency(t, y) -> float:
    """Frequency of the strongest non-DC spectral peak, refined by a Hann-window interpolated DFT.

    Two-point interpolation on the Hann window's main lobe: with alpha the ratio
    of the larger neighbour to the peak bin, the offset is (2 alpha - 1) /
    (alpha + 1) bins.  Non-uniform timestamps are first interpolated onto a
    uniform grid of the same length (good enough for a start value).  Units are
    cycles per unit of ``t`` (Hz for seconds, cycles per sample for indices).
    """
    t, y = _as_inputs(t, y)
    n = y.size
    if n < 8:
        raise DataError(f"only {n} samples: a frequency estimate needs at least 8")
    dt = (t[-1] - t[0]) / (n - 1)
    grid = t[0] + dt * np.arange(n)
    uniform = np.interp(grid, t, y)
    spectrum = np.abs(np.fft.rfft((uniform - uniform.mean()) * np.hanning(n + 2)[1:-1]))
    if spectrum.size < 3:
        raise DataError(f"only {n} samples: too few for a spectrum")
    peak = int(np.argmax(spectrum[1:])) + 1
    left = spectrum[peak - 1]
    right = spectrum[peak + 1] if peak + 1 < spectrum.size else 0.0
    if spectrum[peak] <= 0:
        raise DataError("the signal is constant: there is no frequency to find")
    if right >= left:
        alpha = right / spectrum[peak]
        delta = (2 * alpha - 1) / (alpha + 1)
    else:
        alpha = left / spectrum[peak]
        delta = -(2 * alpha - 1) / (alpha + 1)
    delta = float(np.clip(delta, -0.5, 0.5))  # outside [-0.5, 0.5] a neighbour would be the peak
    return (peak + delta) / (n * dt)


def fit_sine(t, y, frequency: float | None = None, harmonics: int = 1, fit_frequency: bool = True,
             check_noise: bool = False) -> SineFit:
    """Fit offset + harmonics 1..H of one frequency to ``y`` sampled at ``t``.

    ``t`` may be timestamps (s, possibly non-uniform) or sample indices (then
    the frequency is in cycles per sample); ``None`` means sample indices.
    ``frequency`` is the start value (the interpolated DFT when ``None``) or,
    with ``fit_frequency=False``, the known frequency of a three-parameter fit.
    """
    t, y = _as_inputs(t, y)
    harmonics = _check_harmonics(harmonics)
    n_params = 2 * harmonics + 1 + (1 if fit_frequency else 0)
    min_samples = max(8, 3 * n_params)
    if y.size < min_samples:
        raise DataError(f"only {y.size} samples: a {n_params}-parameter sine fit needs at least {min_samples}")
    if frequency is None and not fit_frequency:
        raise DataError("a three-parameter sine fit needs the frequency", "pass frequency= or fit_frequency=True")
    start = interpolated_dft_frequency(t, y) if frequency is None else float(frequency)
    if not np.isfinite(start) or start <= 0:
        raise DataError(f"the frequency must be positive, got {start!r}")
    span = float(t[-1] - t[0])
    mean_dt = span / (y.size - 1)
    cycles = start * (span + mean_dt)
    if cycles < MIN_CYCLES:
        raise DataError(
            f"the record holds only {cycles:.2f} cycles at {start:.4g} cycles per unit time",
            f"a sine fit needs at least {MIN_CYCLES} cycles: record longer",
        )
    if harmonics * start >= 0.5 / mean_dt:
        raise DataError(
            f"harmonic {harmonics} of {start:.4g} lies above the Nyquist frequency {0.5 / mean_dt:.4g}",
            "fit fewer harmonics or sample faster",
        )

    t_ref = float(np.mean(t))
    tc = t - t_ref
    grid_step = _uniform_step(tc)
    n_iterations = 0
    converged = True
    estimate = start
    if fit_frequency:
        stages = [1, harmonics] if harmonics > 1 else [1]
        for stage_harmonics in stages:
            # the final stage stops far below any achievable uncertainty; an
            # earlier stage only has to hand a start well inside the basin, and
            # does so from every stride-th sample of a long record (still at
            # least STAGE_SAMPLES, and 5 samples per period of the top harmonic)
            final = stage_harmonics == harmonics
            tol = (1e-11 if final else 1e-4) / span
            stride = 1 if final else int(max(1, min(y.size // STAGE_SAMPLES,
                                                     0.2 / (harmonics * estimate * mean_dt))))
            estimate, iters, ok, last = _gauss_newton(tc[::stride], y[::stride], estimate, stage_harmonics, tol,
                                                      None if grid_step is None else grid_step * stride)
            n_iterations += iters
            converged = ok
        if estimate * harmonics >= 0.5 / mean_dt or estimate * (span + mean_dt) < 1.0:
            converged = False  # ran off to a frequency the record cannot support

    names = _internal_names(harmonics, fit_frequency)
    if fit_frequency:   # the last stage ran on every sample, at this frequency: its basis and fit are final
        phi, dc, coef, chol, resid = last
        # J = [dPhi c, Phi]: J'J from the pieces at hand (Phi'Phi = L L'), the tall J built only if needed
        cross = _t_times(phi, dc)
        normal = np.block([[np.array([[dc @ dc]]), cross[None, :]], [cross[:, None], chol @ chol.T]])

        def jacobian():
            return np.column_stack([dc, phi])
    else:
        phi, _ = _basis(tc, estimate, harmonics, derivative=False, step=grid_step)
        chol, coef, resid = _project(phi, y, None if grid_step is None
                                     else _uniform_gram(tc, grid_step, estimate, harmonics))
        normal = chol @ chol.T

        def jacobian():
            return phi
    dof = y.size - n_params
    sigma2 = float(resid @ resid) / dof
    # unit sigma then scaled: a noise-free record (sigma2 = 0) still gets its (zero) covariance
    cov_q = sigma2 * normal_covariance(normal, names)
    method, white_test = "white noise: sigma^2 (J'J)^-1", None
    if check_noise:
        white_test = whiteness(resid)
        if white_test.correlated:
            cov_q, method, white_test, _ = checked_covariance(jacobian(), resid, cov_q, white_test)
    amp, phase, cov, names = _to_reported(coef, estimate, t_ref, harmonics, fit_frequency, cov_q)
    sd = np.sqrt(np.clip(np.diag(cov), 0, None))
    nf = 1 if fit_frequency else 0
    return SineFit(
        frequency=float(estimate),
        frequency_uncertainty=float(sd[0]) if fit_frequency else 0.0,
        amplitude=amp,
        amplitude_uncertainty=sd[nf + 1::2].copy(),
        phase=phase,
        phase_uncertainty=sd[nf + 2::2].copy(),
        offset=float(coef[0]),
        offset_uncertainty=float(sd[nf]),
        covariance=cov,
        parameter_names=names,
        residual_sd=float(np.sqrt(sigma2)),
        residuals=resid,
        fitted=y - resid,
        n_iterations=n_iterations,
        converged=bool(converged),
        start_frequency=float(start),
        harmonics=harmonics,
        frequency_fitted=fit_frequency,
        covariance_method=method,
        whiteness=white_test,
    )


def fit_sines_known_frequency(t, signals, frequency: float, harmonics: int = 1,
                              check_noise=False) -> list[SineFit]:
    """Three-parameter fits (IEEE 1057, frequency known) of several signals sampled at the same ``t``.

    ``signals`` is (n, m): one fit per column, the same as ``fit_sine(t, column, frequency,
    harmonics, fit_frequency=False)`` each, with the design matrix and its factorisation made once.
    ``check_noise``: one bool for all columns, or one per column.
    """
    signals = np.asarray(signals, dtype=float)
    if signals.ndim != 2:
        raise DataError(f"fit_sines_known_frequency needs an (n, m) array of signals, got shape {signals.shape}")
    columns = [_as_inputs(t, signals[:, j])[1] for j in range(signals.shape[1])]
    t = _as_inputs(t, columns[0])[0]
    harmonics = _check_harmonics(harmonics)
    n_params = 2 * harmonics + 1
    if t.size < max(8, 3 * n_params):
        raise DataError(f"only {t.size} samples: a {n_params}-parameter sine fit needs at least {max(8, 3 * n_params)}")
    if not (np.isfinite(frequency) and frequency > 0):
        raise DataError(f"the frequency must be positive, got {frequency!r}")
    t_ref = float(np.mean(t))
    tc = t - t_ref
    grid_step = _uniform_step(tc)
    phi, _ = _basis(tc, frequency, harmonics, derivative=False, step=grid_step)
    chol = _gram_factor(phi, None if grid_step is None else _uniform_gram(tc, grid_step, frequency, harmonics))
    coefs = _solve_gram(chol, _t_times(phi, np.column_stack(columns)))
    names = _internal_names(harmonics, False)
    unit = normal_covariance(chol @ chol.T, names)
    checks = [bool(check_noise)] * len(columns) if np.ndim(check_noise) == 0 else [bool(c) for c in check_noise]
    fits = []
    for j, y in enumerate(columns):
        coef = coefs[:, j]
        resid = y - _times(phi, coef)
        sigma2 = float(resid @ resid) / (y.size - n_params)
        cov_q = sigma2 * unit
        method, white_test = "white noise: sigma^2 (J'J)^-1", None
        if checks[j]:
            cov_q, method, white_test, _ = checked_covariance(phi, resid, cov_q)
        amp, phase, cov, reported = _to_reported(coef, frequency, t_ref, harmonics, False, cov_q)
        sd = np.sqrt(np.clip(np.diag(cov), 0, None))
        fits.append(SineFit(
            frequency=float(frequency), frequency_uncertainty=0.0, amplitude=amp,
            amplitude_uncertainty=sd[1::2].copy(), phase=phase, phase_uncertainty=sd[2::2].copy(),
            offset=float(coef[0]), offset_uncertainty=float(sd[0]), covariance=cov, parameter_names=reported,
            residual_sd=float(np.sqrt(sigma2)), residuals=resid, fitted=y - resid, n_iterations=0, converged=True,
            start_frequency=float(frequency), harmonics=harmonics, frequency_fitted=False,
            covariance_method=method, whiteness=white_test,
        ))
    return fits


def sine_crb(t, frequency: float, amplitude, phase, sigma: float, offset: float = 0.0,
             fit_frequency: bool = True) -> SineCRB:
    """Exact Cramér-Rao bound for :func:`fit_sine`'s parameters at the true values.

    ``amplitude`` and ``phase`` are scalars or one value per harmonic; ``sigma``
    is the white-noise sd.  The bound is sigma^2 (J^T J)^-1 with J the model's
    Jacobian, mapped to the same parameters (and phase reference t = 0) as
    :class:`SineFit`.  ``extra["rife_boorstyn_frequency_sd"]`` holds the
    closed form for one sine on uniform samples, for comparison.
    """
    t = np.asarray(t, dtype=float)
    amp = np.atleast_1d(np.asarray(amplitude, dtype=float))
    ph = np.atleast_1d(np.asarray(phase, dtype=float))
    if amp.shape != ph.shape:
        raise DataError("sine_crb needs one phase per amplitude")
    harmonics = amp.size
    t_ref = float(np.mean(t))
    k = np.arange(1, harmonics + 1)
    phase_ref = ph + 2 * np.pi * k * frequency * t_ref
    coef = np.empty(2 * harmonics + 1)
    coef[0] = offset
    coef[1::2] = amp * np.cos(phase_ref)
    coef[2::2] = -amp * np.sin(phase_ref)
    tc = t - t_ref
    jac = _full_jacobian(tc, frequency, coef, harmonics, fit_frequency)
    cov_q = _covariance(jac, sigma**2, _internal_names(harmonics, fit_frequency))
    _, _, cov, names = _to_reported(coef, frequency, t_ref, harmonics, fit_frequency, cov_q)
    sd = np.sqrt(np.clip(np.diag(cov), 0, None))
    nf = 1 if fit_frequency else 0
    extra = {}
    if t.size > 1:
        fs = (t.size - 1) / (t[-1] - t[0])
        extra["rife_boorstyn_frequency_sd"] = rife_boorstyn_frequency_sd(amp[0], sigma, t.size, fs)
    return SineCRB(
        covariance=cov,
        parameter_names=names,
        frequency_sd=float(sd[0]) if fit_frequency else 0.0,
        amplitude_sd=sd[nf + 1::2].copy(),
        phase_sd=sd[nf + 2::2].copy(),
        offset_sd=float(sd[nf]),
        extra=extra,
    )


def rife_boorstyn_frequency_sd(amplitude: float, sigma: float, n: int, fs: float) -> float:
    """Closed-form CRB (sd) of a real tone's frequency: 12 fs^2 / ((2 pi)^2 eta N (N^2 - 1)), eta = A^2 / (2 sigma^2)."""
    eta = amplitude**2 / (2 * sigma**2)
    return float(np.sqrt(12 * fs**2 / ((2 * np.pi) ** 2 * eta * n * (n**2 - 1))))
