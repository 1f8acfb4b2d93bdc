"""The six-face static calibration as a Procedure (accelrig.procedures.contract), live and for files.

One object serves the live flow (the TUI feeds ring-buffer chunks as they
arrive and shows the events) and the batch one (``calibrate_static`` feeds a
whole recording through the same object as one chunk), so a recording gives
the same poses whichever way it is processed.

    proc = StaticProcedure.create(values, device)   values: the declared SETTINGS, parsed
    proc.feed(chunk) -> events      contract Events; data["kind"]: hold_still, captured, moved, ...
    proc.act("redo", face="+x")     forget a face to take it again
    proc.finish()                   the data ended: close the pose in progress
    proc.progress, proc.done        faces done / 6; all six in (enough to compute)
    proc.complete                   the guided sequence is through: six faces, then the drift check's three rounds
    proc.faces                      the face grid's details (done, held, hold fraction, ...)
    proc.result()                   the CalibrationResult (model and method from the settings)

Which model: ``six-face`` (default through ``auto`` when every pose is near a face) is the paper's
9-parameter model with each pose's tilt from its face a nuisance under a flatness prior
(``gravity_fit.fit_six_face``); ``multi-position`` fits gravity magnitudes from any orientations
(``gravity_fit.fit_multiposition``); ``paper`` / ``affine`` are the exact-face fits of ``fit``.
Every still pose found is reported with its fate (``details["poses"]``).
"""

from __future__ import annotations

import numpy as np

from accelrig.errors import CalibrationError, DataError
from accelrig.estimation.distributions import chi2 as chi2_dist
from accelrig.estimation.gravity_fit import (
    CHI2_ALPHA,
    DISTINCT_DEG,
    FACE_REFUSE_SD,
    MULTI_ASKED,
    MULTI_ASKED_WHY,
    MULTI_MIN_DISTINCT,
    PoseStats,
    check_faces,
    distinct_orientations,
    face_tilts,
    fit_multiposition,
    fit_six_face,
    magnitude_z,
    magnitude_z_response,
)
from accelrig.estimation.residuals import ALPHA
from accelrig.geometry import AXES, FACES, opposite_face
from accelrig.procedures.contract import Event, Procedure
from accelrig.procedures.static.fit import MODELS, PoseData, face_reference, fit_model
from accelrig.procedures.static.noise import (
    SETTLE_HINT,
    WANDER_HINT,
    StillNoise,
    drift_bend,
    drift_checks,
    offset_wander,
    pooled_axes,
    slow_memory,
    slow_model_check,
    still_noise,
)
from accelrig.procedures.static.poses import Pose, PoseDetector, full_scale_of, pose_event
from accelrig.procedures.static.settings import MODEL_CHOICES, POSE_FLATNESS_DEG, SETTINGS
from accelrig.recording import Recording
from accelrig.result import CalibrationResult, Correction, Estimate
from accelrig.units import STANDARD_GRAVITY, LocalGravity, local_gravity

# Seconds a face is held before the live flow says "captured" (a pose still counts from min_hold on).
HOLD = 4.0


