"""accelrig noise REC.csv: noise figures of a still recording from its Allan deviation."""

from __future__ import annotations

import sys
import textwrap

import numpy as np

from accelrig.commands import add_time_range, add_units, load_from_args
from accelrig.geometry import AXES
from accelrig.result import format_value
from accelrig.units import STANDARD_GRAVITY

UG = 1e6 / STANDARD_GRAVITY   # (m/s^2) -> micro-g
ONE_ORIENTATION_DEG = 2.0     # still stretches further apart than this: the sensor was turned, not knocked
MAX_MOVING_FRACTION = 0.10    # a still recording moves (or is trimmed at still-motion edges) at most this much
EXCLUDED_SILENTLY = 1.0       # s: the detector's edge trims; more left out than this is said on stderr


def register(sub, groups) -> None:
    p = sub.add_parser(
        "noise",
        description="Overlapping Allan deviation of a recording of the sensor lying still, per axis: "
        "white-noise density (one-sided, ug/sqrt(Hz) as on datasheets: sigma(tau) = N / sqrt(2 tau)), "
        "bias instability (IEEE 952: minimum / 0.664) and rate random walk where the record is long enough. "
        "Uncertainties are standard (k = 1).",
    )
    p.add_argument("recording", help="still recording (.csv, .npz, or segments: a .parquet file or a directory), "
                   "a few minutes or more")
    p.add_argument("--json", action="store_true", help="print figures and Allan curves as JSON")
    p.add_argument("--profile", metavar="P.yaml", help="store the figures in this profile (rewritten atomically)")
    p.add_argument("--force", action="store_true",
                   help="store into a profile of another device or range, or one that holds noise figures")
    add_units(p)
    add_time_range(p)
    p.set_defaults(func=run)


def run(args) -> int:
    from accelrig.estimation.allan import noise_figures
    from accelrig.profiles.apply import check_compatible
    from accelrig.profiles.io import load_profile, save_profile, utc_now
    from accelrig.result import to_json

    rec = load_from_args(args, args.recording)
    profile = None
    if args.profile:
        profile = load_profile(args.profile)   # refuse a bad profile before computing anything
        for w in check_compatible(profile, rec.meta, "m/s^2", args.force):
            print(f"accelrig: warning: {w}", file=sys.stderr)
        if profile.noise is not None and not args.force:
            from accelrig.errors import ProfileError

            raise ProfileError(f"{args.profile} already holds noise figures (from {profile.noise['date']})",
                               "use --force to replace them")
    from accelrig.recording import loss_warning

    if (loss := loss_warning(rec)) is not None:
        print(f"accelrig: warning: {loss}", file=sys.stderr)
    start, stop = still_stretch(rec.to_si())
    report = noise_figures(rec, (start, stop))
    seg = report.still_segment
    if seg["of_total"] - seg["seconds"] > EXCLUDED_SILENTLY:
        print(f"accelrig: note: the sensor was disturbed; reading only its longest still stretch, "
              f"t = {start:.1f}-{stop:.1f} s ({seg['seconds']:.1f} s of {seg['of_total']:.1f} s)", file=sys.stderr)
    if profile is not None:
        profile.data["noise"] = report.to_profile_dict(utc_now())
        save_profile(profile, args.profile, inputs=[args.recording])   # a link: its target is updated
    if args.json:
        section = report.to_json_dict(utc_now())
        section["arrays"] = {k: v.tolist() for k, v in report.arrays().items()}
        print(to_json(section))
        return 0
    print(noise_table(report))
    if profile is not None:
        print(f"stored in {args.profile}")
    return 0


