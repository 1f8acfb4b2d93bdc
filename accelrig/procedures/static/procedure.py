"""The six-face static calibration as a Procedure (accelrig.procedures.contract), live and for files.

One object serves the live flow (the TUI feeds ring-buffer chunks as they
arrive and shows the events) and the batch one (``calibrate_static`` feeds a
whole recording through the same object as one chunk), so a recording gives
the same poses whichever way it is processed.

    proc = StaticProcedure.create(values, device)   values: the declared SETTINGS, parsed
    proc.feed(chunk) -> events      contract Events; data["kind"]: hold_still, captured, moved, ...
    proc.act("redo", face="+x")     forget a face to take it again
    proc.finish()                   the data ended: close the pose in progress
    proc.progress, proc.done        faces done / 6; all six in
    proc.faces                      the face grid's details (done, held, hold fraction, ...)
    proc.result()                   the CalibrationResult (model and method from the settings)
"""

from __future__ import annotations

import numpy as np

from accelrig.errors import CalibrationError, DataError
from accelrig.geometry import FACES
from accelrig.procedures.contract import Event, Procedure
from accelrig.procedures.static.fit import MODELS, PoseData, face_reference, fit_model
from accelrig.procedures.static.poses import Pose, PoseDetector, full_scale_of, pose_event
from accelrig.procedures.static.settings import SETTINGS
from accelrig.recording import Recording
from accelrig.result import CalibrationResult, Estimate
from accelrig.units import STANDARD_GRAVITY

# Seconds a face is held before the live flow says "captured" (a pose still counts from min_hold on).
HOLD = 4.0


class StaticProcedure(Procedure):
    """Six faces in any order (repeats add data), each held still; then the fit."""

    name = "static"
    title = "six-face static calibration"
    settings = SETTINGS
    actions = {"redo": "redo a face"}   # act("redo", face="+x"): take that face again

    def __init__(self, rate: float, g: float = STANDARD_GRAVITY, model: str = "auto", method: str = "vp",
                 **detection):
        """``detection``: PoseDetector's settings (hold, min_hold, still_threshold, full_scale, ...)."""
        if model not in (*MODELS, "auto"):
            raise CalibrationError(f"unknown model {model!r}", "use paper, affine or auto")
        self.model, self.method = model, method
        self.detector = PoseDetector(rate, g=g, **detection)
        self._started = False

    @classmethod
    def create(cls, values: dict, device: dict) -> StaticProcedure:
        rate = device.get("rate") or device.get("nominal_rate")
        if not rate:
            raise DataError("the sample rate is not known", "give the rate of a file without a t column (--rate)")
        return cls(rate, g=values["g"], model=values["model"], method=values["method"],
                   min_hold=values["min_hold"], hold=max(HOLD, values["min_hold"]),
                   still_threshold=values["still_threshold"], full_scale=full_scale_of(device))

    # ------------------------------------------------------------- contract
    def feed(self, chunk) -> list[Event]:
        events = []
        if not self._started and len(chunk.t):
            self._started = True
            events.append(pose_event("start", "put the sensor down on any face and hold it still",
                                     float(chunk.t[0])))
        return events + self.detector.feed(chunk.t, chunk.acc)

    def act(self, action: str, **arguments) -> list[Event]:
        if action != "redo":
            return super().act(action, **arguments)
        if "face" not in arguments:
            raise DataError("redo needs the face to take again", "faces are +x, -x, +y, -y, +z, -z")
        return self.detector.forget(arguments["face"])

    def finish(self) -> list[Event]:
        return self.detector.finish()

    @property
    def progress(self) -> float:
        return len(self.faces_done) / len(FACES)

    @property
    def done(self) -> bool:
        return not self.missing_faces

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
        missing = self.missing_faces
        if missing:
            found = ", ".join(self.faces_done) or "none"
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
        poses = self.detector.accepted()
        return build_result(pose_data(poses, self.detector.g), poses, self.model, self.method, self.settings_used())

    def settings_used(self) -> dict:
        d = self.detector
        return {"g": d.g, "rate": d.rate, "hold": d.hold, "min_hold": d.min_hold,
                "window": d.window_n / d.rate, "still_threshold": d.still_threshold,
                "motion_factor": d.motion_factor, "trim": d.trim_n / d.rate,
                "face_tolerance_deg": d.face_tolerance_deg, "drift_tolerance": d.drift_tolerance,
                "settle": d.settle_blocks * d.drift_block_n / d.rate,
                "full_scale": d.full_scale}


def pose_data(poses: list[Pose], g: float) -> PoseData:
    if not poses:
        raise CalibrationError("no still pose found", "hold each face still for a few seconds")
    return PoseData([p.face for p in poses], [p.mean for p in poses],
                    [len(p.samples) for p in poses], [p.within_ss for p in poses], g)


