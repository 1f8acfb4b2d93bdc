"""Tilted-wheel dynamic calibration (paper 002, Pedersini), at the Cramer-Rao bound.

    calibrate_wheel(recording, radius=0.28)              joint maximum likelihood (default)
    calibrate_wheel(recording, radius=0.28, method="paper")   the paper's four steps
    plan_wheel(radius, tilt_deg, noise, rate, seconds, speed) predicted uncertainties (CRB)
    WheelProcedure(radius=0.28).feed(t, raw) -> events; .speed_trace(); .result()   for the TUI

The joint method starts from the four steps and fits all free parameters of
eq. 6-7 together (Levenberg-Marquardt with the analytic Jacobian of
wheel_model), weighting each axis by its own noise sd.  Its covariance is
(J^T W J)^-1 at the estimate: the CRB, which an efficient estimator reaches.
The four sequential steps each ignore information the others hold; their
uncertainties come from a parametric bootstrap of the same four steps.

The null space of section II-C couples r, alpha, Gamma and o_z: the radius or
the tilt must be given (both may be).  With neither the calibration refuses.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from accelrig.errors import CalibrationError, DataError
from accelrig.estimation.crb import crb_covariance
from accelrig.result import CalibrationResult, Correction, Estimate
from accelrig.procedures.wheel_checks import (
    MIN_TURNS, WheelSurvey, check_capture, survey, timestamp_figures, turn_speeds,
)
from accelrig.procedures.wheel_model import (
    TABLE_I_OMEGA, TABLE_I_THETA0_DEG, FreeSet, WheelState, euler_jacobian, model_and_jacobian, pack, phase,
    predict, rotation_from_euler, unpack,
)
from accelrig.procedures.wheel_paper import PaperSteps, paper_calibrate
from accelrig.recording import Recording
from accelrig.units import STANDARD_GRAVITY

METHODS = ("joint", "paper")
MODEL = "v = o + diag(gain) R a(t); Pedersini eq. 1-7, cubic angular velocity"
DEFAULT_BOOTSTRAP = 20
# A gain known worse than this (relative, k = 1) earns a warning about the mounting.
POOR_GAIN = 5e-3
# The speed trace is shown from this many turns on: before, the circle gravity draws is seen
# too little for its centre (the detrended centripetal term) to be placed, and the turn
# speeds are off by 7-20 % on the simulator (a few percent after three turns, 0.2 % at thirty).
TRACE_MIN_TURNS = 3.0
# The wheel cannot observe the sensor's own cross-axis sensitivity: a skew of its axes is absorbed
# by the mounting rotation R (eq. 1-7 carry only diag(gain) R).  The correction keeps C off-diagonal
# at 0 but with this prior sd: the MPU-9250 and ICM-20948 datasheets bound cross-axis sensitivity by
# +-2 %, read as a uniform distribution (sd = 0.02 / sqrt(3)).
DEFAULT_CROSS_AXIS_SD = 0.02 / np.sqrt(3)
MOUNTING_HINT = ("mount the sensor tilted on the wheel, so that every axis sees both the radial and the "
                 "tangential direction, as the paper does with some 20-30 degrees about each axis")

# Reported parameters (SI), in covariance order; "geometry" is tilt or radius, whichever is free.
MOTION_NAMES = ["theta0", "omega0", "omega1", "omega2", "omega3"]
ROTATION_NAMES = ["misalignment_theta", "misalignment_phi", "misalignment_psi"]
SENSOR_NAMES = ["gain_x", "gain_y", "gain_z", "offset_x", "offset_y", "offset_z"]


def reported_names(free: FreeSet) -> list[str]:
    geo = (["tilt"] if free.tilt_free else []) + (["radius"] if free.radius_free else [])
    return MOTION_NAMES + geo + ROTATION_NAMES + SENSOR_NAMES


def free_set(radius: float | None, tilt: float | None) -> FreeSet:
    """Which of r, alpha is estimated; refuse when neither is known (the null space of II-C)."""
    if radius is None and tilt is None:
        raise CalibrationError(
            "the wheel needs the radius or the tilt: with both unknown, r, the tilt, the gains and "
            "the z offset trade off against each other and the data cannot tell them apart",
            "measure the distance from the sensor to the wheel axis and give --radius METRES (or --tilt-deg)",
        )
    if radius is not None and not radius > 0:
        raise DataError(f"radius {radius} m must be positive")
    if tilt is not None and not 0 < tilt < np.pi / 2:
        raise DataError(f"tilt {np.rad2deg(tilt):g} deg must lie strictly between 0 and 90 degrees")
    return FreeSet(radius_free=radius is None, tilt_free=tilt is None)


# ------------------------------------------------------------------------- the fit


@dataclass
class JointFit:
    state: WheelState
    covariance: np.ndarray          # reported parameters, SI
    names: list[str]
    sigma: np.ndarray               # noise sd per axis
    residuals: np.ndarray           # (n, 3), m/s^2
    iterations: int


def _weighted(t, v, state, free, time_scale, g, weight):
    model, jac = model_and_jacobian(t, state, free, time_scale, g)
    res = ((v - model) * weight).ravel()
    jw = (jac * weight[None, :, None]).reshape(-1, free.size)
    return res, jw


def _levenberg_marquardt(t, v, state, free, time_scale, g, weight, max_iter=60):
    """Minimise the weighted misfit; the rotation is re-centred each step (increment about R)."""
    res, jw = _weighted(t, v, state, free, time_scale, g, weight)
    cost = float(res @ res)
    lam = 1e-4
    iterations = 0
    for iterations in range(1, max_iter + 1):
        a = jw.T @ jw
        grad = jw.T @ res
        d = np.sqrt(np.diag(a))
        d[d == 0] = 1.0
        scaled = a / np.outer(d, d)
        improved = False
        while lam < 1e12:
            step = np.linalg.solve(scaled + lam * np.eye(free.size), grad / d) / d
            trial = unpack(pack(state, free, time_scale) + step, free, time_scale, state)
            res_t, jw_t = _weighted(t, v, trial, free, time_scale, g, weight)
            cost_t = float(res_t @ res_t)
            if cost_t <= cost:
                improved = True
                break
            lam *= 10
        if not improved:
            break
        decrease = cost - cost_t
        state, res, jw, cost = trial, res_t, jw_t, cost_t
        lam = max(lam / 10, 1e-12)
        if decrease <= 1e-12 * cost and np.max(np.abs(step * d)) < 1e-6:
            break
    return state, jw, res, iterations


def _reporting_map(state: WheelState, free: FreeSet, time_scale: float) -> np.ndarray:
    """d(reported)/d(internal): c_k -> w_k = c_k / T^k, rotation increment -> Euler angles."""
    p = free.size
    m = np.eye(p)
    for k in range(4):
        m[1 + k, 1 + k] = time_scale ** -k
    rs = free.rotation_slice
    m[rs, rs] = euler_jacobian(state.rotation)
    return m


def joint_fit(t: np.ndarray, v: np.ndarray, start: WheelState, free: FreeSet,
              g: float = STANDARD_GRAVITY) -> JointFit:
    """Maximum likelihood of all free parameters from ``start``; per-axis noise estimated."""
    time_scale = max(float(t[-1]), 1e-6)
    weight = np.ones(3)
    state, jw, res, it1 = _levenberg_marquardt(t, v, start, free, time_scale, g, weight)
    # per-axis noise sd from the residuals, then the weighted (ML) refinement
    resid = res.reshape(-1, 3) / weight
    dof = resid.size - free.size
    sigma = np.sqrt(np.sum(resid**2, axis=0) / (dof / 3))
    weight = 1.0 / sigma
    state, jw, res, it2 = _levenberg_marquardt(t, v, state, free, time_scale, g, weight)
    try:
        state = state.canonical()
    except ValueError:
        raise CalibrationError("the joint fit ended at gains of mixed sign",
                               "the data do not look like a tilted wheel; check the recording") from None
    res, jw = _weighted(t, v, state, free, time_scale, g, weight)
    try:
        cov_internal = crb_covariance(jw, 1.0, free.names)
    except CalibrationError as exc:
        raise CalibrationError(exc.message, MOUNTING_HINT) from None
    m = _reporting_map(state, free, time_scale)
    return JointFit(state, m @ cov_internal @ m.T, reported_names(free), sigma,
                    res.reshape(-1, 3) / weight, it1 + it2)


def wheel_crb(t: np.ndarray, truth: WheelState, free: FreeSet, sigma, g: float = STANDARD_GRAVITY) -> np.ndarray:
    """CRB (covariance of the reported parameters, SI) for white noise of sd ``sigma``
    (scalar or per axis) at the parameters ``truth``."""
    time_scale = max(float(t[-1]), 1e-6)
    weight = 1.0 / np.broadcast_to(np.asarray(sigma, dtype=float), (3,))
    _, jac = model_and_jacobian(t, truth, free, time_scale, g)
    jw = (jac * weight[None, :, None]).reshape(-1, free.size)
    m = _reporting_map(truth, free, time_scale)
    return m @ crb_covariance(jw, 1.0, free.names) @ m.T


def reported_values(state: WheelState, free: FreeSet) -> np.ndarray:
    geo = ([state.tilt] if free.tilt_free else []) + ([state.radius] if free.radius_free else [])
    return np.concatenate([[state.theta0], state.omega, geo, state.euler, state.gain, state.offset])


# --------------------------------------------------------------------- the procedure


def _prepare(recording: Recording, g: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rec = recording.to_si()  # unit g is standard g: the canonical raw is counts x nominal scale
    t = rec.t - rec.t[0]
    v = rec.acc
    period, _, _, _ = timestamp_figures(t)
    gap_times = t[1:][np.diff(t) > 1.5 * period]
    return t, v, gap_times


def calibrate_wheel(
    recording: Recording,
    radius: float | None = None,
    tilt_deg: float | None = None,
    method: str = "joint",
    g: float = STANDARD_GRAVITY,
    bootstrap: int = DEFAULT_BOOTSTRAP,
    seed: int = 0,
    cross_axis_sd: float = DEFAULT_CROSS_AXIS_SD,
) -> CalibrationResult:
    """Calibrate from a wheel recording.  ``radius`` in m and/or ``tilt_deg`` must be given.

    ``cross_axis_sd`` is the prior sd given to the off-diagonal terms of the correction matrix,
    which the wheel does not observe (they are set to 0 with that uncertainty)."""
    if method not in METHODS:
        raise DataError(f"unknown method {method!r}", f"use one of: {', '.join(METHODS)}")
    if not (np.isfinite(cross_axis_sd) and cross_axis_sd > 0):
        raise DataError(f"cross-axis sd {cross_axis_sd} must be positive",
                        "give the datasheet cross-axis sensitivity as an sd, e.g. 0.0115 for +-2 % uniform")
    tilt = None if tilt_deg is None else float(np.deg2rad(tilt_deg))
    free = free_set(radius, tilt)
    t, v, gap_times = _prepare(recording, g)
    look = survey(t, v, recording.meta, g)
    warnings = check_capture(look, radius, g)
    started = time.perf_counter()
    steps = paper_calibrate(t, v, look, radius, tilt, g, gap_times)
    if method == "joint":
        fit = joint_fit(t, v, steps.state, free, g)
        state, cov, sigma, resid = fit.state, fit.covariance, fit.sigma, fit.residuals
        quality = {"iterations": fit.iterations}
        uncertainty_source = "covariance of the joint maximum-likelihood fit ((J^T W J)^-1, the CRB at the estimate)"
    else:
        state = steps.state
        resid = v - predict(t, state, g)
        sigma = np.sqrt(np.mean(resid**2, axis=0))
        cov = _paper_bootstrap(t, state, free, sigma, look, radius, tilt, g, gap_times, bootstrap, seed)
        crb = wheel_crb(t, state, free, sigma, g)
        quality = {"bootstrap_runs": bootstrap,
                   "sd_over_crb": dict(zip(reported_names(free), np.sqrt(np.diag(cov) / np.diag(crb))))}
        uncertainty_source = f"parametric bootstrap of the four steps ({bootstrap} runs)"
    elapsed = time.perf_counter() - started
    names = reported_names(free)
    for axis in "xyz":
        u_gain = np.sqrt(cov[names.index(f"gain_{axis}"), names.index(f"gain_{axis}")])
        if u_gain > POOR_GAIN * state.gain["xyz".index(axis)]:
            warnings.append(f"gain_{axis} is poorly determined (u = {u_gain:.2g}): the mounting hides it; "
                            + MOUNTING_HINT)
    assumed = ("the datasheet +-2 % cross-axis sensitivity as a uniform bound"
               if cross_axis_sd == DEFAULT_CROSS_AXIS_SD else "given with --cross-axis-sd")
    warnings.append(
        "the wheel does not observe cross-axis terms (the sensor's own axis misalignment is absorbed in the "
        f"mounting rotation): the correction's off-diagonal entries are set to 0 with an assumed prior sd of "
        f"{cross_axis_sd:.3g} ({assumed}); a static calibration measures them")
    return _build_result(method, state, cov, free, sigma, resid, t, steps, look, warnings, quality,
                         elapsed, radius, tilt, g, uncertainty_source, cross_axis_sd)


def _paper_bootstrap(t, state, free, sigma, look, radius, tilt, g, gap_times, runs, seed) -> np.ndarray:
    """Covariance of the four-step estimator: rerun it on data simulated from its own estimate."""
    if runs < 5:
        raise DataError(f"--bootstrap {runs}: the paper method needs at least 5 runs for its uncertainties")
    rng = np.random.default_rng(seed)
    clean = predict(t, state, g)
    names = reported_names(free)
    draws = np.empty((runs, len(names)))
    for i in range(runs):
        noisy = clean + rng.standard_normal(clean.shape) * sigma
        est = paper_calibrate(t, noisy, look, radius, tilt, g, gap_times).state
        draws[i] = reported_values(est, free)
    centre = reported_values(state, free)
    diff = draws - centre
    angles = [0] + [i for i, n in enumerate(names) if n.startswith("misalignment")]
    diff[:, angles] = np.angle(np.exp(1j * diff[:, angles]))   # wrap angle differences
    diff -= diff.mean(axis=0)
    return diff.T @ diff / (runs - 1)


def _build_result(method, state, cov, free, sigma, resid, t, steps: PaperSteps, look: WheelSurvey,
                  warnings, quality, elapsed, radius, tilt, g, uncertainty_source,
                  cross_axis_sd) -> CalibrationResult:
    names = reported_names(free)
    sd = np.sqrt(np.clip(np.diag(cov), 0, None))
    idx = {n: i for i, n in enumerate(names)}

    def est(name, value, unit, factor=1.0):
        return Estimate(float(value) * factor, float(sd[idx[name]]) * factor, unit)

    gi = [idx["gain_x"], idx["gain_y"], idx["gain_z"]]
    oi = [idx["offset_x"], idx["offset_y"], idx["offset_z"]]
    mi = [idx[n] for n in ROTATION_NAMES]
    params: dict[str, Estimate] = {}
    params["gain"] = Estimate(state.gain.tolist(), sd[gi].tolist(), "1")
    params["offset"] = Estimate(state.offset.tolist(), sd[oi].tolist(), "m/s^2")
    if free.tilt_free:
        params["tilt_deg"] = est("tilt", state.tilt, "deg", np.rad2deg(1.0))
    if free.radius_free:
        params["radius"] = est("radius", state.radius, "m")
    params["misalignment_deg"] = Estimate(np.rad2deg(state.euler).tolist(), np.rad2deg(sd[mi]).tolist(), "deg")
    params["theta0_deg"] = est("theta0", state.theta0, "deg", np.rad2deg(1.0))
    units = ["rad/s", "rad/s^2", "rad/s^3", "rad/s^4"]
    for k in range(4):
        params[f"omega{k}"] = est(f"omega{k}", state.omega[k], units[k])

    # canonical correction of the sensor: C = Gamma^-1, b = o (DESIGN.md)
    jac = np.zeros((12, len(names)))
    for k in range(3):
        jac[4 * k, gi[k]] = -1.0 / state.gain[k] ** 2
        jac[9 + k, oi[k]] = 1.0
    correction_cov = jac @ cov @ jac.T
    # the unobserved off-diagonal terms of C: the prior, independent of everything fitted
    off_diagonal = [i for i in range(9) if i % 4 != 0]
    correction_cov[off_diagonal, off_diagonal] = cross_axis_sd**2
    correction = Correction(np.diag(1.0 / state.gain), state.offset.copy(), correction_cov)

    # the paper's Fig. 3: speeds of half turns against the fitted cubic
    speed_fit = phase(steps.speed_time, state.theta0, state.omega)[1]
    speed_resid = steps.speed_samples - np.abs(speed_fit)
    quality = dict(quality)
    quality.update({
        "residual_rms": float(np.sqrt(np.mean(resid**2))),
        "noise_sd": sigma.tolist(),
        "n_samples": int(t.size),
        "duration_s": float(t[-1]),
        "turns": float(abs(phase(t[-1:], 0.0, state.omega)[0][0]) / (2 * np.pi)),
        "speed_residual_sd": float(np.std(speed_resid, ddof=4)) if speed_resid.size > 4 else None,
        "time_s": elapsed,
        "uncertainty": uncertainty_source,
    })
    settings = {
        "rig": {"name": "wheel", "radius": float(state.radius), "radius_given": radius is not None,
                "tilt_deg": float(np.rad2deg(state.tilt)), "tilt_given": tilt is not None},
        "g": g, "euler_convention": "R = Rz(psi) Ry(phi) Rx(theta), bench -> sensor",
        "time_origin": "first sample",
        "cross_axis_sd": float(cross_axis_sd),
    }
    arrays = {
        "t": t, "residuals": resid,
        "speed_time": steps.speed_time, "speed_samples": steps.speed_samples,
        "speed_fit": np.abs(speed_fit), "speed_residuals": speed_resid,
    }
    return CalibrationResult(
        procedure="wheel", method=method, model=MODEL, correction=correction, parameters=params,
        covariance=cov, parameter_names=names, quality=quality, arrays=arrays, settings=settings,
        warnings=list(warnings),
    )


# -------------------------------------------------------------------------- planning


@dataclass
class PlanRow:
    name: str
    value: float
    sd: float
    unit: str


def plan_state(radius: float, tilt_deg: float, speed: float, seconds: float,
               mount_deg=(30.0, 20.0, 25.0)) -> WheelState:
    """The nominal wheel for a plan: a perfect sensor (gains 1, offsets 0) mounted at
    ``mount_deg``, coasting down along the paper's Table I profile scaled to ``speed``
    and stretched over ``seconds``."""
    stretch = 90.0 / seconds
    omega = TABLE_I_OMEGA * (speed / TABLE_I_OMEGA[0]) * stretch ** np.arange(4)
    return WheelState(np.deg2rad(TABLE_I_THETA0_DEG), omega, np.deg2rad(tilt_deg), radius,
                      rotation_from_euler(np.deg2rad(mount_deg)), np.ones(3), np.zeros(3))


def plan_wheel(radius: float, tilt_deg: float, noise: float, rate: float, seconds: float, speed: float,
               mount_deg=(30.0, 20.0, 25.0), g: float = STANDARD_GRAVITY) -> list[PlanRow]:
    """The uncertainty each parameter would reach (CRB, k = 1) on a planned run, radius given."""
    for label, value in (("radius", radius), ("noise", noise), ("rate", rate), ("seconds", seconds), ("speed", speed)):
        if not value > 0:
            raise DataError(f"--{label} {value} must be positive")
    if not 0 < tilt_deg < 90:
        raise DataError(f"--tilt-deg {tilt_deg} must lie strictly between 0 and 90")
    state = plan_state(radius, tilt_deg, speed, seconds, mount_deg)
    turns = abs(phase(np.array([seconds]), 0.0, state.omega)[0][0]) / (2 * np.pi)
    if turns < MIN_TURNS:
        raise CalibrationError(
            f"the planned run makes {turns:.1f} turns, the calibration needs at least {MIN_TURNS:.0f}",
            "plan a faster spin (--speed) or a longer run (--seconds)",
        )
    t = np.arange(int(round(seconds * rate))) / rate
    free = FreeSet(radius_free=False, tilt_free=True)
    cov = wheel_crb(t, state, free, noise, g)
    sd = np.sqrt(np.diag(cov))
    values = reported_values(state, free)
    rows = []
    deg = {"theta0", "tilt", *ROTATION_NAMES}
    units = {"theta0": "deg", "omega0": "rad/s", "omega1": "rad/s^2", "omega2": "rad/s^3", "omega3": "rad/s^4",
             "tilt": "deg", "gain_x": "1", "gain_y": "1", "gain_z": "1"}
    for name, value, s in zip(reported_names(free), values, sd):
        factor = np.rad2deg(1.0) if name in deg else 1.0
        rows.append(PlanRow(name + ("_deg" if name in deg else ""), value * factor, s * factor,
                            units.get(name, "deg" if name in deg else "m/s^2")))
    return rows


# ---------------------------------------------------------------- operator procedure


@dataclass
class ProcedureEvent:
    """One thing to tell the operator.  kind: instruction | progress | ready | problem.

    Progress events also carry the figures of their message as numbers, so a
    display need not parse the text: ``turns`` counted so far, or ``speed``
    (rad/s, the latest point of ``WheelProcedure.speed_trace()``).
    """

    kind: str
    message: str
    progress: float = 0.0        # 0 .. 1 towards enough data
    turns: float | None = None
    speed: float | None = None


@dataclass
class WheelProcedure:
    """The wheel as operator steps: spin, wait for enough turns, stop, calibrate.

    ``feed(t, raw)`` takes each new chunk (times in s, raw (n, 3) in m/s^2) and
    returns the events to show; ``result()`` calibrates what was collected.
    UI-free: the TUI and the CLI drive the same object.
    """

    radius: float | None = None
    tilt_deg: float | None = None
    method: str = "joint"
    target_turns: float = 3 * MIN_TURNS     # comfortably above the minimum
    survey_every: float = 1.0                # seconds of data between looks
    g: float = STANDARD_GRAVITY
    meta: dict = field(default_factory=dict)
    _t: list = field(default_factory=list, repr=False)
    _v: list = field(default_factory=list, repr=False)
    _last_look: float = field(default=-np.inf, repr=False)
    _look: WheelSurvey | None = field(default=None, repr=False)
    _look_t: np.ndarray | None = field(default=None, repr=False)
    _started: bool = field(default=False, repr=False)
    done: bool = False

    def __post_init__(self) -> None:
        free_set(self.radius, None if self.tilt_deg is None else np.deg2rad(self.tilt_deg))

    def start(self) -> list[ProcedureEvent]:
        self._started = True
        return [ProcedureEvent("instruction", "spin the wheel by hand, then let it coast; keep the recording running")]

    def feed(self, t: np.ndarray, raw: np.ndarray) -> list[ProcedureEvent]:
        events = [] if self._started else self.start()
        t = np.asarray(t, dtype=float).reshape(-1)
        raw = np.asarray(raw, dtype=float).reshape(-1, 3)
        if t.size:
            self._t.append(t)
            self._v.append(raw)
        if not self._t:
            return events
        now = self._t[-1][-1]
        if now - self._last_look < self.survey_every:
            return events
        self._last_look = now
        tt = np.concatenate(self._t)
        vv = np.concatenate(self._v)
        if tt.size < 200:
            return events
        look = survey(tt - tt[0], vv, self.meta, self.g)
        progress = min(look.turns / self.target_turns, 1.0)
        if look.saturated:
            events.append(ProcedureEvent("problem", "the sensor clips at full scale: stop and spin slower", progress))
            return events
        if look.turns < 1.0:
            events.append(ProcedureEvent("instruction", "spin the wheel (no rotation seen yet)", progress))
            return events
        if look.turns >= TRACE_MIN_TURNS:
            self._look, self._look_t = look, tt - tt[0]
        events.append(ProcedureEvent(
            "progress", f"{look.turns:.1f} turns, need {self.target_turns:.0f}", progress, turns=look.turns))
        # the speed said is the newest full-turn speed of the trace: the survey's speed_end (a
        # slope over the last tenth) runs high while few turns are in, where the detrend bends the ends
        times, speeds = self.speed_trace()
        if speeds.size:
            trend = "decaying" if speeds[-1] < speeds[0] else "steady"
            events.append(ProcedureEvent("progress", f"speed {speeds[-1]:.1f} rad/s {trend}", progress,
                                         speed=float(speeds[-1])))
        if look.turns >= self.target_turns:
            self.done = True
            events.append(ProcedureEvent("ready", "enough data, stop the wheel", 1.0))
        return events

    def speed_trace(self) -> tuple[np.ndarray, np.ndarray]:
        """(time s from the first sample, |angular speed| rad/s) over the run so far: the speed
        of each full turn of the wheel angle of the latest look, one point every half turn.
        Recomputed at every look (about once a second), so the coast-down shows as it happens;
        empty until the wheel has made TRACE_MIN_TURNS turns."""
        if self._look is None:
            return np.zeros(0), np.zeros(0)
        return turn_speeds(self._look_t, self._look.angle)

    def recording(self) -> Recording:
        if not self._t:
            raise DataError("no samples collected yet", "spin the wheel and feed the procedure")
        meta = dict(self.meta)
        meta.setdefault("procedure", "wheel")
        return Recording(np.concatenate(self._t), np.concatenate(self._v), "m/s^2", {}, meta)

    def result(self) -> CalibrationResult:
        return calibrate_wheel(self.recording(), radius=self.radius, tilt_deg=self.tilt_deg,
                               method=self.method, g=self.g)
