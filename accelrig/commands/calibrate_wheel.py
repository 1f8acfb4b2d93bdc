"""accelrig calibrate wheel REC --radius R   and   accelrig plan wheel --radius R --tilt-deg A ..."""

from __future__ import annotations

from accelrig.commands import add_time_range, add_units, load_from_args, warn_loss
from accelrig.commands.profile_output import add_profile_arguments, check_profile_target, write_profile
from accelrig.errors import DataError
from accelrig.procedures.wheel.settings import PLAN_SETTINGS, SETTINGS
from accelrig.settings import add_arguments, values_from_args


def register(sub, groups) -> None:
    p = groups["calibrate"].add_parser(
        "wheel",
        help="tilted freely rotating wheel (Pedersini): gains and offsets from one spin",
        description="Calibrate from a recording of the sensor on a tilted, freely rotating wheel "
        "(paper 002). Give the measured radius (sensor to axis) or the tilt.",
    )
    p.add_argument("recording", help="recording (.csv interchange, .npz, or segments) of the coasting wheel")
    add_arguments(p, SETTINGS)
    add_units(p)
    p.add_argument("--rate", type=float, help="sample rate, Hz, for a file without a t column")
    add_time_range(p, start_note="the wheel's free coast from T (without it the fit finds where the last push "
                   "ended and leaves the rest and the push before it out, with a warning; a rest before T still checks the coast)",
                   stop_note="the spin before T (without it a stop and rest at the end are found and left out, "
                   "with a warning)")
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    add_profile_arguments(p)
    p.set_defaults(func=run_calibrate)

    q = groups["plan"].add_parser(
        "wheel",
        help="predicted uncertainties (CRB, and u(g) on the gains) of a wheel calibration before spinning",
        description="Print the standard uncertainty (k=1) each parameter would reach on a planned wheel "
        "run: the Cramer-Rao bound for a perfect sensor mounted at --mount-deg and the paper's coast-down "
        "profile scaled to --speed over --seconds, and for the gains the local gravity's u(g) as the "
        "calibration adds it (--g, --latitude/--height, --g-u, as calibrate wheel takes them; default "
        "standard gravity, whose u stands for anywhere on Earth).",
    )
    add_arguments(q, PLAN_SETTINGS)
    q.add_argument("--json", action="store_true", help="print the plan as JSON")
    q.set_defaults(func=run_plan)


def run_calibrate(args) -> int:
    from accelrig.procedures.wheel.procedure import GRAVITY_SCALED, calibrate_wheel
    from accelrig.result import to_json

    v = values_from_args(SETTINGS, args)
    check_profile_target(args)   # an -o that would be refused is refused before the fit
    rec = load_from_args(args, args.recording)
    # the part before --start is not fitted, but a rest at its beginning still checks the coast (rest.py)
    before = None
    if args.start is not None:
        try:
            before = load_from_args(args, args.recording, start=None, stop=args.start)
        except DataError:     # nothing before --start
            before = None
    from accelrig.commands.progress import Progress
    from accelrig.units import local_gravity

    gravity = local_gravity(v["g"], v["latitude"], v["height"], v["g_u"])
    with Progress(f"fitting the wheel ({v['method']} method)") as progress:
        result = calibrate_wheel(rec, radius=v["radius"], tilt_deg=v["tilt_deg"], method=v["method"],
                                 g=gravity.value, bootstrap=v["bootstrap"], cross_axis_sd=v["cross_axis_sd"],
                                 on_progress=progress.step, before=before).with_local_gravity(gravity, GRAVITY_SCALED)
    warn_loss(rec, result)
    write_profile(result, rec, args)
    if args.json:
        print(to_json(result.to_json_dict()))
        return 0
    print(_human(result))
    return 0


def _human(result) -> str:
    import numpy as np

    from accelrig.report.checks import check_lines
    from accelrig.report.html import format_value, scalar_estimates

    q = result.quality
    lines = [f"wheel calibration, method {result.method}: {q['n_samples']} samples, {q['duration_s']:.1f} s, "
             f"{q['turns']:.1f} turns, residual rms {q['residual_rms']:.4f} m/s^2"]
    lines.append(f"parameters: {result.parameter_meaning}")
    lines.append(f"{'parameter':<20} {'value':>14} {'u (k=1)':>12}")
    for label, v, u, unit in scalar_estimates(result.parameters):   # rounded as the TUI and certificate do
        value, unc = format_value(v, u)
        lines.append(f"{label:<20} {value:>14} {unc:>12} {unit}")
    c = result.correction
    lines.append("correction: calibrated = C (raw - b)")
    diag = [format_value(float(v), float(u)) for v, u in zip(np.diag(c.matrix), np.diag(c.matrix_uncertainty),
                                                              strict=True)]
    bias = [format_value(float(v), float(u)) for v, u in zip(c.bias, c.bias_uncertainty, strict=True)]
    lines.append("  C diag " + " ".join(v for v, _ in diag) + "   u " + " ".join(u for _, u in diag))
    lines.append("  b      " + " ".join(v for v, _ in bias) + "   u " + " ".join(u for _, u in bias) + " m/s²")
    lines += [f"{what}: {sentence}" for what, sentence in check_lines(result.to_json_dict())]
    if "coverage_factor" in result.details:   # few batch-means blocks: U = k u with Student's t, not 2
        lines.append(f"expanded uncertainty U = k u with k = {result.details['coverage_factor']:.2f} (Student's t on "
                     f"the {result.details['coverage_dof']:g} degrees of freedom of u), not 2")
    lines.append(f"fit time {q['time_s']:.2f} s")
    for w in result.warnings:
        lines.append(f"warning: {w}")
    return "\n".join(lines)


def run_plan(args) -> int:
    from accelrig.procedures.wheel.plan import plan_wheel
    from accelrig.result import to_json

    v = values_from_args(PLAN_SETTINGS, args)
    if len(v["mount_deg"]) != 3:
        raise DataError(f"--mount-deg {args.mount_deg!r} needs three comma-separated angles in degrees")
    from accelrig.units import local_gravity

    gravity = local_gravity(v["g"], v["latitude"], v["height"], v["g_u"])
    rows = plan_wheel(v["radius"], v["tilt_deg"], v["noise"], v["rate"], v["seconds"], v["speed"], v["mount_deg"],
                      gravity)
    if args.json:
        print(to_json({"procedure": "wheel", "bound": "Cramer-Rao, k=1; gains with u(g) added", **gravity.to_dict(),
                       "parameters": {r.name: {"value": r.value, "uncertainty": r.sd, "crb": r.crb, "unit": r.unit}
                                      for r in rows}}))
        return 0
    import textwrap

    print(f"wheel plan: r = {v['radius']} m, tilt {v['tilt_deg']} deg, noise {v['noise']} m/s^2,\n"
          f"  {v['rate']:g} Hz x {v['seconds']:g} s, start {v['speed']} rad/s")
    print(textwrap.fill(f"best reachable uncertainty (k=1): the CRB, and for the gains u(g) {gravity.u:.2g} m/s^2 "
                        f"({gravity.u / gravity.value:.1e} of g) as the calibration adds it; g {gravity.value:.5f} "
                        f"m/s^2: {gravity.source}", 79, subsequent_indent="  "))
    print(f"{'parameter':<22}{'nominal':>14}{'uncertainty':>13}{'CRB':>11}  unit")
    for r in rows:
        print(f"{r.name:<22}{r.value:>14.6g}{r.sd:>13.2g}{r.crb:>11.2g}  {r.unit}")
    return 0
