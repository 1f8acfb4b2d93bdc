"""The slider's motion with a speed that need not be constant: harmonics of the crank angle, differentiated.

At constant speed a step is a sine with harmonics (``fit_sine``).  A real
motor wanders (a slow ripple of 1-3 %, a drift over the record), and a sine
of one frequency then misses the phase by up to a radian: the first harmonic
shrinks, the radius comes out low with a tiny u, and a sound calibration
"does not hold".

The model here keeps the crank's geometry and lets the speed vary:

    x(t)  = sum_k a_k cos(k phi(t)) + b_k sin(k phi(t))      (the slider's position, any crank law)
    phi(t) = sum_j c_j T_j(tau)                             (crank angle, Chebyshev in tau in [-1, 1])
    y(t)  = x''(t) + offset
          = sum_k a_k (-k^2 phi'^2 cos k phi - k phi'' sin k phi)
                + b_k (-k^2 phi'^2 sin k phi + k phi'' cos k phi) + offset

Linear in (offset, a_k, b_k), nonlinear in the speed profile c_j; solved by
variable projection (the linear part exact for each trial c).  The crank
radius is the displacement's first harmonic hypot(a_1, b_1) directly (at
constant speed this is the usual A_1 / omega^2), and the step's speed is the
mean of phi' over the record.  The profile's order starts at 1 (constant
speed) and grows while an added term lowers the residual sum of squares
significantly (nested F test at ``ORDER_ALPHA``): a steady motor costs nothing,
a wandering one is followed and pays for it in u, through the full covariance.
The F test assumes white residuals; correlated noise would pass it with
spurious terms, so its statistic is divided by the residuals' integrated
autocorrelation time (estimation.residuals.whiteness): the effective number of
independent samples is n / tau.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.polynomial import chebyshev as cheb
from scipy import optimize
from scipy import stats as _sps

from accelrig.estimation.residuals import difference_noise_variance, lack_of_fit, whiteness

ORDER_ALPHA = 1e-3   # an added speed term must lower the RSS at this significance to be kept
# A jump over many orders at once (fit_crank_motion) must lower the RSS at this significance: a ripple the one-by-one
# search missed leaves residuals far above the noise (p ~ 0), and coloured noise, judged through its correlation
# time only, bought a jump at 1e-3 in 2 of 25 held-out runs under 1/f^0.5
JUMP_ALPHA = 1e-6
MAX_ORDER = 24       # highest Chebyshev order of the crank angle (about 7 wobble cycles per record)


@dataclass
class CrankMotionFit:
    order: int                  # Chebyshev order of phi(t); 1 = constant speed
    coefficients: np.ndarray    # c_1 .. c_order (c_0 is absorbed by the harmonics' phases)
    linear: np.ndarray          # offset, a_1, b_1, a_2, b_2, ...
    jacobian: np.ndarray        # of the model in (c, linear), (n, order + 1 + 2H)
    residuals: np.ndarray
    harmonics: int
    half_span: float
    rss_by_order: dict

    @property
    def n_parameters(self) -> int:
        return self.jacobian.shape[1]

    def speed(self, tau: np.ndarray) -> np.ndarray:
        """phi'(t) in rad/s at normalised times tau."""
        return cheb.chebval(tau, cheb.chebder(np.concatenate([[0.0], self.coefficients]))) / self.half_span

    def mean_frequency_gradient(self) -> tuple[float, np.ndarray]:
        """Mean crank rate over the record, Hz, (phi(1) - phi(-1)) / (2 pi 2 h), and its gradient in the parameters."""
        j = np.arange(1, self.order + 1)
        weights = (1.0 - (-1.0) ** j) / (4 * np.pi * self.half_span)   # T_j(1) - T_j(-1) = 1 - (-1)^j
        grad = np.zeros(self.n_parameters)
        grad[: self.order] = weights
        return float(weights @ self.coefficients), grad

    def radius_gradient(self) -> tuple[float, np.ndarray]:
        """First harmonic of the displacement, hypot(a_1, b_1), and its gradient."""
        a, b = self.linear[1], self.linear[2]
        r = float(np.hypot(a, b))
        grad = np.zeros(self.n_parameters)
        grad[self.order + 1] = a / r
        grad[self.order + 2] = b / r
        return r, grad