class StaticProcedure(Procedure):
    """Six faces in any order (repeats add data), each held still; then the fit."""

    name = "static"
    title = "six-face static calibration"
    settings = SETTINGS
    actions = {"redo": "redo a face"}   # act("redo", face="+x"): take that face again

    def __init__(self, rate: float, g: float = STANDARD_GRAVITY, model: str = "auto", method: str = "vp",
                 pose_flatness_deg: float = POSE_FLATNESS_DEG, gravity: LocalGravity | None = None, **detection):
        """``detection``: PoseDetector's settings (hold, min_hold, still_threshold, full_scale, ...).

        ``model="multi-position"`` is the any-orientation flow: progress and ``done`` count distinct
        orientations (``MULTI_MIN_DISTINCT``, poses closer than DISTINCT_DEG count as one), not faces."""
        _check_model(model, method)
        self.model, self.method, self.pose_flatness_deg = model, method, float(pose_flatness_deg)
        self.any_orientation = model == "multi-position"
        # g and u(g): from the settings (create), else the g given (its u: standard gravity's, or its rounding)
        self.gravity = gravity or local_gravity(g)
        self.detector = PoseDetector(rate, g=self.gravity.value, **detection)
        self._started = False
        self._n_distinct = 0
        self._n_captured = 0
        # pose numbers (pose_table's) the operator asked to leave out of a recording (calibrate --skip-pose)
        self.left_out: frozenset[int] = frozenset()

    @classmethod
    def create(cls, values: dict, device: dict) -> StaticProcedure:
        rate = device.get("rate") or device.get("nominal_rate")
        if not rate:
            raise DataError("the sample rate is not known", "give the rate of a file without a t column (--rate)")
        gravity = local_gravity(values["g"], values.get("latitude"), values.get("height"), values.get("g_u"))
        return cls(rate, gravity=gravity, model=values["model"], method=values["method"],
                   pose_flatness_deg=values.get("pose_flatness_deg", POSE_FLATNESS_DEG), min_hold=values["min_hold"], hold=max(HOLD, values["min_hold"]),
                   still_threshold=values["still_threshold"], full_scale=full_scale_of(device))

    # ------------------------------------------------------------- contract
    def feed(self, chunk) -> list[Event]:
        events = []
        if not self._started and len(chunk.t):
            self._started = True
            events.append(pose_event("start", "hold the sensor still in any orientation, then turn it to another"
                                     if self.any_orientation else "put the sensor down on any face and hold it still",
                                     float(chunk.t[0])))
        found = self.detector.feed(chunk.t, chunk.acc)
        return events + (self._orientation_events(found) if self.any_orientation else found)

    def _orientation_events(self, events: list[Event]) -> list[Event]:
        """The detector's face-flow events retold for the any-orientation flow: a pose is an orientation,
        progress counts distinct orientations; it can compute at MULTI_MIN_DISTINCT of them and is through at
        MULTI_ASKED (the ones beyond the minimum test the fit)."""
        out = []
        for event in events:
            kind = event.data.get("kind")
            time = event.data.get("time", 0.0)
            if kind in ("hold_still", "not_flat", "already_done"):
                out.append(pose_event("hold_still", "hold still: " + self._novelty(), time))
            elif kind == "captured":
                out.append(pose_event("captured", event.message.replace(" down captured", " (near a face) captured"),
                                      time))
                # the k-th capture is the k-th usable pose (a chunk may hold several poses: count as of this one)
                self._n_captured += 1
                means = np.array([p.mean for p in self.detector.accepted()[:self._n_captured]])
                n_before, n = self._n_distinct, distinct_orientations(means)
                self._n_distinct = n
                more, asked = max(MULTI_MIN_DISTINCT - n, 0), max(MULTI_ASKED - n, 0)
                said = (f", {more} more needed" if more else
                        f": c computes now; {asked} more asked, {MULTI_ASKED_WHY}" if asked else "")
                out.append(pose_event("progress", f"{n} distinct orientation{'s' if n != 1 else ''}" + said, time,
                                      progress=min(n / MULTI_ASKED, 1.0)))
                if n >= MULTI_ASKED > n_before:
                    out.append(pose_event("complete", f"{n} distinct orientations captured", time, progress=1.0))
            elif kind in ("progress", "complete"):
                continue   # face counts: not this flow's
            else:
                out.append(event)
        return out

    def _novelty(self) -> str:
        """Whether the pose held now is a new orientation (for the instruction line)."""
        state = self.detector.state
        if not state["still"] or state.get("current_mean") is None:
            return "a new orientation"
        held = np.asarray(state["current_mean"])
        taken = [p.mean for p in self.detector.poses]
        if taken and distinct_orientations(np.array([*taken, held])) == distinct_orientations(np.array(taken)):
            return f"close to one already captured (within {DISTINCT_DEG:g} degrees it counts once; turn further)"
        return "a new orientation"

    def act(self, action: str, **arguments) -> list[Event]:
        if action != "redo":
            return super().act(action, **arguments)
        if self.any_orientation:
            raise DataError("any-orientation mode keeps every pose: there is no face to redo",
                            "hold more orientations instead")
        if "face" not in arguments:
            raise DataError("redo needs the face to take again", "faces are +x, -x, +y, -y, +z, -z")
        return self.detector.forget(arguments["face"])

    def finish(self) -> list[Event]:
        # the pose closed by the end of the data is told as feed tells it (the any-orientation flow said
        # "1 of 6" faces here)
        found = self.detector.finish()
        return self._orientation_events(found) if self.any_orientation else found

    @property
    def progress(self) -> float:
        if self.any_orientation:
            return min(self.orientations["n_distinct"] / MULTI_ASKED, 1.0)
        return len(self.faces_done) / len(FACES)

    @property
    def done(self) -> bool:
        if self.any_orientation:
            return self.orientations["n_distinct"] >= MULTI_MIN_DISTINCT
        return not self.missing_faces

    @property
    def complete(self) -> bool:
        """The guided sequence is through: six faces, then the drift check's three rounds; or the orientations
        asked for (MULTI_ASKED: a few beyond the minimum, so that the fit can be tested)."""
        if self.any_orientation:
            return self.orientations["n_distinct"] >= MULTI_ASKED
        return self.detector.complete

    @property
    def orientations(self) -> dict:
        """For the any-orientation display: the unit directions of the usable poses' raw means (the one held
        now included once captured), how many are distinct (closer than DISTINCT_DEG count once), how many
        are needed, and the octants (sign patterns of x, y, z) they reach."""
        means = np.array([p.mean for p in self.detector.accepted()]).reshape(-1, 3)
        directions = means / np.linalg.norm(means, axis=1, keepdims=True) if len(means) else means
        n = distinct_orientations(means) if len(means) else 0
        octants = {tuple(int(v) for v in np.sign(d) >= 0) for d in directions}
        return {"directions": directions, "n_distinct": n, "needed": MULTI_MIN_DISTINCT,
                "more": max(MULTI_MIN_DISTINCT - n, 0), "asked": MULTI_ASKED, "more_asked": max(MULTI_ASKED - n, 0),
                "octants": len(octants), "n_poses": len(means),
                "distinct_deg": DISTINCT_DEG}

    @property
    def faces(self) -> dict:
        """For the face grid: faces_done, missing, current_face, still, hold_fraction, held_seconds, ..."""
        return self.detector.state

    # ------------------------------------------------------------- what was found
    @property
    def poses(self) -> list[Pose]:
        """The poses closed and accepted, in the order captured."""
        return self.detector.poses

    @property
    def rejected(self) -> list[Pose]:
        """Still stretches that could not be used, with the reason."""
        return self.detector.rejected

    @property
    def faces_done(self) -> list[str]:
        return self.detector.faces_done

    @property
    def missing_faces(self) -> list[str]:
        return self.detector.missing_faces

    @property
    def hold(self) -> float:
        return self.detector.hold

    # ---------------------------------------------------------------- result
    def result(self) -> CalibrationResult:
        """The calibration, or a CalibrationError saying what cannot be calibrated and what to do."""
        rows, used = pose_table(self.detector.accepted(), self.rejected)
        used = [(k, p) for k, p in used if k not in self.left_out]
        for k in sorted(self.left_out):
            rows[k - 1].update(fate="left out", reason=f"on request: {LEFT_OUT_WHY[rows[k - 1]['fate']]}")
        if not used and self.any_orientation:
            raise CalibrationError("no usable still pose was found",
                                   f"hold the sensor still for {self.detector.min_hold:g} s in each of at least "
                                   f"{MULTI_MIN_DISTINCT} orientations")
        if not used:
            self._require_six_faces(set())   # says which faces were held and why they did not count
        stats = [PoseStats.from_samples(p.samples, p.face, f"pose {k}") for k, p in used]
        model = self.model
        # a wander that holds through a pose reads as a tilt: when the noise outlasts the holds, a pose found off
        # its face is refused naming the noise, not the placement
        axes = pooled_axes([p.samples for _, p in used])
        slow = slow_memory(axes, [p.t for _, p in used])
        try:
            if model == "auto":
                model = choose_model(stats, self.detector.g, self.pose_flatness_deg)
        except CalibrationError as exc:
            self._refuse_off_face(exc, stats, axes, slow)
        if model != "multi-position":
            try:
                tilts = check_faces(stats, self.pose_flatness_deg, self.detector.g)
            except CalibrationError as exc:
                self._refuse_off_face(exc, stats, axes, slow, "use --model multi-position or place the face flat")
            self._require_six_faces({t.face for t in tilts})
            for s, tilt in zip(stats, tilts, strict=True):
                s.face = tilt.face
            for (k, _), tilt in zip(used, tilts, strict=True):
                rows[k - 1].update(face=tilt.face, angle_deg=tilt.angle_deg)
        poses = [p for _, p in used]
        # the noise within the poses: correlation (u of each mean from n / tau), per-axis sd, drift
        faces = [s.face if model != "multi-position" else None for s in stats]
        noise = still_noise([p.samples for p in poses], [p.t for p in poses], faces)
        sample_covs = [s.cov for s in stats]
        for i, s in enumerate(stats):
            s.cov = sample_covs[i] * noise.pose_covariance_scale(i)
        for (k, pose), pose_noise in zip(used, noise.per_pose, strict=True):
            rows[k - 1]["noise"] = {"sd": np.std(pose.samples, axis=0, ddof=1).tolist(),
                                    "tau_samples": [w.tau if w else None for w in pose_noise],
                                    "ljung_box_p": [w.p_value if w else None for w in pose_noise]}
        settings = {**self.settings_used(), "pose_flatness_deg": self.pose_flatness_deg,
                    "model_requested": self.model}
        if self.left_out:
            settings["skip_poses"] = sorted(self.left_out)
        result = build_result(poses, stats, rows, model, self.method, settings, noise)
        # noise slower than a hold: its model checked against the scatter of the holds, before the drift's terms
        # take the degrees of freedom that show it (``slow_model_check``)
        if noise.slow is not None:
            refusal = slow_model_check(noise, result.quality["chi2"], result.quality["dof"],
                                       [p.samples for p in poses], [p.t for p in poses])
            if refusal is not None:
                raise CalibrationError(refusal, f"{SETTLE_HINT}, or hold the faces again over a longer run")
            for i, s in enumerate(stats):
                s.cov = sample_covs[i] * noise.pose_covariance_scale(i)
            result = build_result(poses, stats, rows, model, self.method, settings, noise)
        # the faces held again, read on this first fit's calibrated magnitudes (free of the hand's tilt)
        if not drift_checks(noise, [p.samples for p in poses], [p.t for p in poses], faces, result.correction):
            return result
        _drift_rates(noise)
        return _referred_to_middle(poses, stats, rows, model, self.method, settings, noise)

    def _refuse_off_face(self, exc: CalibrationError, stats: list[PoseStats], axes, slow: str | None,
                         hint: str | None = None) -> None:
        """Poses read off their faces: refuse naming what the data show.  Noise that outlasts a hold
        (``slow_memory``) reads as a tilt, and so does an offset that wanders (``offset_wander``: the gravity
        magnitudes, which no tilt changes, scatter as much); else it is the placement.  The noise's memory is said
        first: it is measured within the holds, and the magnitudes' test takes each mean's noise from n / tau,
        which such noise makes too small (its wander would be found wherever the noise is slow)."""
        if slow is not None:
            raise CalibrationError(f"{slow}; {exc.message}", SETTLE_HINT) from None
        wander = offset_wander(stats, self.detector.g, axes)
        if wander is not None:
            raise CalibrationError(wander, WANDER_HINT) from None
        if hint is None:
            raise exc
        raise CalibrationError(exc.message, hint) from None

    def _require_six_faces(self, present: set[str]) -> None:
        missing = [f for f in FACES if f not in present]
        if not missing:
            return
        found = ", ".join(f for f in FACES if f in present) or "none"
        # Say why a face that was held did not count (too short, moved, ...).
        why = []
        for face in missing:
            tried = [p for p in self.rejected if p.face == face]
            if tried:
                reasons = sorted({f"{p.problem.replace('_', ' ')} at t = {p.start:.1f} s" for p in tried})
                why.append(f"{face} held but {'; '.join(reasons)}")
        detail = f"; {', '.join(why)}" if why else ""
        raise CalibrationError(f"only {6 - len(missing)} of 6 faces found (have {found}; missing "
                               f"{', '.join(missing)}{detail})",
                               f"hold each missing face down still for at least {self.detector.min_hold:g} s")

    def settings_used(self) -> dict:
        d = self.detector
        return {**self.gravity.to_dict(), "rate": d.rate, "hold": d.hold, "min_hold": d.min_hold,
                "window": d.window_n / d.rate, "still_threshold": d.still_threshold,
                "motion_factor": d.motion_factor, "trim": d.trim_n / d.rate, "lift": d.lift_n / d.rate,
                "live_face_tolerance_deg": d.face_tolerance_deg, "drift_tolerance": d.drift_tolerance,
                "settle": d.settle_blocks * d.drift_block_n / d.rate,
                "full_scale": d.full_scale}