def build_result(data: PoseData, poses: list[Pose], model: str, method: str, settings: dict) -> CalibrationResult:
    """Fit the requested model (or both, for auto) and package the CalibrationResult."""
    if model not in (*MODELS, "auto"):
        raise CalibrationError(f"unknown model {model!r}", "use paper, affine or auto")
    if model == "affine" and method == "paper":
        raise CalibrationError("the paper's Nelder-Mead scheme exists only for the 9-parameter model",
                               "use --method vp with --model affine, or --model paper")
    fits = {m: fit_model(data, m, method if m == "paper" else "vp") for m in (MODELS if model == "auto" else (model,))}
    n_obs = 3 * int(np.sum(data.counts))
    selection = {m: {"chi2": f.chi2, "dof": f.dof, "p_value": f.p_value, "aic": f.aic, "bic": f.bic(n_obs),
                     "n_parameters": len(f.names)} for m, f in fits.items()}
    chosen = min(fits.values(), key=lambda f: f.aic)
    corr = chosen.correction
    calibrated_residuals = [corr.apply(p.samples) - face_reference(p.face, data.g) for p in poses]
    all_res = np.concatenate(calibrated_residuals)
    face_rows = []
    for p, lof in zip(poses, chosen.residuals, strict=True):
        face_rows.append({"face": p.face, "start": p.start, "stop": p.stop, "n": len(p.samples),
                          "noise_sd": p.noise_sd, "residual": (corr.matrix @ lof).tolist(),
                          "residual_norm": float(np.linalg.norm(corr.matrix @ lof))})
    correlation = noise_correlation_factor(poses, max(int(round(0.25 * settings["rate"])), 5), data.noise_sd)
    quality = {
        "residual_rms": float(np.sqrt(np.mean(all_res**2))),
        "noise_correlation_factor": correlation,
        "noise_sd": data.noise_sd,
        "n_samples": int(np.sum(data.counts)),
        "n_poses": len(poses),
        "chi2": chosen.chi2,
        "dof": chosen.dof,
        "p_value": chosen.p_value,
        "model_selection": selection,
        "faces": face_rows,
        "n_evaluations": chosen.n_evaluations,
        "fit_seconds": chosen.seconds,
    }
    warnings = []
    if chosen.dof > 0 and chosen.p_value < 1e-3:
        warnings.append(f"the poses disagree with the {chosen.model} model beyond their noise (chi2 = "
                        f"{chosen.chi2:.1f} for {chosen.dof} dof): table not level, cube not square or a pose "
                        "not flat? The uncertainties may be too small.")
    if correlation > 1.5:
        warnings.append(f"the noise is correlated in time (pose means scatter {correlation:.1f} times more in "
                        "variance than white noise predicts; a digital low-pass filter?): the uncertainties "
                        "assume white noise and are too small by about the square root of that")
    if chosen.extra.get("converged") is False:
        warnings.append(f"Nelder-Mead stopped before converging: {chosen.extra.get('message')}")
    parameters = {n: Estimate(float(v), float(u), unit)
                  for n, v, u, unit in zip(chosen.names, chosen.values, chosen.uncertainty, chosen.units, strict=True)}
    return CalibrationResult(
        procedure="static",
        method=chosen.method,
        model=chosen.model,
        correction=corr,
        parameters=parameters,
        covariance=chosen.covariance,
        parameter_names=list(chosen.names),
        quality=quality,
        arrays={"pose_means": data.means, "pose_references": data.references, "pose_residuals": chosen.residuals,
                "pose_times": np.array([[p.start, p.stop] for p in poses])},
        settings={**settings, "model_requested": model, "faces": list(data.faces)},
        warnings=warnings,
    )


def noise_correlation_factor(poses: list[Pose], block: int, sigma: float) -> float:
    """Variance of block means x block length / sigma^2, pooled over poses and axes.

    About 1 for white noise (the model the uncertainties assume); a low-pass
    filtered sensor, or a pose that creeps, shows more.  nan when the poses
    are too short for two blocks.
    """
    total, dof = 0.0, 0
    for p in poses:
        n_blocks = len(p.samples) // block
        if n_blocks < 2:
            continue
        means = p.samples[: n_blocks * block].reshape(n_blocks, block, 3).mean(axis=1)
        total += float(np.sum((means - means.mean(axis=0)) ** 2)) * block
        dof += 3 * (n_blocks - 1)
    return total / dof / sigma**2 if dof and sigma > 0 else float("nan")


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


def calibrate_static(rec: Recording, **values) -> CalibrationResult:
    """Six-face calibration of a recording (the batch form); bad data raise one clear DataError/CalibrationError.

    ``values``: any of the declared SETTINGS by name (model, method, g, min_hold, still_threshold)."""
    proc = detect_poses(rec, **values)
    for pose in proc.rejected:
        if pose.problem in ("moved", "saturated"):
            raise DataError(pose.detail)
    result = proc.result()
    result.settings["recording"] = rec.meta.get("source") or rec.meta.get("device")
    return result