def _basis(tau: np.ndarray, coefficients: np.ndarray, h: float, harmonics: int):
    """Columns [1, C_1, S_1, ...]: the second time derivatives of cos k phi and sin k phi; and phi, phi', phi''."""
    c = np.concatenate([[0.0], coefficients])
    phi = cheb.chebval(tau, c)
    d1 = cheb.chebval(tau, cheb.chebder(c)) / h
    d2 = cheb.chebval(tau, cheb.chebder(c, 2)) / h**2 if coefficients.size > 1 else np.zeros_like(tau)
    cols = [np.ones_like(tau)]
    for k in range(1, harmonics + 1):
        ck, sk = np.cos(k * phi), np.sin(k * phi)
        cols.append(-(k * d1) ** 2 * ck - k * d2 * sk)
        cols.append(-(k * d1) ** 2 * sk + k * d2 * ck)
    return np.column_stack(cols), phi, d1, d2


def _project(tau, y, coefficients, h, harmonics):
    basis = _basis(tau, coefficients, h, harmonics)[0]
    coef = np.linalg.solve(basis.T @ basis, basis.T @ y)   # normal equations: few columns, no threaded LAPACK
    return coef, y - basis @ coef, basis


def _fit_order(tau, y, start, h, harmonics):
    def residual(c):
        return _project(tau, y, c, h, harmonics)[1]

    scale = np.maximum(np.abs(start), 1e-3)
    sol = optimize.least_squares(residual, start, method="lm", x_scale=scale, xtol=1e-12, ftol=1e-12, gtol=1e-12)
    return sol.x


def _jacobian(tau, coefficients, linear, h, harmonics, basis):
    """Model derivatives in (c_1..c_P) by central differences (few columns), then the basis (exact)."""
    cols = []
    for j in range(coefficients.size):
        step = 1e-6 * max(abs(coefficients[j]), 1.0)
        up, down = coefficients.copy(), coefficients.copy()
        up[j] += step
        down[j] -= step
        cols.append((_basis(tau, up, h, harmonics)[0] @ linear - _basis(tau, down, h, harmonics)[0] @ linear)
                    / (2 * step))
    return np.column_stack(cols + [basis])


def _select(rss: dict, n: int, harmonics: int, correlation: float, limit: int) -> int:
    """The order the nested F tests choose over the RSS of orders 1..: each step up (by one or, looking
    ahead, two orders) must lower the RSS at ORDER_ALPHA, with n / correlation independent samples."""
    order = 1
    while True:
        for extra in (1, 2):
            if order + extra not in rss or order + extra > limit:
                return order
            new = rss[order + extra]
            dof = (n - (order + extra + 1) - (2 * harmonics + 1)) / correlation
            if new < rss[order] and dof > 0:
                statistic = (rss[order] - new) / extra / (new / dof) / correlation
                if float(_sps.f.sf(statistic, extra, dof)) < ORDER_ALPHA:
                    order += extra
                    break
        else:
            return order


def _structured(resid: np.ndarray, y: np.ndarray, order: int, harmonics: int) -> bool:
    """The residuals hold more than white noise: correlated, or above the model-free noise (F test)."""
    if whiteness(resid).correlated:
        return True
    noise_var, noise_dof = difference_noise_variance(y, order=3)
    dof = resid.size - (order + 1) - (2 * harmonics + 1)
    return dof > 0 and lack_of_fit(float(resid @ resid) / dof, dof, noise_var, noise_dof).significant()


def _ripple_rate(coefficients: np.ndarray, h: float) -> float:
    """Rate of a speed profile's swings (half its sign changes about its mean per second), Hz."""
    speed = cheb.chebval(np.linspace(-1.0, 1.0, 201), cheb.chebder(np.concatenate([[0.0], coefficients])))
    swings = np.count_nonzero(np.diff(np.sign(speed - speed.mean())) != 0)
    return float(max(swings, 1) / (2 * 2 * h))


def _jump(rss: dict, n: int, harmonics: int, order: int, top: int, correlation: float) -> int:
    """``top`` when it lowers the RSS below ``order``'s significantly (F test at JUMP_ALPHA, with n / correlation
    independent samples as in _select), else ``order``."""
    dof = (n - (top + 1) - (2 * harmonics + 1)) / correlation
    if dof <= 0 or not rss[top] < rss[order]:
        return order
    statistic = (rss[order] - rss[top]) / (top - order) / (rss[top] / dof) / correlation
    return top if float(_sps.f.sf(statistic, top - order, dof)) < JUMP_ALPHA else order