FATES = {None: "used", "too_short": "too short", "moved": "moved", "saturated": "saturated"}
LEFT_OUT_WHY = {"used": "it was usable", "too short": "it was too short", "moved": "it moved",
                "saturated": "it saturated"}


def _check_model(model: str, method: str) -> None:
    if model not in MODEL_CHOICES:
        raise CalibrationError(f"unknown model {model!r}", f"use one of {', '.join(MODEL_CHOICES)}")
    if method == "paper" and model != "paper":
        raise CalibrationError("the paper's Nelder-Mead scheme exists only for the 9-parameter model",
                               "use --method vp, or --model paper")


def pose_table(accepted: list[Pose], rejected: list[Pose]) -> tuple[list[dict], list[tuple[int, Pose]]]:
    """Every still pose found, in time order and numbered from 1, with its fate; and the (number, pose) used.

    Stretches with fewer than 2 samples left once their edges are trimmed (a hand pausing between poses)
    are not poses and are left out."""
    every = sorted([p for p in [*accepted, *rejected] if p.t.size >= 2], key=lambda p: p.start)
    rows, used = [], []
    for k, p in enumerate(every, start=1):
        rows.append({"index": k, "start": p.start, "stop": p.stop, "n": len(p.samples), "face": p.face, "angle_deg": p.angle_deg, "fate": FATES[p.problem],
                     "reason": p.detail})
        if p.problem is None:
            used.append((k, p))
    return rows, used


