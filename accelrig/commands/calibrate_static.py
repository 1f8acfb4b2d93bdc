"""accelrig calibrate static REC.csv [--model auto|six-face|multi-position|paper|affine] [--pose-flatness-deg D]
[--method vp|paper] [--json] [-o PROFILE.yaml]

The procedure's flags come from its declared settings (accelrig.procedures.static.settings);
the numerical machinery is imported only when the command runs, so --help stays quick.
"""

from __future__ import annotations

from accelrig.commands import add_time_range, add_units, load_from_args, warn_loss
from accelrig.commands.profile_output import add_profile_arguments, check_profile_target, write_profile
from accelrig.procedures.static.settings import SETTINGS
from accelrig.settings import add_arguments, values_from_args


def register(sub, groups) -> None:
    p = groups["calibrate"].add_parser(
        "static",
        help="static calibration from still poses: six faces (tilt-robust) or any orientations",
        description="Calibrate from a recording of the sensor held still on each of its six faces "
        "(any order, repeats add data), or in at least 9 orientations (multi-position), with handling in "
        "between. Poses are found on the raw data; '+z down' means the +z axis points down (reads -g). "
        "A pose too far from a face for six-face mode is refused by name; no profile is written then. "
        "The drift check (the TUI wizard's fifteen holds): after the six faces one face of each axis again, "
        "then their opposite faces once more, then the first faces a third time (last, so that their holds "
        "span the run); a recording with fewer holds or another order "
        "calibrates too and says what it could not check.",
    )
    p.add_argument("recording", help="recording (.csv interchange, .npz, or segments: a .parquet file or a directory)")
    add_arguments(p, SETTINGS)
    add_units(p)
    p.add_argument("--rate", type=float, help="sample rate in Hz for a file without a t column")
    add_time_range(p)
    p.add_argument("--skip-pose", type=pose_numbers, action="append", default=[], metavar="N[,N...]",
                   help="leave these poses out (numbers from the pose table, in time order from 1), e.g. a face "
                   "that moved and was held again later; a moved pose not left out refuses the recording")
    p.add_argument("--json", action="store_true", help="print one JSON object instead of the text report")
    add_profile_arguments(p)
    p.set_defaults(func=run)


def run(args) -> int:
    from accelrig.procedures.static.procedure import calibrate_static
    from accelrig.result import to_json

    values = values_from_args(SETTINGS, args)
    check_profile_target(args)   # an -o that would be refused is refused before the fit
    rec = load_from_args(args, args.recording)
    from accelrig.commands.progress import Progress

    with Progress(f"calibrating from {args.recording}"):
        result = calibrate_static(rec, skip_poses=[k for group in args.skip_pose for k in group], **values)
    warn_loss(rec, result)
    write_profile(result, rec, args)
    if args.json:
        print(to_json(result.to_json_dict()))
    else:
        print(text_report(result))
    return 0


def pose_numbers(text: str) -> list[int]:
    """'7' or '3,7': pose numbers from the pose table (argparse type)."""
    import argparse

    try:
        numbers = [int(part) for part in text.split(",") if part.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a list of pose numbers (e.g. 7 or 3,7)") from None
    if not numbers or min(numbers) < 1:
        raise argparse.ArgumentTypeError(f"{text!r}: pose numbers start at 1 (e.g. 7 or 3,7)")
    return numbers


def text_report(result) -> str:
    """What a person reads: every still pose and its fate, parameters with k = 1 uncertainties, the
    correction, what the uncertainty holds, warnings."""
    from accelrig.report.checks import check_lines
    from accelrig.report.html import format_value, scalar_estimates

    q = result.quality
    lines = [f"static calibration: model {result.model}, method {result.method}, "
             f"{q['n_poses']} of {q['n_poses_found']} still poses used, {q['n_samples']} samples, "
             f"noise sd {q['noise_sd']:.4f} m/s^2"]
    lines.append("  pose   start    stop      n  nearest face  fate        |g| residual (m/s^2)")
    for r in result.details["poses"]:
        fit = f"{r['magnitude_residual']:+.4f}" if "magnitude_residual" in r else r["reason"]
        lines.append(f"  {r['index']:4d} {r['start']:7.2f} {r['stop']:7.2f} {r['n']:6d}  {r['face']:>4} "
                     f"{r['angle_deg']:5.1f} deg  "
                     f"{r['fate']:10s}  {fit}")
    lines.append("parameters (standard uncertainty, k = 1): " + result.parameter_meaning)
    for label, v, u, unit in scalar_estimates(result.parameters):   # rounded as the TUI and certificate do
        value, unc = format_value(v, u)
        lines.append(f"  {label:<20} {value:>14} +- {unc:<12} {unit}")
    c = result.correction
    lines.append("correction: calibrated = C @ (raw - b)")

    def paired(v: float, u: float) -> str:   # value(u), rounded together as every face rounds (format_value)
        if v == 0 and u == 0:
            return "0"   # fixed by the model's gauge (multi-position's C is upper triangular)
        value, unc = format_value(v, u)
        return f"{'' if value.startswith('-') else '+'}{value}({unc})"

    cells = [[paired(v, u) for v, u in zip(row, urow, strict=True)]
             for row, urow in zip(c.matrix, c.matrix_uncertainty, strict=True)]
    width = max(len(cell) for row in cells for cell in row)
    lines += ["  C  " + "  ".join(f"{cell:<{width}}" for cell in row).rstrip() for row in cells]
    lines.append("  b  " + "  ".join(paired(v, u) for v, u in zip(c.bias, c.bias_uncertainty, strict=True)) + " m/s^2")
    lines += [f"{what}: {sentence}" for what, sentence in check_lines(result.to_json_dict())]
    lines.append(f"largest |g| residual of a pose {q['max_magnitude_residual']:.4f} m/s^2")
    lines += [f"warning: {w}" for w in result.warnings]
    return "\n".join(lines)
