"""accelrig noise REC.csv: noise figures of a still recording from its Allan deviation."""

from __future__ import annotations

import sys

from accelrig.geometry import AXES
from accelrig.units import STANDARD_GRAVITY

UG = 1e6 / STANDARD_GRAVITY   # (m/s^2) -> micro-g


def register(sub, groups) -> None:
    p = sub.add_parser(
        "noise",
        description="Overlapping Allan deviation of a recording of the sensor lying still, per axis: "
        "white-noise density (one-sided, ug/sqrt(Hz) as on datasheets: sigma(tau) = N / sqrt(2 tau)), "
        "bias instability (IEEE 952: minimum / 0.664) and rate random walk where the record is long enough. "
        "Uncertainties are standard (k = 1).",
    )
    p.add_argument("recording", help="still recording (.csv or .npz), a few minutes or more")
    p.add_argument("--json", action="store_true", help="print figures and Allan curves as JSON")
    p.add_argument("--profile", metavar="P.yaml", help="store the figures in this profile (rewritten atomically)")
    p.add_argument("--force", action="store_true", help="store into a profile of another device or range")
    p.add_argument("--units", choices=("m/s2", "g", "counts"), help="units of the recording if it does not say")
    p.set_defaults(func=run)


def run(args) -> int:
    from accelrig.estimation.allan import noise_figures
    from accelrig.profiles.apply import check_compatible
    from accelrig.profiles.io import load_profile, save_profile, utc_now
    from accelrig.recording import load_recording
    from accelrig.result import to_json

    rec = load_recording(args.recording, units=args.units)
    profile = None
    if args.profile:
        profile = load_profile(args.profile)   # refuse a bad profile before computing anything
        for w in check_compatible(profile, rec.meta, "m/s^2", args.force):
            print(f"accelrig: warning: {w}", file=sys.stderr)
    report = noise_figures(rec)
    if profile is not None:
        profile.data["noise"] = report.to_profile_dict(utc_now())
        save_profile(profile, args.profile)
    if args.json:
        section = report.to_profile_dict(utc_now())
        section["arrays"] = {k: v.tolist() for k, v in report.arrays().items()}
        print(to_json(section))
        return 0
    print(noise_table(report))
    if profile is not None:
        print(f"stored in {args.profile}")
    return 0


def noise_table(report) -> str:
    """The closing-note table: one row per axis, datasheet units."""
    lines = [
        f"{report.n_samples} samples, {report.duration:.1f} s at {report.rate:.2f} Hz; "
        "overlapping Allan deviation at octave taus; uncertainties k = 1",
        "",
        "| axis | density ug/sqrt(Hz) | density (m/s^2)/sqrt(Hz) | bias instability ug (tau) | rate random walk (m/s^2)/sqrt(s) |",
        "|---|---|---|---|---|",
    ]
    for axis in AXES:
        a = report.axes[axis]
        d = a.density
        bi = (f"{a.bias_instability.value * UG:.1f} +- {a.bias_instability.uncertainty * UG:.1f} "
              f"({a.bias_instability_tau:.3g} s)") if a.bias_instability else "not reached"
        rw = (f"{a.random_walk.value:.3g} +- {a.random_walk.uncertainty:.2g}") if a.random_walk else "not seen"
        lines.append(f"| {axis} | {d.value * UG:.1f} +- {d.uncertainty * UG:.1f} | "
                     f"{d.value:.4g} +- {d.uncertainty:.2g} | {bi} | {rw} |")
    lines.append("")
    lines.append("density is one-sided (datasheet convention): sigma(tau) = N / sqrt(2 tau), "
                 "per-sample sd = N sqrt(rate / 2); bias instability = min sigma / 0.664 (IEEE 952)")
    notes = sorted({n for axis in AXES for n in report.axes[axis].notes})
    lines.extend(f"note: {n}" for n in notes)
    return "\n".join(lines)