def choose_model(stats: list[PoseStats], g: float, flatness_deg: float) -> str:
    """auto: six-face when every pose is near a face, multi-position when not (and enough orientations)."""
    limit = FACE_REFUSE_SD * flatness_deg
    tilts = face_tilts(stats, g)
    off = [t for t in tilts if t.angle_deg > limit]
    if not off:
        return "six-face"
    n_distinct = distinct_orientations(np.array([s.mean for s in stats]))
    if n_distinct >= MULTI_MIN_DISTINCT:
        return "multi-position"
    worst = max(off, key=lambda t: t.angle_deg)
    raise CalibrationError(
        f"{len(off)} of {len(stats)} poses are more than {limit:.1f} degrees from a face ({worst.name} is "
        f"{worst.angle_deg:.1f} from {worst.face}) and the poses hold only {n_distinct} distinct orientations",
        f"place each face flat for six-face mode, or hold the sensor still in at least {MULTI_MIN_DISTINCT} "
        "orientations for --model multi-position")


def _units(name: str) -> str:
    return "rad" if name.startswith("angle") else "m/s^2" if name[0] in "ob" else "1"


def parameter_meaning(names: list[str]) -> str:
    """What the fitted parameters are (the fits estimate in three forms; the correction is one form)."""
    if names[0].startswith("angle_"):
        return ("the paper's form calibrated = G R(angle) raw + c: gain_k (G) and offset_k (c) correct the "
                "reading, so offset_k is the correction's shift after the gain, about -b_k (C = G R, b = -C^-1 c)")
    if names[0].startswith("K_"):
        return "the sensor's own form raw = K a + o: K = C^-1 and o = b of the correction"
    return "the correction itself: C_ij and b_k of calibrated = C (raw - b)"


def _drift_rates(noise: StillNoise) -> None:
    """Each raw offset's drift rate from the faces held again (``noise.drift["revisits"]``, their offset
    changes read on a first fit's calibrated magnitudes, free of the hand's tilt), weighted by their u."""
    weights, rates = [[] for _ in range(3)], [[] for _ in range(3)]
    for r in noise.drift["revisits"]:
        k = AXES.index(r["face"][1])
        span = r["last"] - r["first"]
        weights[k].append(span**2 / r["u"] ** 2)
        rates[k].append(r["change"] / span)
    for k in range(3):
        if weights[k]:
            w = np.array(weights[k])
            noise.drift_rate[k] = float(np.sum(w * np.array(rates[k])) / np.sum(w))
            noise.drift_rate_u[k] = float(1.0 / np.sqrt(np.sum(w)))
    noise.drift["rate"] = noise.drift_rate.tolist()
    noise.drift["rate_u"] = noise.drift_rate_u.tolist()


