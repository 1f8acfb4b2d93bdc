"""accelrig verify slider-crank STEP.csv [STEP.csv ...] --crank-radius M --rod-length M [...]"""

from __future__ import annotations

from dataclasses import replace

from accelrig.commands import add_units, load_from_args, warn_loss
from accelrig.errors import DataError, ProfileError
from accelrig.procedures.slider_crank.settings import CRANK_RADIUS, FILE_SETTINGS, ROD_LENGTH
from accelrig.settings import add_arguments, values_from_args


def register(sub, groups) -> None:
    p = groups["verify"].add_parser(
        "slider-crank",
        help="verify a calibration on a slider-crank stand (frequency response, crank radius, backlash)",
        description="Verify under motion that a (static) calibration holds: one recording per motor speed step, "
        "or one recording with a 'step' column. Per step: PCA to the axis of motion, interpolated-DFT start, "
        "sine fit with harmonics by variable projection, crank radius from the first harmonic against the "
        "caliper radius +- clearance.",
        epilog="Exit status: 0 when the calibration holds under motion, 1 when it does not hold or the verdict is "
        "inconclusive, 2-6 when the input or the analysis fails (one line on stderr).",
    )
    p.add_argument("recordings", nargs="+", metavar="STEP.csv",
                   help="recordings (.csv, .npz, or segments: a .parquet file or a directory), in step order")
    add_arguments(p, [s for s in FILE_SETTINGS if s is not ROD_LENGTH])
    geometry = p.add_mutually_exclusive_group(required=True)
    # one of the two is required (the group says so); the setting's own "required" would read as both
    add_arguments(geometry, [replace(ROD_LENGTH, default=None)])
    geometry.add_argument("--lambda", dest="lam", type=float, metavar="L",
                          help="crank radius / rod length, instead of --rod-length")
    add_units(p)
    p.add_argument("--rate", type=float, metavar="HZ", help="sample rate for files without a t column")
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    p.set_defaults(func=run)


def run(args) -> int:
    from accelrig.procedures.slider_crank.procedure import verify_slider_crank
    from accelrig.result import to_json

    if args.rod_length is None:
        if not (args.lam is not None and 0 < args.lam < 1):
            raise DataError(f"--lambda {args.lam} must lie between 0 and 1")
        args.rod_length = CRANK_RADIUS.parse(args.crank_radius) / args.lam
    values = values_from_args(FILE_SETTINGS, args)
    recordings = [(path, load_from_args(args, path)) for path in args.recordings]
    correction = None
    profile_warnings: list[str] = []
    if values["profile"]:
        correction, profile_warnings = _profile_correction(values["profile"], recordings, values["force"])
    from accelrig.commands.progress import Progress

    with Progress(f"analysing {len(recordings)} recording(s)"):
        result = verify_slider_crank(recordings, values["crank_radius"], values["rod_length"], values["clearance"],
                                     correction=correction, speeds=values["speeds"], harmonics=values["harmonics"],
                                     profile=values["profile"])
    result.warnings = profile_warnings + result.warnings
    for _, rec in recordings:
        warn_loss(rec, result)
    if args.json:
        print(to_json(result.to_json_dict()))
    else:
        print(format_report(result))
    return 0 if result.details["verdict"] == "holds" else 1


def _profile_correction(path: str, recordings, force: bool = False) -> tuple:
    """The profile's correction, after checking it fits every recording (device, range, units)."""
    from accelrig.profiles import load_profile
    from accelrig.profiles.apply import check_compatible

    profile = load_profile(path)
    warnings: list[str] = []
    for label, rec in recordings:
        if "calibrated_with" in rec.meta:
            raise ProfileError(f"{label} is already calibrated (its metadata name a profile)",
                               "verify the raw recording with --profile, or the calibrated one without it")
        for warning in check_compatible(profile, rec.meta, rec.units, force):
            if warning not in warnings:
                warnings.append(warning)
    return profile.correction, warnings


def coverage_text(k: float, dof: float | None) -> str:
    """A coverage factor with the effective dof it is Student's t on ("2.13 (nu_eff 21)"; "2.00" when the dof
    are beyond counting)."""
    return f"{k:.2f}" + (f" (nu_eff {dof:.0f})" if dof is not None and dof < 1e4 else "")


