"""Static calibration with tilted poses: Monte Carlo against truth and the bound (issue 12).

    python tests/benchmarks/bench_static_tilt.py [--runs 1000] [--seed 1]
    python tests/benchmarks/bench_static_tilt.py --through-sim [--runs 300] [--seed 1]

Pose statistics are drawn here from first principles, sharing no code with the estimators: a true
correction (C = G R(angles), angles +-1 deg, gains 1 +- 2 %, offsets +-0.5 m/s^2), each pose's true
down direction (a face rotated by its tilt vector, Rodrigues), the specific force -g d, raw mean
K f + b plus white noise of sd sigma / sqrt(n) per axis.  Scenarios (the six faces once each, or
arbitrary orientations):

  level         exact faces (granite), stated flatness 0
  hand 0.1/0.3/1  each tilt component N(0, s^2) (hand-placed), stated flatness s
  table 1       table tilted 1 deg, a random yaw per pose, hand 0.2 deg; stated flatness 1 deg (default)
  table 3       table tilted 3 deg, stated flatness 1 deg (the tilt test must catch it)
  arbitrary     18 orientations uniform on the sphere: multi-position fit

For each model the 12 correction entries (9 for multi-position: its gauge fixes 3) are compared with
the truth: sd / bound (six-face: the hybrid CRB with the stated flatness; multi-position: its CRB) and
the coverage of +-2u, printed as min-max over the entries of C and of b.  The paper's exact-face model
and the Ferraris pairing (noise-only u, no inflation; the procedure's --model paper adds a Birge ratio when chi^2
rejects, see --through-sim) are judged against the
same bound as the tilt models on the same poses.

``--through-sim`` runs the whole pipeline instead: sim://static (``accelrig.sim.rigs.static``: hand
tilts, a tilted table under random yaws, or arbitrary orientations; handling between poses) recorded
through the sensor model at 100 Hz, still poses found by the procedure's detector (``detect_poses``),
then the procedure's fits (``StaticProcedure.result()`` with --model six-face / paper /
multi-position) and, on the same detected poses, the six-face affine fit and the Ferraris pairing
(``gravity_fit``).  The truth is the simulator's (``meta["truth"]``: the sensor's correction and each
pose's true up direction), the bound is computed at that truth for the samples each run used.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from accelrig.errors import AccelrigError, CalibrationError
from accelrig.estimation.gravity_fit import (
    PoseStats,
    fit_ferraris,
    fit_multiposition,
    fit_six_face,
    multiposition_crb,
    six_face_crb,
    upper_gauge,
)

G, SIGMA, N = 9.80665, 0.02, 400            # 4 s at 100 Hz per pose, 0.02 m/s^2 per raw axis
FACE_LIST = ["+x", "-x", "+y", "-y", "+z", "-z"]
SCENARIOS = {   # name: (kind, table tilt deg, hand tilt sd deg, stated flatness deg)
    "level": ("faces", 0.0, 0.0, 0.0),
    "hand 0.1": ("faces", 0.0, 0.1, 0.1),
    "hand 0.3": ("faces", 0.0, 0.3, 0.3),
    "hand 1": ("faces", 0.0, 1.0, 1.0),
    "table 1": ("faces", 1.0, 0.2, 1.0),
    "table 3": ("faces", 3.0, 0.2, 1.0),
    "arbitrary": ("sphere", 0.0, 0.0, 0.0),
}
MODELS_FACES = ["six-face affine", "six-face paper", "ferraris", "exact-face paper"]


def _rx(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def _ry(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def _rz(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def draw_truth(rng):
    angles = np.radians(rng.uniform(-1, 1, 3))
    gains = 1 + rng.uniform(-0.02, 0.02, 3)
    c_mat = np.diag(gains) @ _rz(angles[2]) @ _ry(angles[1]) @ _rx(angles[0])
    bias = rng.uniform(-0.5, 0.5, 3)
    paper = np.concatenate([angles, gains, -c_mat @ bias])
    return c_mat, bias, paper


def face_vector(face):
    v = np.zeros(3)
    v["xyz".index(face[1])] = 1.0 if face[0] == "+" else -1.0
    return v


def tilted(e, tilt_vec):
    """Rotate the unit vector e by the rotation vector tilt_vec (perpendicular to e): Rodrigues."""
    angle = np.linalg.norm(tilt_vec)
    if angle == 0:
        return e
    axis = tilt_vec / angle
    return e * np.cos(angle) + np.cross(axis, e) * np.sin(angle) + axis * (axis @ e) * (1 - np.cos(angle))


def draw_poses(rng, c_mat, bias, kind, table_deg, hand_deg):
    k_mat = np.linalg.inv(c_mat)
    poses, downs = [], []
    if kind == "faces":
        table_dir = rng.uniform(0, 2 * np.pi)
        for face in FACE_LIST:
            e = face_vector(face)
            helper = np.eye(3)[(int(np.argmax(np.abs(e))) + 1) % 3]
            t1 = np.cross(e, helper)
            t1 /= np.linalg.norm(t1)
            t2 = np.cross(e, t1)
            yaw = rng.uniform(0, 2 * np.pi)           # the housing's yaw on the table: the table tilt seen in the body
            comp = np.radians(table_deg) * np.array([np.cos(table_dir + yaw), np.sin(table_dir + yaw)])
            comp = comp + np.radians(hand_deg) * rng.standard_normal(2)
            downs.append(tilted(e, comp[0] * t1 + comp[1] * t2))
    else:
        for _ in range(18):
            v = rng.standard_normal(3)
            downs.append(v / np.linalg.norm(v))
    faces = FACE_LIST if kind == "faces" else [None] * len(downs)
    for d, face in zip(downs, faces, strict=True):
        mean = k_mat @ (-G * d) + bias + SIGMA / np.sqrt(N) * rng.standard_normal(3)
        poses.append(PoseStats(mean, SIGMA, N, face))
    return poses, np.array(downs)


def run_scenario(name, runs, seed, models=None):
    """Per model: errors, stated u and bound sd per correction entry; the entries compared.
    ``models`` (names) keeps only those fits (the same draws, whichever are kept); None runs them all."""
    kind, table_deg, hand_deg, stated = SCENARIOS[name]
    rng = np.random.default_rng(seed)
    out = {}
    seconds = {}
    for _ in range(runs):
        c_mat, bias, paper = draw_truth(rng)
        poses, downs = draw_poses(rng, c_mat, bias, kind, table_deg, hand_deg)
        if kind == "sphere":
            truth = np.concatenate([upper_gauge(c_mat).ravel(), bias])
            bound = np.sqrt(np.diag(multiposition_crb(c_mat, bias, -downs, N, SIGMA, G)))
            fits = {"multi-position": lambda poses=poses: fit_multiposition(poses, G)}
            bounds = {"multi-position": bound}
        else:
            truth = np.concatenate([c_mat.ravel(), bias])
            b_aff = np.sqrt(np.diag(six_face_crb("affine", c_mat, bias, FACE_LIST, N, SIGMA, stated, G)))
            b_pap = np.sqrt(np.diag(six_face_crb("paper", c_mat, bias, FACE_LIST, N, SIGMA, stated, G, params=paper)))
            fits = {
                "six-face affine": lambda poses=poses: fit_six_face(poses, "affine", stated, G),
                "six-face paper": lambda poses=poses: fit_six_face(poses, "paper", stated, G),
                "ferraris": lambda poses=poses: fit_ferraris(poses, G),
                "exact-face paper": lambda poses=poses: fit_six_face(poses, "paper", 0.0, G, inflation="none"),
            }
            bounds = {"six-face affine": b_aff, "six-face paper": b_pap, "ferraris": b_aff, "exact-face paper": b_pap}
        for model, fit_fn in fits.items():
            if models is not None and model not in models:
                continue
            t0 = time.perf_counter()
            try:
                fit = fit_fn()
            except CalibrationError:
                out.setdefault(model, {"err": [], "u": [], "bound": [], "inflated": 0, "refused": 0})["refused"] += 1
                continue
            seconds[model] = seconds.get(model, 0.0) + time.perf_counter() - t0
            rec = out.setdefault(model, {"err": [], "u": [], "bound": [], "inflated": 0, "refused": 0})
            est = np.concatenate([fit.correction.matrix.ravel(), fit.correction.bias])
            rec["err"].append(est - truth)
            rec["u"].append(np.sqrt(np.clip(np.diag(fit.correction.covariance), 0, None)))
            rec["bound"].append(bounds[model])
            rec["inflated"] += int(fit.inflated)
    for model, rec in out.items():
        for key in ("err", "u", "bound"):
            rec[key] = np.array(rec[key])
        rec["seconds"] = seconds.get(model, 0.0) / max(len(rec["err"]), 1)
        rec["free"] = (np.array([0, 1, 2, 4, 5, 8, 9, 10, 11]) if model == "multi-position"
                       else np.arange(12))
    return out


# ------------------------------------------------------------------ through the simulator

SIM_RATE, SIM_HOLD = 100.0, 3.0          # 3 s holds at 100 Hz (about 240 clean samples per pose): a short run
SIM_SCENARIOS = {   # name: (rig options, stated flatness deg)
    "hand 0.1": ({"tilt_deg": 0.1}, 0.1),
    "hand 0.3": ({"tilt_deg": 0.3}, 0.3),
    "hand 1": ({"tilt_deg": 1.0}, 1.0),
    "table 1": ({"table_deg": 1.0, "tilt_deg": 0.2}, 1.0),
    "table 3": ({"table_deg": 3.0, "tilt_deg": 0.2}, 1.0),
    "arbitrary": ({"orientations": 18}, 1.0),
}
SIM_MODELS_FACES = ["six-face affine", "six-face paper", "ferraris", "exact-face paper"]


def _first_line(exc: AccelrigError) -> str:
    text = str(exc)
    for word in (" is ", " poses "):   # group refusals by their kind, not by the pose number or angle
        if word in text:
            return text.split(word, 1)[1][:60]
    return text[:60]


def run_through_sim(name, runs, seed):
    """The whole pipeline per run: simulate, detect the still poses, fit every model; compare with the sim's truth."""
    from accelrig.procedures.static.procedure import detect_poses
    from accelrig.sim.device import simulate
    from accelrig.sim.rigs.static import StaticRig, sensor_with_response
    from accelrig.sim.sensor import SensorModel, SimClock

    options, stated = SIM_SCENARIOS[name]
    rng = np.random.default_rng(seed)
    out, seconds = {}, {}
    for _ in range(runs):
        c_draw, bias_draw, paper = draw_truth(rng)
        sensor = sensor_with_response(np.linalg.inv(c_draw), bias_draw,
                                      noise_density=SensorModel.noise_density_for_sd(SIGMA, SIM_RATE))
        rig = StaticRig(rng, hold=SIM_HOLD, **options)
        rec = simulate(rig, sensor, SimClock(SIM_RATE), seed=int(rng.integers(2**31)))
        truth = rec.meta["truth"]
        c_true = np.array(truth["sensor"]["correction"]["matrix"])
        b_true = np.array(truth["sensor"]["correction"]["bias"])
        sigma = sensor.noise_sd(SIM_RATE)
        proc = detect_poses(rec, g=G, pose_flatness_deg=stated)
        poses = proc.poses
        # each detected pose's true up direction: the simulator's pose whose interval holds it
        true_poses = truth["rig"]["poses"]
        ups = np.array([next(tp["up_body"] for tp in true_poses if tp["start"] <= p.t.mean() <= tp["stop"])
                        for p in poses])
        counts = np.array([len(p.samples) for p in poses])
        stats = [PoseStats.from_samples(p.samples, p.face, f"pose {k + 1}") for k, p in enumerate(poses)]

        def procedure_fit(model, proc=proc):
            proc.model = model
            result = proc.result()
            # inflated: the tilt test rejected the stated flatness, a repeatability term or a Birge ratio was added
            return result.correction, any(w.startswith(("uncertainty:", "tilts exceed", "the poses disagree"))
                                          for w in result.warnings)

        def direct(fit):
            return fit.correction, fit.inflated

        if "orientations" in options:
            fits = {"multi-position": lambda: procedure_fit("multi-position")}
            bounds = {"multi-position": np.sqrt(np.diag(multiposition_crb(c_true, b_true, ups, counts, sigma, G)))}
            truth_vec = np.concatenate([upper_gauge(c_true).ravel(), b_true])
        else:
            faces = [p.face for p in poses]
            b_aff = np.sqrt(np.diag(six_face_crb("affine", c_true, b_true, faces, counts, sigma, stated, G)))
            b_pap = np.sqrt(np.diag(six_face_crb("paper", c_true, b_true, faces, counts, sigma, stated, G,
                                                 params=paper)))
            fits = {
                "six-face affine": lambda stats=stats: direct(fit_six_face(stats, "affine", stated, G)),
                "six-face paper": lambda: procedure_fit("six-face"),
                "ferraris": lambda stats=stats: direct(fit_ferraris(stats, G)),
                "exact-face paper": lambda: procedure_fit("paper"),
            }
            bounds = {"six-face affine": b_aff, "six-face paper": b_pap, "ferraris": b_aff, "exact-face paper": b_pap}
            truth_vec = np.concatenate([c_true.ravel(), b_true])
        for model, fit_fn in fits.items():
            rec_m = out.setdefault(model, {"err": [], "u": [], "bound": [], "inflated": 0, "refused": 0, "why": {}})
            t0 = time.perf_counter()
            try:
                corr, inflated = fit_fn()
            except AccelrigError as exc:
                rec_m["refused"] += 1
                why = _first_line(exc)
                rec_m["why"][why] = rec_m["why"].get(why, 0) + 1
                continue
            seconds[model] = seconds.get(model, 0.0) + time.perf_counter() - t0
            est = np.concatenate([corr.matrix.ravel(), corr.bias])
            rec_m["err"].append(est - truth_vec)
            rec_m["u"].append(np.sqrt(np.clip(np.diag(corr.covariance), 0, None)))
            rec_m["bound"].append(bounds[model])
            rec_m["inflated"] += int(inflated)
            rec_m.setdefault("flags", []).append(bool(inflated))
    for model, rec_m in out.items():
        for key in ("err", "u", "bound"):
            rec_m[key] = np.array(rec_m[key])
        rec_m["seconds"] = seconds.get(model, 0.0) / max(len(rec_m["err"]), 1)
        rec_m["free"] = (np.array([0, 1, 2, 4, 5, 8, 9, 10, 11]) if model == "multi-position" else np.arange(12))
    return out