def _referred_to_middle(poses: list[Pose], stats: list[PoseStats], rows: list[dict], model: str, method: str,
                        settings: dict, noise: StillNoise) -> CalibrationResult:
    """The fit on pose means referred to the middle of the run, the drift of the axes held again fitted.

    Each pose mean m_i becomes m_i - r (t_i - t_mid) - kappa q(t_i) (t_i the pose's centre, t_mid the
    count-weighted mean of the centres: the time the offsets stand for).  r, per axis with a face held again,
    is the drift rate; kappa, per axis with a face held three times far apart (``noise._shape``), the drift's
    curvature, with q(t) = (t - t_a)(t - t_b) / 2 through that face's first and last holds, less its average
    over the run (the offsets stand for the run's average, which a curving drift moves too).  Both are the
    model's own: the values that minimise the fit's lack of fit, its whitened residuals profiled over the
    other parameters (Gauss-Newton from the revisits' estimates; the Jacobian, the six-face fit's own response
    to the shift of the means, which is linear in the terms, or for the exact-face fits one refit per term two
    of its u away); cov = (J^T J)^-1.  A rate taken from the revisits alone would disagree with the fit's tilts
    and misalignment and show as lack of fit.  Their u enters the result's covariance through the fit's
    sensitivity to them (the same Jacobian): cov += S cov(r, kappa) S^T.  Their degrees of freedom go into
    them, so the lack-of-fit test has that many fewer.  An axis held again but not three times far apart keeps a stated allowance for a curving drift
    (``noise.drift_bend``, type B), and the uncertainty line names the check it could not make."""
    centres = np.array([float(np.mean(p.t)) for p in poses])
    counts = np.array([len(p.t) for p in poses], dtype=float)
    middle = float(np.average(centres, weights=counts))
    shaped = {AXES.index(e["axis"]): e for e in noise.drift.get("shape", {}).get("faces", [])}

    # per axis held again, the centres of the two holds that fix its rate: a curving drift's departure from
    # the straight line is zero there (the face held three times when there is one; else the two holds
    # furthest apart)
    anchors: dict[int, tuple[float, float]] = {}
    for r in noise.drift.get("revisits") or []:
        k = AXES.index(r["face"][1])
        if k not in anchors or r["last"] - r["first"] > anchors[k][1] - anchors[k][0]:
            anchors[k] = (float(r["first"]), float(r["last"]))
    for k, e in shaped.items():
        anchors[k] = (e["times"][0], e["times"][2])
    bend_shape = np.zeros((len(poses), 3))
    for k, (t_a, t_b) in anchors.items():
        bend_shape[:, k] = (centres - t_a) * (centres - t_b) / 2.0
        bend_shape[:, k] -= np.average(bend_shape[:, k], weights=counts)

    def referred(rate: np.ndarray, bend: np.ndarray | None = None) -> tuple[list[PoseStats], list[np.ndarray]]:
        shift = np.outer(centres - middle, rate) + (bend_shape * bend if bend is not None else 0.0)
        return ([PoseStats(s.mean - d, s.cov, s.n, s.face, s.name) for s, d in zip(stats, shift, strict=True)],
                [p.mean - d for p, d in zip(poses, shift, strict=True)])

    def fit(rate: np.ndarray, bend: np.ndarray | None = None,
            shifts: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, tuple | None]:
        """The model's whitened lack-of-fit residuals (no inflation: only their shape in r counts) and its
        reported parameters then C and b, as ``build_result`` fits them; with ``shifts`` (k, P, 3: changes of
        the pose means per unit of k terms; six-face only) their derivatives along each, (dz (P, k), dp (k, ..)),
        from the fit's own Jacobian."""
        referred_stats, means = referred(rate, bend)
        if model in MODELS:
            data = PoseData([s.face for s in stats], means, [len(p.samples) for p in poses],
                            [p.within_ss for p in poses], settings["g"])
            f = fit_model(data, model, method if model == "paper" else "vp")
            scale = f.sigma * np.sqrt(float(np.mean(noise.tau)) if noise.correlated else 1.0)
            z = (np.sqrt(counts)[:, None] * f.residuals).ravel() / scale
            return z, np.concatenate([f.values, f.correction.matrix.ravel(), f.correction.bias]), None
        f = fit_six_face(referred_stats, "paper", settings["pose_flatness_deg"], settings["g"],
                         inflation="none", wander_var=noise.wander_var, mean_shifts=shifts)
        # with the slow-noise wander as the fit weighs the poses: the rates' u must carry the wander the
        # poses carry (the tilt-free gravity magnitudes, whose chi^2 is the fit's lack of fit)
        corr = np.concatenate([f.correction.matrix.ravel(), f.correction.bias])
        z = magnitude_z(corr, referred_stats, settings["g"], noise.wander_var)[0]
        derivatives = None
        if shifts is not None:
            dp = f.mean_response
            dz = magnitude_z_response(corr, dp[:, len(f.values):], referred_stats, shifts, settings["g"],
                                      noise.wander_var)
            derivatives = (dz, dp)
        return z, np.concatenate([f.values, corr]), derivatives

    axes = [k for k in range(3) if noise.drift_rate_u[k] > 0]
    bent = [k for k in sorted(shaped) if k in axes]
    m, q = len(axes), len(bent)

    def split(theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        rate, bend = noise.drift_rate.copy(), np.zeros(3)
        rate[axes], bend[bent] = theta[:m], theta[m:]
        return rate, bend

    start = np.concatenate([noise.drift_rate[axes], [shaped[k]["curvature"] for k in bent]])
    steps = 2.0 * np.concatenate([noise.drift_rate_u[axes], [shaped[k]["curvature_u"] for k in bent]])
    # the axes held again whose curvature is not measured: an allowance for it below, through the fit's
    # response to it
    allowed = [k for k in sorted(anchors) if k not in bent]
    bend_response = {}
    if model in MODELS:
        # the exact-face fits (the paper's, Nelder-Mead over the angles among them) give no Jacobian at their
        # solution: one refit per term, two of its u away (the fits are linear in them to well within that)
        z0, p0, _ = fit(*split(start))
        jz, jp = [], []
        for i in range(m + q):
            z, p, _ = fit(*split(start + steps[i] * np.eye(m + q)[i]))
            jz.append((z - z0) / steps[i])
            jp.append((p - p0) / steps[i])
        jz, jac = np.column_stack(jz), np.column_stack(jp)
    else:
        # the six-face fit's own response to the terms: the pose means move linearly in the rates and
        # curvatures (each term's column of ``referred``'s shift), and the fit gives its solution's derivative
        # in the means from its own Jacobian (fit_six_face's mean_shifts): one fit instead of one per term
        # (six refits with 3 rates and 3 curvatures, most of the calibration's time).  This is the tangent:
        # refits a hundredth of a u apart agree with it to about 1e-6; the two-u secant it replaces was off by
        # up to 1e-2 of a column (the fit's curvature over two u), which moved the terms by up to 1e-2 of their
        # u and C, b by up to 6e-3 of theirs on the held-out simulator's static conditions.
        unit = np.eye(3)
        columns = ([np.outer(centres - middle, unit[k]) for k in axes] +
                   [np.outer(bend_shape[:, k], unit[k]) for k in bent] +
                   [np.outer(bend_shape[:, k], unit[k]) for k in allowed])
        # ``referred`` subtracts the shift from the means
        z0, p0, (dz, dp) = fit(*split(start), shifts=-np.array(columns))
        jz, jac = dz[:, :m + q], dp[:m + q].T
        bend_response = {k: dp[m + q + j] for j, k in enumerate(allowed)}
    info = jz.T @ jz
    eigenvalues = np.linalg.eigvalsh(info) if m + q else np.zeros(0)
    # information that is not positive in every direction is not a profile to trust: then the revisits' own
    # estimates and u stand
    if m + q and np.all(eigenvalues > 1e-9 * max(float(np.max(np.abs(eigenvalues))), 1e-300)):
        theta_cov = np.linalg.inv(info)
        theta = start - theta_cov @ (jz.T @ z0)
        from_ = "fit"
    else:
        theta, theta_cov, from_ = start, np.diag((steps / 2.0) ** 2), "revisits"
    rate, bend_fitted = split(theta)
    # a drift that the middle holds show is not a line (noise._shape rejected at ALPHA on its own, whether or
    # not the drift family warns): the parabola through three holds fixes it at those holds only; between and
    # beyond them the drift may leave the parabola by as much as the curve it had to bend (type B, normal):
    # each measured curvature's u grows by its own size
    off_line = q > 0 and noise.drift["shape"].get("p_value", 1.0) < ALPHA
    if off_line:
        theta_cov = theta_cov + np.diag(np.r_[np.zeros(m), theta[m:] ** 2])
    theta_u = np.sqrt(np.clip(np.diag(theta_cov), 0.0, None))
    noise.drift_rate = rate
    noise.drift_rate_u = np.zeros(3)
    noise.drift_rate_u[axes] = theta_u[:m]
    noise.drift["rate"], noise.drift["rate_u"] = noise.drift_rate.tolist(), noise.drift_rate_u.tolist()
    noise.drift["rate_from"] = from_
    if q:
        noise.drift["shape"]["fitted"] = {"axes": [AXES[k] for k in bent], "curvature": theta[m:].tolist(),
                                          "curvature_u": theta_u[m:].tolist(),
                                          "anchors_s": [list(anchors[k]) for k in bent],
                                          "u_widened_by_the_curvature": bool(off_line)}
    referred_stats, means = referred(rate, bend_fitted)
    # before the result is built: its warning and record go with the noise's
    bend = drift_bend(noise, anchors, middle, measured=bent)
    base = build_result(poses, referred_stats, rows, model, method, settings, noise, means=means, spent_dof=m + q)
    extra = jac @ theta_cov @ jac.T
    # the drift's curvature allowed on the axes whose shape was not measured (type B): through the same
    # fits, one step of its sd per such axis (the departure is linear in it: the six-face fit's response
    # above, the exact-face fits' central differences)
    if bend:
        for j, k in enumerate(sorted(anchors)):
            step = np.zeros(3)
            step[k] = bend["allowance"]["curvature_sd"][j]
            if k in allowed and step[k] > 0:
                column = (bend_response[k] * step[k] if k in bend_response else
                          (fit(rate, bend_fitted + step)[1] - fit(rate, bend_fitted - step)[1]) / 2.0)
                extra = extra + np.outer(column, column)
        bend["allowance"]["on"] = [AXES[k] for k in allowed]
    n_par = len(base.parameters)
    cov = np.array(base.covariance, dtype=float) + extra[:n_par, :n_par]
    corr_cov = np.array(base.correction.covariance, dtype=float) + extra[n_par:, n_par:]
    base.covariance = cov
    base.correction = Correction(base.correction.matrix, base.correction.bias, corr_cov)
    base.parameters = {n: Estimate(e.value, float(np.sqrt(max(cov[k, k], 0.0))), e.unit)
                       for k, (n, e) in enumerate(base.parameters.items())}
    base.quality["uncertainty_source"] += (f"; pose means referred to the middle of the run (t = {middle:.1f} s) "
                                           f"with the offset drift rate on {_names(axes)} fitted (faces held again)")
    if q:
        base.quality["uncertainty_source"] += f" and its curvature on {_names(bent)} (a face held three times)"
        if off_line:
            base.quality["uncertainty_source"] += (" (the drift is not a straight line: each curvature's u widened "
                                                   "by its own size, for a drift that leaves the parabola between "
                                                   "the holds)")
    if bend and allowed:
        departure = max(d for d, k in zip(bend["allowance"]["largest_departure"], sorted(anchors), strict=True)
                        if k in allowed)
        base.quality["uncertainty_source"] += (
            f"; drift shape not checked on {_names(allowed)} (no face of {'that axis' if len(allowed) == 1 else 'those axes'} "
            f"held three times far apart): an allowance for a drift that curves instead "
            f"({bend['allowance']['distribution']}: up to {departure:.2g} m/s^2 off the straight line at a pose, 1 sd)")
    base.quality["drift_referred_to"] = middle
    # the revisits' degrees of freedom went into the rates and curvatures: the lack-of-fit test has that many
    # fewer (none left with six faces and three again, twice; the wizard's last round, the opposite faces once
    # more, leaves some)
    dof = int(base.quality["dof"])   # build_result took the m + q out of every test
    if q:
        noise.drift["shape"]["fitted"]["tested_between_holds"] = dof > 0
        noise.drift["shape"]["fitted"]["dof_between_holds"] = max(dof, 0)
    if q and dof > 0:
        # the wizard's opposite faces once more leave a few degrees of freedom: enough to see a drift that leaves
        # the curve at the opposite face, not one that is back on it at every hold (docs/static.md, "What twelve
        # holds cannot see": a bump back to zero at every +x hold): u still assumes that much
        base.quality["uncertainty_source"] += (
            f"; the drift's curve between the holds is tested with {dof} degree{'s' if dof != 1 else ''} of "
            "freedom: a drift that is back on the curve at every hold would still go unseen")
    if q and dof <= 0:
        # per axis the face held three times and its opposite face fix the offset, the gain, the rate and the
        # curvature exactly: what the parabola misses between and beyond those holds (the run's other holds, the
        # opposite face's) leaves no misfit to see, and the poses' own trends are about 5x too coarse to bound it
        # (docs/static.md, "What twelve holds cannot see"): say what u assumes
        opposite = ", ".join(opposite_face(shaped[k]["face"]) for k in sorted(bent, key=lambda k: shaped[k]["times"][0]))
        base.quality["uncertainty_source"] += ("; u assumes the drift follows that curve between the holds: no "
                                               f"degree of freedom is left to test it ({opposite} held once more, "
                                               "as the wizard asks, would leave some)")
    base.quality["p_value"] = float(chi2_dist.sf(base.quality["chi2"], dof)) if dof > 0 else float("nan")
    return base


def _names(axes: list[int]) -> str:
    return ", ".join(AXES[k] for k in axes)


def build_result(poses: list[Pose], stats: list[PoseStats], rows: list[dict], model: str, method: str,
                 settings: dict, noise: StillNoise, means: list[np.ndarray] | None = None,
                 spent_dof: int = 0) -> CalibrationResult:
    """Fit ``model`` (exact-face paper / affine, six-face, multi-position) and package the CalibrationResult.

    ``rows``: every pose found (``pose_table``); ``poses`` / ``stats`` the ones used, in the same order;
    ``means`` the pose means to fit when not the poses' own (referred to the middle of the run);
    ``spent_dof`` the degrees of freedom that referring them used (the drift's rates and curvatures): every
    lack-of-fit test, and the inflation it decides, has that many fewer."""
    g = settings["g"]
    data = PoseData([s.face for s in stats], means if means is not None else [p.mean for p in poses],
                    [len(p.samples) for p in poses],
                    [p.within_ss for p in poses], g)
    warnings = []
    if model in MODELS:
        fit = fit_model(data, model, method if model == "paper" else "vp")
        corr, source = fit.correction, "noise of the pose means (faces assumed exact: a tilted pose biases the fit)"
        names, values, uncertainty, units, cov = fit.names, fit.values, fit.uncertainty, fit.units, fit.covariance
        chi2, label, method_used = fit.chi2, fit.model, fit.method
        dof = fit.dof - spent_dof
        p_value = float(chi2_dist.sf(chi2, dof)) if dof > 0 else float("nan")
        n_eval, seconds = fit.n_evaluations, fit.seconds
        n_obs = 3 * int(np.sum(data.counts))
        extra = {"model_selection": {model: {"chi2": fit.chi2, "dof": fit.dof, "p_value": fit.p_value,
                                             "aic": fit.aic, "bic": fit.bic(n_obs), "n_parameters": len(fit.names)}}}
        calibrated_residuals = [corr.apply(p.samples) - face_reference(f, g) for p, f in zip(poses, data.faces, strict=True)]
        extra["faces"] = [{"face": f, "start": p.start, "stop": p.stop, "n": len(p.samples), "noise_sd": p.noise_sd,
                           "residual": (corr.matrix @ lof).tolist(), "residual_norm": float(np.linalg.norm(corr.matrix @ lof))}
                          for p, f, lof in zip(poses, data.faces, fit.residuals, strict=True)]
        arrays = {"pose_references": data.references, "pose_residuals": fit.residuals}
        if noise.correlated:
            # exact-face models weigh every pose by one pooled sigma: the mean of the axes' tau scales it
            tau = float(np.mean(noise.tau))
            cov, uncertainty, chi2 = cov * tau, uncertainty * np.sqrt(tau), chi2 / tau
            corr = Correction(corr.matrix, corr.bias, corr.covariance * tau)
            p_value = float(chi2_dist.sf(chi2, dof)) if dof > 0 else float("nan")
            source = f"noise of the pose means x mean integrated autocorrelation time {tau:.3g} (correlated noise)"
        if dof > 0 and p_value < CHI2_ALPHA:
            # The data disagree with exact faces: the stated u grows with the misfit (Birge ratio), the
            # numbers stay the fit's.  Tilted poses are better served by the six-face model, which says so.
            birge = float(np.sqrt(chi2 / dof))
            cov, uncertainty = cov * birge**2, uncertainty * birge
            corr = Correction(corr.matrix, corr.bias, corr.covariance * birge**2)
            source = (f"noise of the pose means x Birge ratio {birge:.3g} (χ² = {chi2:.3g} for {dof} degrees of freedom: "
                      "the poses are not exact faces)")
            warnings.append(f"the poses disagree with the {label} model beyond their noise (χ² = "
                            f"{chi2:.3g} for {dof} degrees of freedom): table not level, cube not square or a pose "
                            f"not flat? The uncertainties are scaled by the Birge ratio {birge:.3g}; the six-face "
                            "model (--model six-face) allows for tilted poses.")
        if fit.extra.get("converged") is False:
            warnings.append(f"Nelder-Mead stopped before converging: {fit.extra.get('message')}")
    else:
        if model == "six-face":
            fit = fit_six_face(stats, "paper", settings["pose_flatness_deg"], g, wander_var=noise.wander_var,
                               spent_dof=spent_dof, between=noise.between_pose_covariance())
            method_used = "map"
        else:
            fit = fit_multiposition(stats, g, wander_var=noise.wander_var, spent_dof=spent_dof,
                                    between=noise.between_pose_covariance())
            method_used = "lm"
            if fit.dof <= 0:
                # nothing is left to test the fit with: the result must not read as "no warnings"
                spent = (f" and the drift's {spent_dof} terms" if spent_dof else "")
                warnings.append(f"the fit could not be tested: {len(stats)} poses fix the 9 parameters{spent} "
                                "exactly (no degree of freedom left for a lack-of-fit test), so a pose that moved or a "
                                f"model that does not hold would go unseen; hold at least {MULTI_ASKED} "
                                f"distinct orientations, {MULTI_ASKED_WHY}")
        corr, source, label = fit.correction, fit.uncertainty_source, model
        names, values, uncertainty, cov = fit.names, fit.values, fit.uncertainty, fit.covariance
        units = [_units(n) for n in names]
        chi2, dof, p_value = fit.chi2_before, fit.dof, fit.p_value
        n_eval, seconds = fit.n_evaluations, fit.seconds
        calibrated_residuals = [np.linalg.norm(corr.apply(p.samples), axis=1) - g for p in poses]
        extra = {"pose_flatness_deg_used": fit.pose_flatness_deg, "repeatability_sd": fit.repeatability_sd,
                 "chi2_after_inflation": fit.chi2, "gauge": fit.gauge, **fit.extra}
        if fit.tilts_deg is not None:
            extra["tilts_deg"] = fit.tilts_deg
        arrays = {}
        notes = list(fit.extra.get("notes", []))
        warnings += notes
        if fit.inflated and fit.dof > 0 and fit.p_value < CHI2_ALPHA:
            # the magnitudes' own test rejected (the tilts' says so in its note): say what was seen, once; the
            # uncertainty line says what was done about it
            warnings.append(f"the poses disagree with the model beyond their noise (χ² = {chi2:.3g} for {dof} "
                            f"degrees of freedom, p = {p_value:.2g}): the uncertainty allows for it (see the "
                            "uncertainty line)")
    magnitudes = np.linalg.norm(corr.apply(data.means), axis=1) - g
    used_rows = [r for r in rows if r["fate"] == "used"]
    for r, m in zip(used_rows, magnitudes, strict=True):
        r["magnitude_residual"] = float(m)
    all_res = np.concatenate([np.ravel(r) for r in calibrated_residuals])
    # u(g) (with_local_gravity below): C scales with the g used (b does not), and so do the parameters that
    # are C's (gains, C_ij, the paper model's calibrated-domain offsets c = -G R b); K = C^-1 the other way
    u_g = float(settings.get("g_u") or 0.0)
    scaled = {n: 1 if n.startswith(("gain_", "C_", "offset_")) else -1
              for n in names if n.startswith(("gain_", "C_", "offset_", "K_"))}
    if noise.slow is not None:
        source += "; " + noise.slow_model_note()
    elif noise.correlated and model not in MODELS:
        source += ("; each pose mean's u from the effective sample count n / tau (the noise is correlated in time)"
                   if noise.short_correlated else
                   f"; each pose mean's u widened {np.sqrt(noise.slow_factor):.1f}x for noise slower than a pose")
    warnings += noise.warnings + noise.drift_warnings()
    quality = {
        "residual_rms": float(np.sqrt(np.mean(all_res**2))),
        "noise": noise.to_dict(),
        "noise_sd": data.noise_sd,
        "noise_sd_axes": noise.sd.tolist(),
        "n_samples": int(np.sum(data.counts)),
        "n_poses": len(poses),
        "n_poses_found": len(rows),
        "chi2": chi2,
        "dof": dof,
        "p_value": p_value,
        "uncertainty_source": source,
        "max_magnitude_residual": float(np.max(np.abs(magnitudes))),
        "n_evaluations": n_eval,
        "fit_seconds": seconds,
        **extra,
    }
    parameters = {n: Estimate(float(v), float(u), unit)
                  for n, v, u, unit in zip(names, values, uncertainty, units, strict=True)}
    return CalibrationResult(
        procedure="static",
        method=method_used,
        model=label,
        correction=corr,
        parameters=parameters,
        covariance=cov,
        parameter_names=list(names),
        quality=quality,
        arrays={"pose_means": data.means, **arrays, "pose_times": np.array([[p.start, p.stop] for p in poses])},
        settings={**settings, "faces": list(data.faces)},
        warnings=warnings,
        details={"poses": rows},
        parameter_meaning=parameter_meaning(list(names)),
    ).with_local_gravity(LocalGravity(g, u_g, settings.get("g_source", "")), scaled)


# ------------------------------------------------------------------ files

def settings_values(given: dict) -> dict:
    """Every declared setting's value: those given (checked as a flag would be), the others' defaults."""
    unknown = sorted(set(given) - {s.name for s in SETTINGS})
    if unknown:
        raise TypeError(f"static calibration has no setting {', '.join(unknown)}")
    return {s.name: s.parse(given.get(s.name)) for s in SETTINGS}


def detect_poses(rec: Recording, **values) -> StaticProcedure:
    """A whole recording fed through a StaticProcedure as one chunk; returns it (``.poses``, ``.rejected``).

    ``values``: any of the declared SETTINGS by name; the others take their defaults."""
    values = settings_values(values)
    if len(rec) < 2:
        raise DataError("the recording holds fewer than two samples")
    si = rec.to_si()   # refuses data in other units than declared; unit g means standard g
    if not np.all(np.isfinite(si.acc)):
        raise DataError("the recording holds NaN or infinite values")
    proc = StaticProcedure.create(values, {**rec.meta, "rate": si.rate})
    proc.feed(si)
    proc.finish()
    return proc


def calibrate_static(rec: Recording, skip_poses=(), **values) -> CalibrationResult:
    """Six-face calibration of a recording (the batch form); bad data raise one clear DataError/CalibrationError.

    ``values``: any of the declared SETTINGS by name (model, method, g, min_hold, still_threshold).
    ``skip_poses``: pose numbers (the pose table's, in time order from 1) the operator leaves out, e.g. a
    face that moved and was held again later; a moved or saturated pose not left out refuses the recording,
    because what to do with a pose a person captured is theirs to decide."""
    proc = detect_poses(rec, **values)
    rows, _ = pose_table(proc.detector.accepted(), proc.rejected)
    skip = frozenset(int(k) for k in skip_poses)
    unknown = sorted(k for k in skip if not 1 <= k <= len(rows))
    if unknown:
        raise DataError(f"there is no pose {', '.join(map(str, unknown))} to leave out: the recording holds "
                        f"{len(rows)} still poses, numbered from 1 in time order",
                        "the text report's pose table numbers them, as does --json's details.poses")
    for row in rows:
        if row["fate"] in ("moved", "saturated") and row["index"] not in skip:
            again = [r["index"] for r in rows if r["fate"] == "used" and r["face"] == row["face"]
                     and r["index"] not in skip]
            held = (f"; {row['face']} down was held still again as pose {', '.join(map(str, again))}"
                    if again else "")
            raise DataError(f"pose {row['index']}: {row['reason']}{held}",
                            f"or leave pose {row['index']} out with --skip-pose {row['index']}")
    proc.left_out = skip
    result = proc.result()
    if skip:
        result.warnings.append(
            "left out on the operator's request: " + "; ".join(
                f"pose {r['index']} ({r['face']} down, {r['start']:.1f}-{r['stop']:.1f} s; "
                f"{r['reason'].removeprefix('on request: ')})"
                for r in result.details["poses"] if r["index"] in skip))
    result.settings["recording"] = rec.meta.get("source") or rec.meta.get("device")
    return result