def still_stretch(rec) -> tuple[float, float]:
    """(start, stop) in s of the stretch to read the noise from: the longest still pose the static
    procedure's detector finds (any orientation counts). Refuses, in one line, a recording that is
    not of a sensor resting in one position apart from short disturbances (see docs/noise.md)."""
    from accelrig.errors import DataError
    from accelrig.procedures.static.poses import PoseDetector, full_scale_of

    detector = PoseDetector(rec.rate, face_tolerance_deg=90.0, full_scale=full_scale_of(rec.meta))
    detector.feed(rec.t, rec.acc)
    detector.finish()
    poses, total = detector.poses, rec.duration
    todo = "record the sensor resting on a bench, untouched, in one position"
    if not poses:
        shifted = [p for p in detector.rejected if p.problem in ("moved", "saturated")]
        if shifted:
            raise DataError(f"the sensor was not still: {shifted[0].detail.rsplit(': ', 1)[0]}", todo)
        span = float(np.linalg.norm(np.ptp(rec.acc, axis=0)))
        raise DataError(f"the sensor was moving throughout t = {rec.t[0]:.1f}-{rec.t[-1]:.1f} s (its acceleration "
                        f"spans {span:.1f} m/s^2): never still for {detector.min_hold:g} s", todo)
    longest = max(poses, key=lambda p: p.duration)
    angles = [angle_deg(p.mean, longest.mean) for p in poses]
    if max(angles) > ONE_ORIENTATION_DEG:
        far = poses[int(np.argmax(angles))]
        raise DataError(f"the sensor was turned: it rested in {len(poses)} positions up to {max(angles):.0f} degrees "
                        f"apart (t = {longest.start:.1f} s and t = {far.start:.1f} s, with motion between)", todo)
    moving = total - sum(p.duration for p in poses)
    if moving > MAX_MOVING_FRACTION * total:
        first = min(poses, key=lambda p: p.start)
        when = rec.t[0] if first.start - rec.t[0] > EXCLUDED_SILENTLY else first.stop
        raise DataError(f"the sensor moved for {moving:.1f} s of {total:.1f} s (first at t = {when:.1f} s), more than "
                        f"{MAX_MOVING_FRACTION:.0%} of the recording: not a still recording", todo)
    return longest.start, longest.stop


def angle_deg(a: np.ndarray, b: np.ndarray) -> float:
    """Angle between two mean accelerations (the direction of gravity in the sensor), degrees."""
    cos = float(np.dot(a, b) / (np.linalg.norm(a) * np.linalg.norm(b)))
    return float(np.degrees(np.arccos(min(max(cos, -1.0), 1.0))))


def noise_table(report) -> str:
    """The closing-note table: one row per axis, datasheet units; 80 columns wide (tables.fitted_lines:
    the columns that do not fit stack under the first, each led by the axis)."""
    from accelrig.tables import TERMINAL_WIDTH, fitted_lines

    def wrapped(text: str) -> list[str]:
        return textwrap.wrap(text, TERMINAL_WIDTH, subsequent_indent="  ", break_on_hyphens=False)

    def pm(value: float, u: float) -> str:   # rounded together, as on every face (format_value)
        return " +- ".join(format_value(value, u))

    lines = wrapped(f"{report.n_samples} samples, {report.duration:.1f} s at {report.rate:.2f} Hz; "
                    "overlapping Allan deviation at octave taus; uncertainties k = 1")
    if seg := report.still_segment:
        lines += wrapped(f"read on the longest still stretch, t = {seg['start']:.1f}-{seg['stop']:.1f} s of a "
                         f"{seg['of_total']:.1f} s recording")
    titles = ("axis", "density ug/sqrt(Hz)", "density (m/s^2)/sqrt(Hz)", "bias instability ug (tau)",
              "rate random walk (m/s^2)/sqrt(s)")
    rows = []
    for axis in AXES:
        a = report.axes[axis]
        d = a.density
        bi = (f"{pm(a.bias_instability.value * UG, a.bias_instability.uncertainty * UG)} "
              f"({a.bias_instability_tau:.3g} s)") if a.bias_instability else "not reached"
        rw = pm(a.random_walk.value, a.random_walk.uncertainty) if a.random_walk else "not seen"
        rows.append([axis, pm(d.value * UG, d.uncertainty * UG), pm(d.value, d.uncertainty), bi, rw])
    lines += ["", *fitted_lines(titles, rows, (0, 1, 3, 4, 2)), ""]
    lines += wrapped("density is one-sided (datasheet convention): sigma(tau) = N / sqrt(2 tau), "
                     "per-sample sd = N sqrt(rate / 2); bias instability = min sigma / 0.664 (IEEE 952)")
    notes = sorted({n for axis in AXES for n in report.axes[axis].notes})
    for n in notes:
        lines += wrapped(f"note: {n}")
    return "\n".join(lines)