def summarise(rec):
    """sd / bound and +-2u coverage per free entry (nan when nothing was fitted)."""
    err, u, bound, free = rec["err"], rec["u"], rec["bound"], rec["free"]
    if not len(err):
        return None
    sd = np.sqrt(np.mean(err[:, free] ** 2, axis=0))          # RMS error about the truth (bias included)
    ratio = sd / np.mean(bound[:, free], axis=0)
    cover = np.mean(np.abs(err[:, free]) <= 2 * u[:, free], axis=0)
    is_b = free >= 9
    return {"ratio_C": ratio[~is_b], "ratio_b": ratio[is_b], "cover_C": cover[~is_b], "cover_b": cover[is_b]}


def _rng(values, fmt):
    return f"{fmt.format(np.min(values))}-{fmt.format(np.max(values))}"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=1000)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--through-sim", action="store_true",
                    help="simulate every run through sim://static and the procedure's pose detection")
    ap.add_argument("--only", help="comma-separated scenario names (default: all)")
    args = ap.parse_args(argv)
    if args.through_sim:
        print(f"## Through the simulator: {args.runs} runs per scenario, sigma {SIGMA} m/s^2, {SIM_RATE:g} Hz, "
              f"{SIM_HOLD:g} s holds, handling between poses\n")
        scenarios, runner = SIM_SCENARIOS, run_through_sim
    else:
        print(f"## Tilted poses: {args.runs} runs per scenario, sigma {SIGMA} m/s^2, {N} samples per pose\n")
        scenarios, runner = SCENARIOS, run_scenario
    print("RMS error / bound and coverage of +-2u, min-max over the entries of C and of b; "
          "'inflated': runs where a lack-of-fit test changed the uncertainty.\n")
    print("| scenario | model | err/bound C | err/bound b | cover C % | cover b % | inflated % | refused % | ms/fit |")
    print("|---|---|---|---|---|---|---|---|---|")
    refusals = []
    for k, name in enumerate(scenarios):
        if args.only and name not in args.only.split(","):
            continue
        result = runner(name, args.runs, args.seed + k)
        for model, rec in result.items():
            for why, n in rec.get("why", {}).items():
                refusals.append(f"{name}, {model}: {n} x '{why}'")
            s = summarise(rec)
            refused = 100 * rec["refused"] / args.runs
            if s is None:
                print(f"| {name} | {model} | - | - | - | - | - | {refused:.0f} | - |")
                continue
            print(f"| {name} | {model} | {_rng(s['ratio_C'], '{:.2f}')} | {_rng(s['ratio_b'], '{:.2f}')} | "
                  f"{_rng(100 * s['cover_C'], '{:.1f}')} | {_rng(100 * s['cover_b'], '{:.1f}')} | "
                  f"{100 * rec['inflated'] / max(len(rec['err']), 1):.1f} | {refused:.0f} | {1e3 * rec['seconds']:.1f} |")
    if refusals:
        print("\nRefusals (first words of the message after the pose named):\n")
        for line in refusals:
            print(f"* {line}")


if __name__ == "__main__":
    main()
