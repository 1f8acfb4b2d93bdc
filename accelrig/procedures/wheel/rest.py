"""The wheel at rest, before the push and after the stop: does it read what the coast's fit predicts?

A drift of the offsets that grows or settles like w^2 during the coast is, within about 20 degrees of the
wheel's plane, the centripetal term scaled and turned by the mounting about the axle: the coast alone cannot
tell them apart, and the fit takes such a drift into the gains, the tilt and the mounting, and its offset
``a`` is the drift extrapolated to w = 0 (docs/wheel.md, "Offset drift").  At rest there is no centripetal
or tangential term: the sensor reads its offset plus gravity at the resting angle,

    v_rest = o + Gamma R (g sin(alpha) cos(phi), g sin(alpha) sin(phi), g cos(alpha)),

exact physics with one unknown, the resting angle phi.  The wizard's record starts with the wheel at rest
("spin the wheel by hand after holding it still for 5 s, then let it coast; keep the
recording running"), and may end with it at rest after
it stopped, so the rest's mean, set against the fit's prediction at the best resting angle, tests the offsets
the fit found along the two directions the angle does not absorb (a chi^2 test at ALPHA, 2 degrees
of freedom per rest, the fit's own covariance and the rest's noise in its variance).

Found, the result warns with the size, and u includes the bias a drift that size would make: a w^2-shaped
drift along the wheel's plane that reads the rest's miss at w = 0 (the largest miss over the mean w^2 of the
coast), in any direction within the plane (the rest cannot say which: its angle absorbs one), carried through
the fit's own normal equations.  Whether the offset moved between the rest and the coast (u then grows for
nothing) or during the coast into the gains (u then covers it), the data cannot say.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import special

from accelrig.estimation.crb import numerical_jacobian
from accelrig.estimation.distributions import chi2
from accelrig.estimation.residuals import ALPHA
from accelrig.procedures.wheel.fit import chunks
from accelrig.procedures.wheel.model import FreeSet, WheelState, model_and_jacobian, pack, phase, unpack
from accelrig.units import STANDARD_GRAVITY

ANGLE_GRID = 720          # the resting angle's first look, then refined by Newton steps


@dataclass
class Rest:
    """A stretch of the recording with the wheel still: where (``before the spin``, ``after the stop``), its
    times in the recording and its samples."""

    where: str
    t: np.ndarray
    v: np.ndarray


@dataclass
class RestCheck:
    rests: list[dict]                  # per rest: where, from/to s, samples, resting angle, what it read off
    statistic: float
    dof: int
    p_value: float
    allowance: np.ndarray              # covariance of the bias a drift that size would make (internal parameters;
    drift: float                       # zero when not significant) and the drift's size, m/s^2 over the coast

    @property
    def significant(self) -> bool:
        return self.p_value < ALPHA

    def to_dict(self) -> dict:
        return {"rests": self.rests, "statistic": self.statistic, "dof": self.dof, "p_value": self.p_value,
                "significant": self.significant}


def _at_rest(state: WheelState, angle: float, g: float) -> np.ndarray:
    """What the sensor reads at rest at wheel angle ``angle`` (eq. 1 and 6 with w = w' = 0)."""
    ga = g * np.sin(state.tilt)
    a = np.array([ga * np.cos(angle), ga * np.sin(angle), g * np.cos(state.tilt)])
    return state.offset + state.gain * (state.rotation @ a)


def _resting_angle(mean: np.ndarray, state: WheelState, weight: np.ndarray, g: float) -> float:
    """The wheel angle whose prediction is nearest the rest's mean (weighted)."""
    grid = np.linspace(0.0, 2 * np.pi, ANGLE_GRID, endpoint=False)
    ga = g * np.sin(state.tilt)
    response = state.gain[:, None] * state.rotation
    base = state.offset + response[:, 2] * g * np.cos(state.tilt)
    cols = response[:, :2] * ga

    def miss(phi):
        return (mean - base)[None, :] - np.stack([np.cos(phi), np.sin(phi)], axis=-1) @ cols.T

    angle = float(grid[np.argmin(np.sum((miss(grid) * weight) ** 2, axis=1))])
    for _ in range(5):                        # Newton on the weighted sum of squares
        r = miss(np.array([angle]))[0] * weight
        d1 = -(cols @ np.array([-np.sin(angle), np.cos(angle)])) * weight
        d2 = -(cols @ np.array([-np.cos(angle), -np.sin(angle)])) * weight
        grad, hess = 2 * r @ d1, 2 * (d1 @ d1 + r @ d2)
        if hess <= 0:
            break
        angle -= grad / hess
    return angle


def check_rests(rests: list[Rest], t: np.ndarray, state: WheelState,
                cov_internal: np.ndarray, free: FreeSet, time_scale: float, sigma: np.ndarray, tau: np.ndarray,
                g: float = STANDARD_GRAVITY) -> RestCheck | None:
    """Test the fit (``state``, its covariance ``cov_internal`` over the internal parameters of ``pack``) against
    the rests' means, and find the move the rests would make.  ``t`` is the coast's times; ``sigma``
    each axis' noise sd of the fit, ``tau`` its integrated correlation time in samples (1 when white): the
    variance of a rest's mean is the larger of that noise and the rest's own scatter, times tau, over its
    samples.  None when there is no rest."""
    if not rests:
        return None
    x0 = pack(state, free, time_scale)
    p = x0.size
    k = len(rests)
    miss = np.zeros(3 * k)
    jac_x = np.zeros((3 * k, p))
    jac_angle = np.zeros((3 * k, k))
    noise = np.zeros(3 * k)
    found = []
    for i, rest in enumerate(rests):
        mean = rest.v.mean(axis=0)
        spread = np.maximum(sigma, rest.v.std(axis=0, ddof=1))
        var = spread**2 * np.maximum(tau, 1.0) / rest.v.shape[0]
        angle = _resting_angle(mean, state, 1.0 / np.sqrt(var), g)
        rows = slice(3 * i, 3 * i + 3)
        miss[rows] = mean - _at_rest(state, angle, g)
        noise[rows] = var
        jac_x[rows] = numerical_jacobian(lambda x, a=angle: _at_rest(unpack(x, free, time_scale, state), a, g), x0)
        jac_angle[rows, i] = numerical_jacobian(lambda a: _at_rest(state, a[0], g), np.array([angle]))[:, 0]
        found.append({"where": rest.where, "from_s": float(rest.t[0]), "to_s": float(rest.t[-1]),
                      "samples": int(rest.v.shape[0]), "resting_angle_deg": float(np.degrees(angle) % 360.0),
                      "read_off_m_s2": miss[rows].tolist()})
    # the rests' misses against the fit: their own noise and the fit's uncertainty at rest, the resting angles
    # free (projected out)
    total = jac_x @ cov_internal @ jac_x.T + np.diag(noise)
    inv = np.linalg.inv(total)
    angle_info = jac_angle.T @ inv @ jac_angle
    project = inv - inv @ jac_angle @ np.linalg.solve(angle_info, jac_angle.T @ inv)
    statistic = float(miss @ project @ miss)
    dof = 2 * k
    p_value = float(chi2.sf(statistic, dof))
    allowance, drift = np.zeros((p, p)), 0.0
    if p_value < ALPHA:     # only then is u widened: the pass over the coast is spared otherwise
        allowance, drift = _allowance(miss, t, state, free, time_scale, sigma, g)
    return RestCheck(found, statistic, dof, p_value, allowance, drift)


def _allowance(miss: np.ndarray, t: np.ndarray, state: WheelState, free: FreeSet, time_scale: float,
               sigma: np.ndarray, g: float) -> tuple[np.ndarray, float]:
    """The covariance (internal parameters) of the estimates' bias by a drift the rests show, and its size.

    A drift of the offsets shaped like w^2 along the wheel's plane, b (w^2 - mean w^2), is what the coast takes for
    the centripetal term; at rest (w = 0) it reads -b mean(w^2) off the coast's mean offset.  The largest miss of a
    rest sets the size the drift needs to explain it, |b| = |miss| / mean(w^2); its direction within the plane the
    rests cannot give (the resting angle absorbs one in-plane direction), so it is taken as any, evenly:
    E[b b^T] = |b|^2 / 2 on the plane.  The fit's bias by a drift D b is (J^T W J)^-1 J^T W D b."""
    p = free.size
    weight = 1.0 / sigma**2
    rate_sq = phase(t, state.theta0, state.omega)[1] ** 2
    mean_sq = float(rate_sq.mean())
    centred = rate_sq - mean_sq
    response = state.gain[:, None] * state.rotation             # Gamma R: bench -> sensor
    plane = np.linalg.qr(response[:, :2])[0]                     # the wheel's plane in the sensor frame, orthonormal
    normal = np.zeros((p, p))
    cross = np.zeros((p, 2))
    for part in chunks(t.size):
        _, jac = model_and_jacobian(t[part], state, free, time_scale, g)
        weighted = jac * weight[None, :, None]
        normal += np.einsum("nki,nkj->ij", weighted, jac)
        cross += np.einsum("nki,kd,n->id", weighted, plane, centred[part])
    per_unit = np.linalg.solve(normal, cross)                    # bias per unit b along each in-plane direction
    size = float(np.max(np.linalg.norm(miss.reshape(-1, 3), axis=1))) / mean_sq
    return size**2 / 2.0 * per_unit @ per_unit.T, size * mean_sq


# Without a rest, what a drift along the wheel's plane could be and go unseen: the drift tests (assumptions.py, a
# line per axis, then Legendre degrees 2-3 in time beyond it, each at ALPHA) with the model projected out, at this
# power.  A drift shaped exactly like w^2 is missed at any size; these shapes are not w^2, so each has a size the
# tests find half the time.
UNSEEN_POWER = 0.5
UNSEEN_SHAPES = {
    "steady": ("steady over the coast (a line)", lambda x: x),
    "settling": ("settling with a time constant of a quarter of the coast (a warm-up)",
                 lambda x: -np.expm1(-4.0 * x) / -np.expm1(-4.0)),
}
JUDGED = ("gain_x", "gain_y", "gain_z", "offset_x", "offset_y", "offset_z", "tilt")


def _noncentrality_for_power(dof: int) -> float:
    """The noncentrality at which a chi^2 test of ``dof`` degrees of freedom at ALPHA rejects with UNSEEN_POWER."""
    return float(special.chndtrinc(special.chdtri(dof, ALPHA), dof, 1.0 - UNSEEN_POWER))


def unseen_drift(t: np.ndarray, state: WheelState, cov_internal: np.ndarray, free: FreeSet, time_scale: float,
                 sigma: np.ndarray, g: float = STANDARD_GRAVITY) -> dict:
    """The detection limit of a drift along the wheel's plane on a coast with no rest to check it: for each of
    UNSEEN_SHAPES, the size (m/s^2 over the coast) the drift tests find with UNSEEN_POWER, in the worse of two
    in-plane directions, and how far a drift that size moves the estimates (largest |bias| / u over gains,
    offsets and tilt, at the white noise ``sigma``; a correlated noise raises the limit).  Stated, not added to
    u: on a coast-down of 9 to 5 rad/s the limits are 0.05-0.2 m/s^2 steady and about 0.02 settling, moving the
    gains by 5 to 40 u (docs/wheel.md)."""
    p = free.size
    weight = 1.0 / sigma
    x = t / max(float(t[-1]), 1e-12)
    legendre = 2.0 * t / time_scale - 1.0
    response = state.gain[:, None] * state.rotation
    plane = np.linalg.qr(response[:, :2])[0]
    shapes = list(UNSEEN_SHAPES)
    q = 9 + 2 * len(shapes)
    normal = np.zeros((p + q, p + q))
    for part in chunks(t.size):
        _, jac = model_and_jacobian(t[part], state, free, time_scale, g)
        added = np.zeros((jac.shape[0], 3, q))
        for d in range(3):
            shape = np.polynomial.legendre.legval(legendre[part], [0] * (d + 1) + [1])
            for k in range(3):
                added[:, k, 3 * d + k] = shape
        for j, name in enumerate(shapes):
            shape = UNSEEN_SHAPES[name][1](x[part])
            for e in range(2):
                added[:, :, 9 + 2 * j + e] = shape[:, None] * plane[:, e][None, :]
        columns = np.concatenate([jac, added], axis=2) * weight[None, :, None]
        normal += np.einsum("nki,nkj->ij", columns, columns)
    a, b = normal[:p, :p], normal[:p, p:]
    a_inv = np.linalg.inv(a)
    schur = normal[p:, p:] - b.T @ a_inv @ b          # every added column with the model projected out
    line, bend = list(range(3)), list(range(3, 9))
    to_line = np.linalg.solve(schur[np.ix_(line, line)], schur[np.ix_(line, bend)])
    bend_given_line = schur[np.ix_(bend, bend)] - schur[np.ix_(bend, line)] @ to_line
    need_line, need_bend = _noncentrality_for_power(3), _noncentrality_for_power(6)
    judged = [free.names.index(n) for n in JUDGED if n in free.names]
    u = np.sqrt(np.diag(cov_internal))
    out = {}
    for j, name in enumerate(shapes):
        sizes, moves = [], []
        for e in range(2):                              # two directions within the plane, each on its own
            c = 9 + 2 * j + e
            g_line = schur[line, c]
            g_bend = schur[bend, c] - to_line.T @ g_line
            # the test that sees this drift better sets the limit
            per_unit = max(g_line @ np.linalg.solve(schur[np.ix_(line, line)], g_line) / need_line,
                           g_bend @ np.linalg.solve(bend_given_line, g_bend) / need_bend)
            size = float(np.sqrt(1.0 / per_unit)) if per_unit > 0 else float("inf")
            sizes.append(size)
            moves.append(np.abs(a_inv @ b[:, c])[judged] * size / u[judged])
        move = np.max(moves, axis=0)
        k = int(np.argmax(move))
        out[name] = {"shape": UNSEEN_SHAPES[name][0], "size_m_s2": max(sizes),
                     "largest_move_over_u": float(move[k]), "moves_most": free.names[judged[k]]}
    return out
