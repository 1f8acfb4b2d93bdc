"""accelrig calibrate wheel REC --radius R   and   accelrig plan wheel --radius R --tilt-deg A ..."""

from __future__ import annotations


import numpy as np

from accelrig.errors import DataError
from accelrig.procedures.wheel import DEFAULT_BOOTSTRAP, DEFAULT_CROSS_AXIS_SD, METHODS, calibrate_wheel, plan_wheel
from accelrig.recording import load_recording
from accelrig.units import STANDARD_GRAVITY
from accelrig.result import to_json


def register(sub, groups) -> None:
    p = groups["calibrate"].add_parser(
        "wheel",
        help="tilted freely rotating wheel (Pedersini): gains and offsets from one spin",
        description="Calibrate from a recording of the sensor on a tilted, freely rotating wheel "
        "(paper 002). Give the measured radius (sensor to axis) or the tilt.",
    )
    p.add_argument("recording", help="recording (.csv interchange or .npz) of the coasting wheel")
    p.add_argument("--radius", type=float, help="distance from the sensor to the wheel axis, m")
    p.add_argument("--tilt-deg", type=float, help="tilt of the wheel axis from the vertical, deg (instead of or with --radius)")
    p.add_argument("--method", choices=METHODS, default="joint",
                   help="joint maximum likelihood (default) or the paper's four steps")
    p.add_argument("--bootstrap", type=int, default=DEFAULT_BOOTSTRAP,
                   help=f"runs of the parametric bootstrap giving the paper method's uncertainties (default {DEFAULT_BOOTSTRAP})")
    p.add_argument("--cross-axis-sd", type=float, default=DEFAULT_CROSS_AXIS_SD,
                   help="prior sd of the correction's off-diagonal (cross-axis) terms, which the wheel does not "
                   f"observe (default {DEFAULT_CROSS_AXIS_SD:.4f}: the datasheet +-2 %% as a uniform bound)")
    p.add_argument("--units", choices=("m/s2", "g", "counts"), help="units of ax, ay, az if the file does not say")
    p.add_argument("--rate", type=float, help="sample rate, Hz, for a file without a t column")
    p.add_argument("--g", type=float, default=STANDARD_GRAVITY, help="local gravity, m/s^2 (default 9.80665)")
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    p.add_argument("-o", "--output", help="write a device profile (YAML) with the correction")
    p.set_defaults(func=run_calibrate)

    q = groups["plan"].add_parser(
        "wheel",
        help="predicted uncertainties (CRB) of a wheel calibration before spinning",
        description="Print the standard uncertainty (k=1) each parameter would reach on a planned wheel "
        "run (Cramer-Rao bound), for a perfect sensor mounted at --mount-deg and the paper's coast-down "
        "profile scaled to --speed over --seconds.",
    )
    q.add_argument("--radius", type=float, required=True, help="distance from the sensor to the axis, m")
    q.add_argument("--tilt-deg", type=float, default=45.0, help="tilt of the axis from the vertical, deg (default 45)")
    q.add_argument("--noise", type=float, default=0.08, help="sensor noise sd per sample, m/s^2 (default 0.08)")
    q.add_argument("--rate", type=float, default=200.0, help="sample rate, Hz (default 200)")
    q.add_argument("--seconds", type=float, default=90.0, help="length of the run, s (default 90)")
    q.add_argument("--speed", type=float, default=9.0, help="initial angular velocity, rad/s (default 9)")
    q.add_argument("--mount-deg", default="30,20,25",
                   help="mounting Euler angles theta,phi,psi in deg (default 30,20,25: tilted, as the paper advises)")
    q.add_argument("--json", action="store_true", help="print the plan as JSON")
    q.set_defaults(func=run_plan)


def run_calibrate(args) -> int:
    if args.radius is not None and not args.radius > 0:
        raise DataError(f"--radius {args.radius} must be a positive distance in metres")
    rec = load_recording(args.recording, units=args.units, rate=args.rate)
    result = calibrate_wheel(rec, radius=args.radius, tilt_deg=args.tilt_deg, method=args.method, g=args.g,
                             bootstrap=args.bootstrap, cross_axis_sd=args.cross_axis_sd)
    if args.output:
        # profiles validate and write atomically: nothing half-written on error
        from accelrig.profiles import profile_from_result, save_profile

        save_profile(profile_from_result(result, rec), args.output)
    if args.json:
        print(to_json(result.to_json_dict()))
        return 0
    print(_human(result))
    if args.output:
        print(f"profile written to {args.output}")
    return 0


def _human(result) -> str:
    q = result.quality
    lines = [f"wheel calibration, method {result.method}: {q['n_samples']} samples, {q['duration_s']:.1f} s, "
             f"{q['turns']:.1f} turns, residual rms {q['residual_rms']:.4f} m/s^2"]
    lines.append("parameter            value                          uncertainty (k=1)")
    for name, est in result.parameters.items():
        if isinstance(est.value, list):
            value = " ".join(f"{v:+.6g}" for v in est.value)
            unc = " ".join(f"{u:.2g}" for u in est.uncertainty)
        else:
            value, unc = f"{est.value:+.6g}", f"{est.uncertainty:.2g}"
        lines.append(f"{name:<20} {value:<30} {unc} {est.unit}")
    c = result.correction
    lines.append("correction: calibrated = C (raw - b)")
    lines.append("  C diag " + " ".join(f"{x:.6f}" for x in np.diag(c.matrix))
                 + "   u " + " ".join(f"{x:.2g}" for x in np.diag(c.matrix_uncertainty)))
    lines.append("  b      " + " ".join(f"{x:+.5f}" for x in c.bias)
                 + "   u " + " ".join(f"{x:.2g}" for x in c.bias_uncertainty) + " m/s^2")
    lines.append(f"uncertainties: {q['uncertainty']}; {q['time_s']:.2f} s")
    for w in result.warnings:
        lines.append(f"warning: {w}")
    return "\n".join(lines)


def run_plan(args) -> int:
    try:
        mount = [float(x) for x in args.mount_deg.split(",")]
    except ValueError:
        mount = []
    if len(mount) != 3:
        raise DataError(f"--mount-deg {args.mount_deg!r} needs three comma-separated angles in degrees")
    rows = plan_wheel(args.radius, args.tilt_deg, args.noise, args.rate, args.seconds, args.speed, mount)
    if args.json:
        print(to_json({"procedure": "wheel", "bound": "Cramer-Rao, k=1",
                          "parameters": {r.name: {"value": r.value, "uncertainty": r.sd, "unit": r.unit}
                                         for r in rows}}))
        return 0
    print(f"wheel plan: r = {args.radius} m, tilt {args.tilt_deg} deg, noise {args.noise} m/s^2, "
          f"{args.rate:g} Hz x {args.seconds:g} s, start {args.speed} rad/s; best reachable uncertainty (CRB, k=1)")
    print(f"{'parameter':<22}{'nominal':>14}{'uncertainty':>14}  unit")
    for r in rows:
        print(f"{r.name:<22}{r.value:>14.6g}{r.sd:>14.2g}  {r.unit}")
    return 0