def format_report(result) -> str:
    """Human-readable frequency response table and verdict (mm and degrees at the edge)."""
    from accelrig.procedures.slider_crank.analysis import COVERAGE_FACTOR_LABELS
    from accelrig.result import format_value

    v = result.details
    lines = [
        f"slider-crank verification: r = {v['crank_radius_m'] * 1e3:.3f} mm ("
        + (f"clearance +- {v['clearance_m'] * 1e3:.3f} mm" if v["clearance_m"] > 0 else "no clearance given")
        + f"), l = {v['rod_length_m'] * 1e3:.2f} mm, lambda = {v['lambda']:.4f}"
        + (f", profile {v['profile']}" if v["profile"] else ""),
        "",
        "| step | f / Hz | u(f) / Hz | FFT peak / Hz | A1 / m/s^2 | model r w^2 | ratio | radius / mm | u / mm | "
        "k for U (nu_eff) | in clearance (k) | backlash | motor | axis angle x,y,z / deg |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for s in v["steps"]:
        motor = "limited" if s["motor_limited"] else "ok"
        angles = ",".join(f"{a:.1f}" for a in s["axis_angles_deg"])
        lines.append(
            f"| {s['index'] + 1} | {s['frequency_hz']['value']:.5f} | {s['frequency_hz']['uncertainty']:.2g} | "
            f"{s['fft_peak_hz']:.2f} | {s['amplitude']['value']:.4f} | {s['model_amplitude']:.4f} | "
            f"{s['ratio']['value']:.5f} +- {s['ratio']['uncertainty']:.5f} | "
            f"{' | '.join(format_value(s['radius_m']['value'] * 1e3, s['radius_m']['uncertainty'] * 1e3))} | "
            f"{coverage_text(s.get('radius_k', 2.0), s.get('radius_dof'))} | "
            f"{'yes' if s['within_clearance'] else 'NO'} ({s['clearance_k']:.2f}) | "
            f"{'YES' if s['backlash'] else 'no'} | {motor} | {angles} |"
        )
    lines.append("")
    # three k, three questions (analysis.coverage_factors): say which is which, once
    lines.extend(f"{COVERAGE_FACTOR_LABELS.get(key, key)}: {text}" for key, text in v.get("coverage_factors", {}).items())
    r = result.parameters["radius"]
    value_mm, u_mm = format_value(r.value * 1e3, r.uncertainty * 1e3)   # as the TUI and certificate round it
    lines.append(
        f"radius from the motion: {value_mm} +- {u_mm} mm (k = 1) over steps "
        f"{', '.join(str(i + 1) for i in v['used_steps'])}, chi2 = {v['radius_chi2']:.2f} for {v['radius_dof']} dof; "
        f"expanded U = {format_value(r.value * 1e3, v.get('radius_k', 2.0) * r.uncertainty * 1e3)[1]} mm at k = "
        f"{coverage_text(v.get('radius_k', 2.0), v.get('radius_nu_eff'))}"
    )
    if v.get("radius_profile_u_m"):
        lines.append(f"  u includes the profile's own u of the scale along the motion, "
                     f"{100 * v['profile_scale_u_rel']:.3g} % ({format_value(r.value * 1e3, v['radius_profile_u_m'] * 1e3)[1]}"
                     " mm; its gain u, u(g) included): the same in every step, so judged once, never averaged down")
    lines.append(
        "motor roll-off: " + (f"tops out near {v['rolloff_hz']:.2f} Hz" if v["rolloff_hz"] is not None else "none seen")
    )
    for w in result.warnings:
        lines.append(f"warning: {w}")
    if v["profile"]:
        verdict = {"holds": "the static calibration holds under motion",
                   "does not hold": "the static calibration does not hold under motion",
                   "inconclusive": "inconclusive, whether the static calibration holds under motion is not decided"}
    else:   # raw data: no calibration was applied, so none is judged (the reason says so)
        verdict = {"holds": "the raw readings agree with the caliper",
                   "does not hold": "the raw readings disagree with the caliper",
                   "inconclusive": "inconclusive"}
    lines.append(f"verdict: {verdict.get(v['verdict'], v['verdict'])}: {v['verdict_reason']}")
    return "\n".join(lines)
