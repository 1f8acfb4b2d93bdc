"""The tilted wheel (paper 002, Pedersini) on the Procedure contract, and the batch form for files.

    calibrate_wheel(recording, radius=0.28)                   joint maximum likelihood (default)
    calibrate_wheel(recording, radius=0.28, method="paper")   the paper's four steps
    WheelProcedure.create(values, device): feed(chunk) -> events; speed_trace(); result()   live

The joint fit (``fit``) starts from the paper's four steps (``paper``); the
four sequential steps each ignore information the others hold, so their
uncertainties come from a parametric bootstrap of the same four steps.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

from accelrig.errors import CalibrationError, DataError
from accelrig.estimation.residuals import whiteness_by_column
from accelrig.procedures.contract import Event, Procedure
from accelrig.procedures.wheel.assumptions import (
    DRIFT_SEGMENTS,
    MAX_NOD_MOVE,
    MAX_SECOND_ORDER,
    MAX_WOBBLE,
    Checks,
    check_residuals,
)
from accelrig.procedures.wheel.checks import (
    MIN_TURNS,
    REST_WINDOW_S,
    WheelSurvey,
    check_capture,
    coasting_from,
    noise_sd,
    rested_until,
    stopped_at,
    survey,
    timestamp_figures,
    turn_speeds,
)
from accelrig.procedures.wheel.fit import (
    MOUNTING_HINT,
    ROTATION_NAMES,
    chunks,
    free_set,
    joint_fit,
    reported_names,
    reported_values,
    reporting_map,
    residuals,
    wheel_crb,
)
from accelrig.procedures.wheel.model import phase, predict
from accelrig.procedures.wheel.paper import PaperSteps, paper_calibrate
from accelrig.procedures.wheel.rest import Rest, RestCheck, check_rests, unseen_drift
from accelrig.procedures.wheel.settings import (
    DEFAULT_BOOTSTRAP,
    DEFAULT_CROSS_AXIS_SD,
    METHODS,
    NEEDS_RADIUS_OR_TILT,
    SETTINGS,
)
from accelrig.procedures.wheel.start import joint_start
from accelrig.recording import Recording
from accelrig.result import CalibrationResult, Correction, Estimate
from accelrig.units import STANDARD_GRAVITY, local_gravity

MODEL = "v = o + diag(gain) R a(t); Pedersini eq. 1-7, cubic angular velocity"
# what scales with the local g the fit assumed (CalibrationResult.with_local_gravity): the gains have gravity as
# their reference; the radius is read from the centripetal term in the gains' scale, so it goes the other way
GRAVITY_SCALED = {"gain": 1, "radius": -1}
# A gain known worse than this (relative, k = 1) earns a warning about the mounting.
POOR_GAIN = 5e-3
# The speed trace is shown from this many turns on: before, the circle gravity draws is seen
# too little for its centre (the detrended centripetal term) to be placed, and the turn
# speeds are off by 7-20 % on the simulator (a few percent after three turns, 0.2 % at thirty).
TRACE_MIN_TURNS = 3.0
TARGET_TURNS = 3 * MIN_TURNS   # the live procedure asks for these: comfortably above the minimum
SURVEY_EVERY = 1.0             # seconds of data between looks at the live stream
# Fewer samples than this give the survey too little to count turns or speeds from.
MIN_LOOK_SAMPLES = 200


def _prepare(recording: Recording) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
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
    on_progress: Callable[[str], None] | None = None,
    before: Recording | None = None,
) -> CalibrationResult:
    """Calibrate from a wheel recording.  ``radius`` in m and/or ``tilt_deg`` must be given.

    ``before`` is what the recording held before ``recording`` when that is a part of it (``--start``): it is
    not fitted, but a rest at its beginning (the wheel held still before the push) still checks the coast.

    ``cross_axis_sd`` is the prior sd given to the off-diagonal terms of the correction matrix,
    which the wheel does not observe (they are set to 0 with that uncertainty).  ``on_progress``
    hears how far a long run is ("bootstrap run 120 of 1000"), for a progress line."""
    if method not in METHODS:
        raise DataError(f"unknown method {method!r}", f"use one of: {', '.join(METHODS)}")
    if not (np.isfinite(cross_axis_sd) and cross_axis_sd > 0):
        raise DataError(f"cross-axis sd {cross_axis_sd} must be positive",
                        "give the datasheet cross-axis sensitivity as an sd, e.g. 0.0115 for +-2 % uniform")
    tilt = None if tilt_deg is None else float(np.deg2rad(tilt_deg))
    free = free_set(radius, tilt)
    t, v, gap_times = _prepare(recording)
    look = survey(t, v, recording.meta, g, keep_angle=False)
    t, v, gap_times, coast, origin, rests = _free_coast(t, v, gap_times, look)
    if before is not None and not any(r.where == "before the spin" for r in rests):
        rests = _rest_before(before, recording, look) + rests
    if coast is not None:
        look = survey(t, v, recording.meta, g, keep_angle=False)
    warnings = check_capture(look, radius, g)
    started = time.perf_counter()
    if method == "joint":
        steps = joint_start(t, v, look, radius, tilt, g, gap_times)
        fit = joint_fit(t, v, steps.state, free, g)
        state, sigma, resid = fit.state, fit.sigma, fit.residuals
        checks = check_residuals(t, v, state, free, fit.time_scale, 1.0 / sigma, resid, g)
        warnings.extend(_assumption_warnings(checks, sigma))
        # the structure the checks found and took in: the estimates moved by its step, and ``resid`` (the
        # one residual array) now holds what is left after it
        state = checks.state
        tau = np.array([w.tau for w in checks.whiteness]) if checks.correlated else np.ones(3)
        drift_taken = checks.drift_per_axis is not None
        allowance, rest_quality, rest_source, rest_warnings = _rest_check(
            rests, t, state, checks.covariance_internal, free, fit.time_scale, fit.sigma, tau, g, drift_taken)
        warnings.extend(rest_warnings)
        m = reporting_map(state, free, fit.time_scale)
        cov = m @ (checks.covariance_internal + allowance) @ m.T
        quality = {"iterations": fit.iterations, "residual_checks": checks.to_dict(), "rest_check": rest_quality}
        uncertainty_source = checks.source + rest_source
    else:
        steps = paper_calibrate(t, v, look, radius, tilt, g, gap_times)
        state = steps.state
        resid = residuals(t, v, state, g)
        sigma = np.sqrt(np.einsum("nk,nk->k", resid, resid) / t.size)
        cov = _paper_bootstrap(t, state, free, sigma, look, radius, tilt, g, gap_times, bootstrap, seed,
                               on_progress)
        crb = wheel_crb(t, state, free, sigma, g)
        # the rest checks the four steps' coast as it checks the joint fit's: their covariance (the bootstrap's)
        # taken to the internal parameters the check works in, the noise's correlation time from the residuals
        time_scale = max(float(t[-1]), 1e-6)
        m = reporting_map(state, free, time_scale)
        # the bootstrap's own sd against the CRB, before any rest allowance joins it
        sd_over_crb = dict(zip(reported_names(free), np.sqrt(np.diag(cov) / np.diag(crb)), strict=True))
        white = whiteness_by_column(resid)
        tau = np.array([w.tau for w in white]) if any(w.correlated for w in white) else np.ones(3)
        try:
            m_inv = np.linalg.inv(m)
        except np.linalg.LinAlgError:   # the mounting's Euler angles at gimbal lock: no internal covariance
            allowance, rest_warnings = np.zeros((m.shape[1], m.shape[1])), []
            rest_quality = {"made": False, "why": "the mounting's angles sit at gimbal lock, where the four "
                                                  "steps' covariance cannot be taken to the check's parameters"}
            rest_source = f"; not checked against the wheel at rest: {rest_quality['why']}"
        else:
            allowance, rest_quality, rest_source, rest_warnings = _rest_check(
                rests, t, state, m_inv @ cov @ m_inv.T, free, time_scale, sigma, tau, g, False)
        warnings.extend(rest_warnings)
        cov = cov + m @ allowance @ m.T
        quality = {"bootstrap_runs": bootstrap, "sd_over_crb": sd_over_crb, "rest_check": rest_quality}
        uncertainty_source = f"parametric bootstrap of the four steps ({bootstrap} runs)" + rest_source
    elapsed = time.perf_counter() - started
    names = reported_names(free)
    # the mounting's part of u: the white-noise covariance (a correlated noise widens u for another reason)
    mounting_cov = fit.covariance if method == "joint" else cov
    for axis in "xyz":
        u_gain = np.sqrt(mounting_cov[names.index(f"gain_{axis}"), names.index(f"gain_{axis}")])
        if u_gain > POOR_GAIN * state.gain["xyz".index(axis)]:
            warnings.append(f"gain_{axis} is poorly determined (u = {u_gain:.2g}): the mounting hides it; "
                            + MOUNTING_HINT)
    assumed = ("the datasheet +-2 % cross-axis sensitivity as a uniform bound"
               if cross_axis_sd == DEFAULT_CROSS_AXIS_SD else "given with --cross-axis-sd")
    # a limit of the method, the same on every run: stated with the checks (quality.cross_axis), as the coast
    # and the local gravity are, so that the warnings hold only what this record showed
    quality["cross_axis"] = {
        "observed": False, "prior_sd": float(cross_axis_sd),
        "note": "the wheel does not observe cross-axis terms (the sensor's own axis misalignment is absorbed in "
                f"the mounting rotation): the correction's off-diagonal entries are 0 with an assumed prior sd of "
                f"{cross_axis_sd:.3g} ({assumed}), carried in their u; a static calibration measures them"}
    if coast is not None:
        quality["coast"] = coast
    result = _build_result(method, state, cov, free, sigma, resid, t, steps, look, warnings, quality,
                           elapsed, radius, tilt, g, uncertainty_source, cross_axis_sd)
    few = checks.few_blocks if method == "joint" else None
    if few is not None and few.few:
        # u rests on few batch-means blocks: its expanded form takes Student's t on their dof (residuals.FewBlocks)
        result.details["coverage_factor"] = few.coverage_factor
        result.details["coverage_dof"] = few.dof
    if origin:
        # t, theta0 and the speed law count from the free coast's first sample
        result.settings["time_origin"] = f"first sample of the free coast, {origin:.3f} s after the recording's first"
    return result


def _free_coast(t: np.ndarray, v: np.ndarray, gap_times: np.ndarray, look: WheelSurvey):
    """The free coast the speed law (eq. 2, a cubic in t) can follow: (t, v, gap times, the cut (None: the whole
    record is the coast; else its bounds and a note for quality.coast), the time of its
    first sample in the recording).

    Before it the wheel may rest and be pushed by hand (the wizard says "spin the wheel by hand after holding
    it still for 5 s, then let it coast; keep the recording running"); after it the wheel may stop and rest.
    Neither is a coast-down: the fit takes the coast, t counted from its first sample, and the cut says what was
    left out and why (with the checks, not as a warning: it is what the wizard asks for).  Nothing is dropped from the recording itself.  The rests (before the push, after the stop)
    are returned for the check against the fit (rest.py)."""
    start = coasting_from(t, v, look.noise_sd, look.period)
    stop = stopped_at(t, v, look.noise_sd, look.period)
    if stop is not None and start is not None and stop <= start:
        stop = None
    if start is None and stop is None:
        return t, v, gap_times, None, 0.0, []
    # the wheel at rest before the push and after the stop reads the offsets and gravity alone (rest.py)
    rests = []
    until = rested_until(t, v, look.noise_sd, look.period) if start is not None else None
    if until is not None and until < start:
        rests.append(Rest("before the spin", t[t < until], v[t < until]))
    if stop is not None:
        # a window's margin: the wheel may rock a little as it comes to rest
        after = t >= stop + REST_WINDOW_S
        if np.count_nonzero(after) >= MIN_LOOK_SAMPLES:
            rests.append(Rest("after the stop", t[after], v[after]))
    lo = 0.0 if start is None else start
    hi = np.inf if stop is None else stop
    kept = (t >= lo) & (t < hi)
    # What the wizard asks for (a rest, a push, a coast, perhaps a stop) is no warning: the cut is reported with
    # the checks (quality.coast), and the rests check the coast (rest.py)
    end = float(min(hi, t[-1]))
    parts = [f"the fit uses the free coast from {lo:.1f} s to {end:.1f} s ({np.count_nonzero(kept)} of {t.size} "
             "samples), where the speed law holds"]
    if start is not None:
        parts.append(f"before {start:.1f} s the wheel rested or was pushed by hand")
    if stop is not None:
        parts.append(f"from {stop:.1f} s it stood still")
    coast = {"from_s": float(lo), "to_s": end, "samples_used": int(np.count_nonzero(kept)), "samples": int(t.size),
             "note": "; ".join(parts) + "; the whole recording is kept"}
    origin = float(t[kept][0])
    gap_times = gap_times[(gap_times > lo) & (gap_times < hi)] - origin
    return t[kept] - origin, v[kept], gap_times, coast, origin, rests


def _rest_before(before: Recording, recording: Recording, look: WheelSurvey) -> list[Rest]:
    """The rest before the spin in the part of the recording left out before ``recording`` (``--start``): the
    still windows from its first sample, as ``_free_coast`` finds them in a whole record (the wheel must be seen
    turning after them, in ``before`` or in ``recording``).  Times count from ``before``'s first sample, the
    whole recording's."""
    if len(before) == 0 or len(recording) == 0:
        return []
    t0 = before.t[0]
    tb, vb = before.t - t0, before.to_si().acc
    t, v = recording.t - t0, recording.to_si().acc
    until = rested_until(np.concatenate([tb, t]), np.concatenate([vb, v]), look.noise_sd, look.period)
    if until is None:
        return []
    inside = tb < until
    if np.count_nonzero(inside) < MIN_LOOK_SAMPLES:
        return []
    return [Rest("before the spin", tb[inside], vb[inside])]


def _rest_check(rests: list[Rest], t: np.ndarray, state, cov: np.ndarray, free, time_scale: float,
                sigma: np.ndarray, tau: np.ndarray, g: float, drift_taken: bool):
    """The coast's fit (``state``, its covariance ``cov`` over the internal parameters) against the wheel at rest
    (rest.py): (what u adds, internal; the quality entry; what the uncertainty line adds; warnings).  Found, u
    includes the move the rests would make; with no rest, or with a drift taken in per segment (the offset at the
    coast's ends is then known only roughly), the quality and the uncertainty line say the check was not made.
    ``sigma`` is each axis' noise sd, ``tau`` its correlation time in samples (ones when white)."""
    nothing = np.zeros_like(cov)
    if not rests:
        why = ("the recording holds no rest (the wheel held still a few seconds before the push, with the recording "
               "running, would show a drift of the offsets along the wheel's plane that the coast alone takes for "
               "the centripetal term)")
        # what the coast alone could miss: stated with its effect, not added to u (it would make u 5-300 times the
        # noise's on every record without a rest: docs/wheel.md, "Not solved")
        unseen = unseen_drift(t, state, cov, free, time_scale, sigma, g)
        said = " or ".join(f"{d['size_m_s2']:.2g} m/s^2 {d['shape'].split(' (')[0]}" for d in unseen.values())
        worst = max(unseen.values(), key=lambda d: d["largest_move_over_u"])
        # computed at white noise: correlated noise raises the limit, and the sentence must not read as a bound then
        colour = (" at white noise (the noise here is correlated, which raises it)" if np.any(np.asarray(tau) > 1)
                  else "")
        limit = (f"; a drift along the wheel's plane of {said} would go unseen{colour} (the drift tests find it half "
                 f"the time) and would move {worst['moves_most']} by up to {worst['largest_move_over_u']:.2g} u; u "
                 "does not include it: record 5 s with the wheel still before the push")
        # and warned: u leaves out a move the record cannot rule out (38 u on the docs' 45 s coast), so the result
        # must not read "no warnings"; the wizard's record has its rest and never sees this
        warning = (f"the recording holds no rest before the push, so a drift of the offsets along the wheel's plane "
                   f"({said}) would go unseen and could move {worst['moves_most']} by up to "
                   f"{worst['largest_move_over_u']:.2g} u, which u does not include: record 5 s with the wheel "
                   "still before the push")
        return nothing, {"made": False, "why": why, "unseen_drift": unseen}, \
            f"; not checked against the wheel at rest: {why}{limit}", [warning]
    if drift_taken:
        why = ("the offsets drifted during the coast and the fit took the drift in, so the offset at the coast's "
               "ends is known too roughly for the rest to test it")
        return nothing, {"made": False, "why": why}, f"; not checked against the wheel at rest: {why}", []
    found = check_rests(rests, t, state, cov, free, time_scale, sigma, tau, g)
    where = " and ".join(f"{r['where']} ({r['to_s'] - r['from_s']:.1f} s)" for r in found.rests)
    quality = {"made": True, **found.to_dict()}
    if not found.significant:
        return nothing, quality, f"; checked against the wheel at rest {where}: it agrees (p = {found.p_value:.2g})", []
    return found.allowance, quality, (f"; the wheel at rest {where} disagrees with the fit (p = {found.p_value:.2g}): u "
                                      f"includes the bias of a drift along the wheel's plane that size ({found.drift:.2g} "
                                      "m/s^2 over the coast, shaped like w^2, in any direction within the plane)"), \
        [_rest_warning(found)]


def _rest_warning(found: RestCheck) -> str:
    read = "; ".join(f"{r['where']} ({r['from_s']:.1f}-{r['to_s']:.1f} s) by "
                     + ", ".join(f"{x:+.3g}" for x in r["read_off_m_s2"]) + " m/s^2"
                     for r in found.rests)
    return ("the wheel at rest read off what the fit of the coast predicts, beyond what the resting angle explains: "
            f"{read} (x, y, z; chi^2 test p = {found.p_value:.1g}): the offsets moved between the rest and the coast, "
            "or drifted during the coast along the wheel's plane, where a drift looks like the centripetal term the "
            f"gains are scaled by; the data cannot tell which, so u of the gains, offsets and tilt includes the bias "
            f"a drift of {found.drift:.2g} m/s^2 over the coast would make; a sensor still warming up drifts like "
            "this, let it settle powered before calibrating")


def _assumption_warnings(checks: Checks, sigma: np.ndarray) -> list[str]:
    """What the residual checks found, in the operator's words; a refusal beyond MAX_SECOND_ORDER."""
    out = list(checks.notes)
    angle, third = checks.angle, checks.third
    if (angle is not None and angle.significant) or (third is not None and third.significant):
        out += _angle_locked(checks, sigma)
    if checks.drift_per_axis is not None:
        d = checks.drift_per_axis
        seen = [f"{t.name} p = {t.p_value:.1g}" for t in (checks.drift, checks.drift_shape) if t.significant]
        out.append(f"the offsets drifted during the run, by {d[0]:+.3g}, {d[1]:+.3g}, {d[2]:+.3g} m/s^2 from its "
                   f"start to its end (x, y, z; known only roughly, as what moves along the wheel's radius looks like "
                   f"the centripetal term; score tests: {', '.join(seen)}): the fit takes the drift in as a "
                   f"line and an offset for each of {DRIFT_SEGMENTS} parts of the run, whatever its shape (a warm-up "
                   "that settles, a step); the offsets are the run's mean. A drifting offset looks like the "
                   "centripetal term the gains are scaled by, so u of the gains, offsets and tilt grows several "
                   "times; a sensor still warming up drifts like this, let it settle powered before calibrating")
    return out


BALANCE_HINT = ("balance the wheel (an unbalanced wheel speeds up and slows down once per turn), check its bearing, "
                "and record a free coast-down without touching it")
PLAY_HINT = ("check the wheel's bearing for play and that the wheel runs true on its axle (a dial gauge on the rim "
             "shows a wobble), tighten or replace the bearing and record again")

NOD_HINT = ("check the bearing for play (rock the wheel by its rim across its plane: it should not click or give), "
            "tighten or replace it so the axis holds still, and record again")
THIRD_HINT = ("check the bearings: one worn out of round, or two that do not line up on the axle, let the axis nod "
              "twice per turn; replace or realign them so the wheel turns true, and record again")


def _angle_locked(checks: Checks, sigma: np.ndarray) -> list[str]:
    """Structure locked to the wheel's angle, named by its cause: the speed law (imbalance, friction), the
    wheel's wobble (play, an axle that does not run true), or both when the data cannot tell them apart.

    Taken into the fit, it widens u.  The take-in models it to first order (a small speed swing, a small
    wobble); what that leaves out is computed from what the take-in fitted, and when its bias exceeds
    MAX_SECOND_ORDER of an estimate's u the estimates cannot be trusted within any u: refused.  Not the
    structure's size against the noise: that ratio tends to one for a quiet sensor, which was refused where a
    noisier one passed, though the take-in held the structure as well.  A wobble is still refused beyond
    MAX_WOBBLE of the noise: there the first-order model is not what fails (its remainder is small) but the
    wobble family itself (see MAX_WOBBLE)."""
    angle, causes = checks.angle, [c for c in checks.causes if c != "wobble at 3x"]
    size = angle.systematic_rms * float(np.mean(sigma))
    found = (f"{size:.3g} m/s^2 rms ({100 * angle.systematic_rms:.0f} % of the noise sd; score test "
             f"p = {angle.p_value:.1g})")
    law = ("the wheel did not follow the model's smooth speed law: the residuals hold a structure locked to the "
           "wheel angle or slower than the cubic coast-down")
    wobble = (f"the wheel wobbles with its own angle (bearing play, or a wheel that does not run true on its axle): "
              f"the residuals hold a structure locked to the wheel angle that tips gravity towards the wheel axis, "
              f"where no speed law reaches, a wobble of about {checks.wobble_deg:.2g} deg rms "
              f"(score test with the speed law projected out p = {checks.wobble.p_value:.1g})")
    third = None
    if "wobble at 3x" in checks.causes:
        t3 = checks.third
        third = (f"the wheel wobbles at three times its angle, beyond the harmonics 1-2 the wobble model holds: a "
                 f"wobble of about {checks.third_deg:.2g} deg (score test with the rest projected out "
                 f"p = {t3.p_value:.1g}, {t3.systematic_rms * float(np.mean(sigma)):.3g} m/s^2 rms); an axis that "
                 "nods twice per turn (a bearing worn out of round, two bearings out of line) shows half its nod "
                 "there, and half at once per turn")
    if not causes:
        seen, hint, cause = third, THIRD_HINT, "the fit takes it in"
    elif causes == ["speed law"]:
        seen, hint = f"{law}, {found}", BALANCE_HINT
        cause = "an unbalanced wheel or friction that is not a smooth coast-down does this"
    elif causes == ["wobble"]:
        seen, hint, cause = f"{wobble}; the structure in all: {found}", PLAY_HINT, "it is not the speed law"
    else:
        both = all(t.significant for t in (checks.speed_law, checks.wobble))
        seen = (f"the residuals hold a structure locked to the wheel angle, {found}: "
                + ("both a speed swing (an unbalanced wheel, friction) and a wobble (bearing play, a wheel that "
                   "does not run true), " if both else
                   "a speed swing (an unbalanced wheel) or a wobble (bearing play, a wheel that does not run true), "
                   "the data cannot tell which; ")
                + f"a wobble of about {checks.wobble_deg:.2g} deg rms")
        hint, cause = PLAY_HINT + "; " + BALANCE_HINT, "the fit takes both in"
    if third is not None and causes:
        seen, hint = f"{seen}; and {third}", f"{hint}; {THIRD_HINT}"
    missed = checks.second_order_over_u
    if missed is not None and missed > MAX_SECOND_ORDER:
        raise CalibrationError(
            seen + f"; the structure is too large for the fit to take in: what its first-order model leaves out "
            f"alone moves the estimates by up to {missed:.2g} times their u", hint)
    nod = checks.nod_move_over_u
    change = checks.nod_change
    if nod is not None and nod > MAX_NOD_MOVE:
        raise CalibrationError(
            f"the wheel wobbles by {checks.nod_deg / 2:.2g} deg turning with it at twice its angle ({found}): "
            f"what an axis that nods about {checks.nod_deg:.2g} deg once per turn (bearing play) shows of itself, "
            f"or one that cones round against the wheel by {checks.nod_deg / 2:.2g} deg; a nod's other half, as "
            "large, turns gravity on the wheel as a mounting rotation would but leaves the centripetal term alone, "
            "which the fit cannot tell from the mounting and the offsets, and it could move the estimates by up to "
            f"{nod:.2g} times their u (beyond {MAX_NOD_MOVE:g} the calibration would measure the bearing more than "
            "the sensor)", NOD_HINT)
    if nod is not None and change is not None and change.significant:
        start, end = checks.nod_ends_deg
        raise CalibrationError(
            f"the wheel wobbles turning with it at twice its angle, as an axis that nods once per turn (bearing "
            f"play) shows half of itself, and the wobble changes its size over the run: a nod of about {start:.2g} "
            f"deg at the start, {end:.2g} deg at the end (score test of the change p = {change.p_value:.1g}; the "
            f"structure in all: {found}); play that opens only above some speed does this. A nod's other half turns "
            "gravity on the wheel as a mounting rotation would; one that changes with the speed changes as the "
            "centripetal term does, which the fit cannot tell from the gains, so no u can be stated for it",
            NOD_HINT + "; or record a coast that stays below the speed where the wobble appears")
    if "wobble" in causes and checks.wobble.systematic_rms > MAX_WOBBLE:
        raise CalibrationError(
            seen + f"; a wobble beyond {100 * MAX_WOBBLE:.0f} % of the noise sd: the wobble the fit takes in (a "
            "rotation of the wheel at harmonics 1-2 of its angle) does not hold a real nodding axis that large, the "
            "gains and offsets are then off by more than any u the fit can state", hint)
    if nod is not None:
        # what was seen is a wobble at twice the angle turning with the wheel; a nod is one reading of it
        seen += (f"; of it, {checks.nod_deg / 2:.2g} deg turns with the wheel at twice its angle, as an axis that "
                 f"nods about {checks.nod_deg:.2g} deg once per turn shows half of itself (or one that cones round "
                 "against the wheel, all of itself), and u includes what a nod's other half, which the fit cannot "
                 f"tell from the mounting, could do (up to {nod:.2g} u)")
    return [seen + f": {cause}; the fit takes the structure in and u grows with it, but a wheel that runs true and "
            "smoothly gives a calibration to trust more"]


def _paper_bootstrap(t, state, free, sigma, look, radius, tilt, g, gap_times, runs, seed,
                     on_progress=None) -> np.ndarray:
    """Covariance of the four-step estimator: rerun it on data simulated from its own estimate."""
    if runs < 5:
        raise DataError(f"--bootstrap {runs}: the paper method needs at least 5 runs for its uncertainties")
    rng = np.random.default_rng(seed)
    clean = predict(t, state, g)
    names = reported_names(free)
    draws = np.empty((runs, len(names)))
    for i in range(runs):
        if on_progress is not None:
            on_progress(f"bootstrap run {i + 1} of {runs}")
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
        "residual_rms": float(np.sqrt(np.einsum("nk,nk->", resid, resid) / resid.size)),
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
    # the wheel's fitted angle, wrapped to one turn: residuals against it show a pattern tied to the rotation
    angle_deg = np.empty(t.size)
    for part in chunks(t.size):
        angle_deg[part] = np.mod(np.rad2deg(phase(t[part], state.theta0, state.omega)[0]), 360.0)
    arrays = {
        "t": t, "residuals": resid, "angle_deg": angle_deg,
        "speed_time": steps.speed_time, "speed_samples": steps.speed_samples,
        "speed_fit": np.abs(speed_fit), "speed_residuals": speed_resid,
    }
    return CalibrationResult(
        procedure="wheel", method=method, model=MODEL, correction=correction, parameters=params,
        covariance=cov, parameter_names=names, quality=quality, arrays=arrays, settings=settings,
        warnings=list(warnings),
        parameter_meaning=("the sensor's own form v = o + diag(gain) R a (Pedersini eq. 6): gain and offset are "
                           "what the sensor does to the acceleration, so the correction is C = 1/gain and b = "
                           "offset; misalignment_deg is how it sits on the wheel, tilt_deg the wheel's tilt, omega0-3 its "
                           "speed law"),
    )


class WheelProcedure(Procedure):
    """The wheel as operator steps: spin, wait for enough turns, stop, calibrate.

    Each look at the stream (about once a second) counts the turns and the speed; ``result()``
    calibrates what was collected with ``calibrate_wheel``.
    """

    name = "wheel"
    title = "tilted wheel calibration"
    settings = SETTINGS
    settings_note = NEEDS_RADIUS_OR_TILT

    def __init__(self, values: dict, device: dict):
        free_set(values["radius"], None if values["tilt_deg"] is None else np.deg2rad(values["tilt_deg"]))
        self.values = dict(values)
        self.device = dict(device)
        self._t: list[np.ndarray] = []
        self._v: list[np.ndarray] = []
        self._last_look = -np.inf
        self._look: WheelSurvey | None = None
        self._look_t: np.ndarray | None = None
        self._started = False
        self._progress = 0.0
        self._done = False

    @property
    def progress(self) -> float:
        return self._progress

    @property
    def done(self) -> bool:
        return self._done

    def feed(self, chunk) -> list[Event]:
        events = []
        if not self._started:
            self._started = True
            # the rest before the spin reads the offsets and gravity alone: it checks the coast's fit (rest.py)
            events.append(Event("instruction", "spin the wheel by hand after holding it still for 5 s, then let it "
                                "coast; keep the recording running"))
        t = np.asarray(chunk.t, dtype=float).reshape(-1)
        if t.size:
            self._t.append(t)
            self._v.append(np.asarray(chunk.acc, dtype=float).reshape(-1, 3))
        if not self._t:
            return events
        now = self._t[-1][-1]
        if now - self._last_look < SURVEY_EVERY:
            return events
        self._last_look = now
        tt = np.concatenate(self._t)
        vv = np.concatenate(self._v)
        if tt.size < MIN_LOOK_SAMPLES:
            return events
        tt = tt - tt[0]
        # once the hand has let go, the look (turns, the speed trace) is of the free coast, as the fit's will be
        start = coasting_from(tt, vv, noise_sd(vv), float(np.median(np.diff(tt))))
        if start is not None and np.count_nonzero(tt >= start) >= MIN_LOOK_SAMPLES:
            keep = tt >= start
            tt, vv = tt[keep], vv[keep]
        look = survey(tt, vv, self.device, self.values["g"])
        self._progress = progress = min(look.turns / TARGET_TURNS, 1.0)
        if look.saturated:
            events.append(Event("problem", "the sensor clips at full scale: stop and spin slower", progress))
            return events
        if look.turns < 1.0:
            events.append(Event("instruction", "spin the wheel (no rotation seen yet)", progress))
            return events
        if look.turns >= TRACE_MIN_TURNS:
            self._look, self._look_t = look, tt
        events.append(Event("progress", f"{look.turns:.1f} turns, need {TARGET_TURNS:.0f}", progress,
                            {"turns": look.turns}))
        # the speed said is the newest full-turn speed of the trace: the survey's speed_end (a
        # slope over the last tenth) runs high while few turns are in, where the detrend bends the ends
        times, speeds = self.speed_trace()
        if speeds.size:
            trend = "decaying" if speeds[-1] < speeds[0] else "steady"
            events.append(Event("progress", f"speed {speeds[-1]:.1f} rad/s {trend}", progress,
                                {"speed": float(speeds[-1])}))
        if look.turns >= TARGET_TURNS:
            self._done = True
            events.append(Event("ready", "enough data, stop the wheel", 1.0))
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
        meta = dict(self.device)
        meta.setdefault("procedure", "wheel")
        return Recording(np.concatenate(self._t), np.concatenate(self._v), "m/s^2", {}, meta)

    def result(self) -> CalibrationResult:
        v = self.values
        gravity = local_gravity(v["g"], v.get("latitude"), v.get("height"), v.get("g_u"))
        return calibrate_wheel(self.recording(), radius=v["radius"], tilt_deg=v["tilt_deg"], method=v["method"],
                               g=gravity.value, bootstrap=v["bootstrap"],
                               cross_axis_sd=v["cross_axis_sd"]).with_local_gravity(gravity, GRAVITY_SCALED)