def fit_crank_motion(t: np.ndarray, y: np.ndarray, frequency: float, harmonics: int,
                     max_order: int = MAX_ORDER) -> CrankMotionFit:
    """Fit the slider's acceleration ``y`` (along the axis, m/s^2) at times ``t`` (s), starting from ``frequency``.

    The order: first the white-noise F tests choose (a wandering speed leaves structured residuals
    that no correlation correction should excuse); the residuals at that order are then mostly the
    sensor's noise, and when they are correlated (a coloured sensor buys spurious terms from a white
    test) the choice is made again over the same fits with the tests' statistic divided by their
    integrated correlation time.
    """
    t = np.asarray(t, dtype=float)
    y = np.asarray(y, dtype=float)
    mid, h = 0.5 * (t[0] + t[-1]), 0.5 * (t[-1] - t[0])
    tau = (t - mid) / h
    n = y.size
    fits = {1: _fit_order(tau, y, np.array([2 * np.pi * frequency * h]), h, harmonics)}
    rss = {}

    def residual_of(order):
        resid = _project(tau, y, fits[order], h, harmonics)[1]
        rss[order] = float(resid @ resid)
        return resid

    residual_of(1)
    # keep about a hundred residual degrees of freedom per speed term: the profile follows the motor, not the noise
    limit = int(min(max_order, max(1, (n - 2 * harmonics - 1) // 100)))
    # The jump to a high order (below) stays below pi (cycles - 1): no speed term within a resolution bin (1 / record)
    # of the crank's rate or above (mid-record T_j swings as a sine of j / pi cycles over the record).  The angle
    # is seen through the harmonics' phase, and a ripple at or above the crank's rate puts its lower sideband
    # f - f_ripple onto the offset and its upper onto the next harmonic: jumped to order 24, a 5 Hz ripple
    # "wandered" by 26 % at 3 Hz.  (The one-by-one search keeps the whole limit: a 1-s step at 2.5 Hz with a
    # 1.3 Hz wobble needs order 6, above that bound.)
    cycles = frequency * (t[-1] - t[0])
    jump_to = int(max(1, min(limit, np.floor(np.pi * (cycles - 1)))))
    order = 1
    while True:
        top = max(fits)
        for extra in (1, 2):   # the fits the next white test needs (two ahead: a wobble's odd part alone may not help)
            if order + extra <= limit and order + extra not in fits:
                previous = fits[order + extra - 1] if order + extra - 1 in fits else fits[top]
                fits[order + extra] = _fit_order(tau, y, np.concatenate([previous, [0.0]]), h, harmonics)
                residual_of(order + extra)
        chosen = _select(rss, n, harmonics, 1.0, limit)
        if chosen == order and jump_to > order + 2 and jump_to not in fits and _structured(residual_of(order), y, order,
                                                                                           harmonics):
            # A speed ripple of several cycles per record (a 5 Hz wobble: six in 1.25 s) needs a dozen
            # terms before any one of them helps: one or two more lower the RSS by nothing significant, and
            # the search stopped at constant speed, leaving the ripple's sidebands (at k f +- the ripple's
            # rate) in the residuals.  So when they are correlated or exceed the noise, the highest order is
            # tried too, against the one chosen (residuals at the noise: nothing is left to follow, and the fit
            # is not paid for).
            fits[jump_to] = _fit_order(tau, y, np.concatenate([fits[order], np.zeros(jump_to - order)]), h, harmonics)
            residual_of(jump_to)
            chosen = _jump(rss, n, harmonics, order, jump_to, 1.0)
            if chosen == jump_to:
                order = jump_to
                break
        if chosen == order:
            break
        order = chosen
    correlation = max(whiteness(residual_of(order)).tau, 1.0)
    if correlation > 1.0:
        chosen = _select(rss, n, harmonics, correlation, order)
        order = _jump(rss, n, harmonics, chosen, order, correlation) if order == jump_to > chosen else chosen
    if order > 1 and _ripple_rate(fits[order], h) >= frequency - 1.0 / (2 * h):
        # the profile swings at or above the crank's rate less a resolution bin: what it follows cannot be told
        # from the harmonics (a 5 Hz ripple at a 4.5 Hz step, followed to order 19, left the radius 5-7 u off);
        # the step is taken at constant speed, and what the ripple leaves is budgeted from the steps that
        # followed it (analysis.budget_unfollowed_ripple)
        order = 1
    coefficients = fits[order]
    linear, resid, basis = _project(tau, y, coefficients, h, harmonics)
    jac = _jacobian(tau, coefficients, linear, h, harmonics, basis)
    return CrankMotionFit(order, coefficients, linear, jac, resid, harmonics, h, rss)
