"""accelrig calibrate rotary: the oscillating-disk bench of paper 001 (one test or a campaign)."""

from __future__ import annotations

import sys

from accelrig.errors import DataError
from accelrig.procedures.rotary.settings import TEST_SETTINGS
from accelrig.settings import add_arguments, values_from_args


def register(sub, groups) -> None:
    p = groups["calibrate"].add_parser(
        "rotary",
        help="rotary oscillating bench (paper 001): sampling rate, sensitivity, uncertainty budget",
        description="One test: --mems M.csv (counts or a recording with its scale, own clock) with --encoder E.csv (t,theta on an accurate "
        "clock; or a theta channel in the MEMS file) and the geometry. A campaign: --campaign CAMPAIGN.yaml. "
        "Sensitivities are in counts per m/s^2, uncertainties standard (k = 1) unless labelled.",
    )
    p.add_argument("--campaign", metavar="YAML", help="campaign file listing the tests (see docs/rotary.md)")
    p.add_argument("--mems", metavar="FILE", help="MEMS recording (.csv or .npz): counts, or what the file declares")
    p.add_argument("--encoder", metavar="FILE", help="encoder log t,theta[,ref] (s, rad, m/s^2) on an accurate clock")
    add_arguments(p, TEST_SETTINGS)
    p.add_argument("--units", help="units of the MEMS file's ax,ay,az (default: what the file declares, as "
                   "'accelrig record' does, else counts)")
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    p.add_argument("-o", "--output", metavar="REPORT", help="campaign report file (.yaml or .md), written atomically")
    p.add_argument("--force", action="store_true", help="replace the report file if it exists")
    p.set_defaults(func=run)


def run(args) -> int:
    if args.campaign:
        given = [f"--{n.replace('_', '-')}" for n in ("mems", "encoder", "radius", "tangential", "radial",
                                                      "nominal_rate", "frequency") if getattr(args, n) is not None]
        if given:
            raise DataError(f"--campaign takes its tests from the YAML; drop {', '.join(given)}")
        if args.output:
            from accelrig.files import writable_target

            writable_target(args.output, args.force, inputs=[args.campaign])   # refused before the tests run
        return _run_campaign(args)
    if args.output:
        raise DataError("-o/--output writes a campaign report", "use it with --campaign, or --json for one test")
    missing = [f"--{n.replace('_', '-')}" for n in ("mems", "radius", "tangential", "radial", "nominal_rate")
               if getattr(args, n) is None]
    if missing:
        raise DataError(f"one test needs {', '.join(missing)}", "or give --campaign CAMPAIGN.yaml")
    import numpy as np

    from accelrig.commands import warn_loss
    from accelrig.procedures.rotary.bench import RotarySetup, analyse_test, load_test_inputs
    from accelrig.result import format_value, to_json

    v = values_from_args(TEST_SETTINGS, args)
    setup = RotarySetup(radius=v["radius"], radius_uncertainty=v["radius_uncertainty"], ref_radius=v["ref_radius"])
    from accelrig.commands.progress import Progress

    with Progress(f"analysing {args.mems}"):
        mems, encoder = load_test_inputs(args.mems, args.encoder, v["nominal_rate"], units=args.units)
        result = analyse_test(mems, encoder, v["tangential"], v["radial"], v["nominal_rate"],
                              v["frequency"], v["rate_method"], setup)
    analysis_warnings = list(result.warnings)
    warn_loss(mems, result)   # heavy link loss: on stderr now, and in the result
    if args.json:
        print(to_json(result.to_calibration_result().to_json_dict()))
        return 0
    fs = result.sample_rate
    print(f"sample rate  {' +- '.join(format_value(fs.value, fs.uncertainty))} Hz  (nominal {result.nominal_rate:g} Hz, "
          f"by {result.rate_method})")
    print(f"excitation   {result.frequency.value:.5f} Hz, theta0 {np.degrees(result.theta0.value):.3f} deg "
          f"({2 * np.degrees(result.theta0.value):.2f} deg peak to peak)")
    for axis, s in result.sensitivity.items():
        s_text, u_text = format_value(s.value, s.uncertainty)
        print(f"S_{axis}          {s_text} +- {u_text} counts per m/s^2  ({s.component}, "
              f"reference {s.reference_amplitude:.3f} m/s^2)")
    dc = result.dc_sensitivity
    print(f"S_{dc.axis} from DC  {dc.value:.3f} counts per m/s^2  (reported, not used: offset and tilt enter it)")
    for w in analysis_warnings:   # warn_loss printed its own
        print(f"warning: {w}", file=sys.stderr)
    return 0


def _run_campaign(args) -> int:
    from accelrig.commands.progress import Progress
    from accelrig.procedures.rotary.campaign import report_markdown, run_campaign, write_report
    from accelrig.result import to_json

    losses = []   # heavy link loss per test: in the report, and said on stderr as the single test says it

    def on_test(test, result):
        progress.step(f"test {test.index} done: {test.label}")
        if result.quality.get("link_loss"):
            losses.append(f"test {test.index} ({test.label}): {result.quality['link_loss']}")

    with Progress(f"analysing the campaign {args.campaign}") as progress:
        report = run_campaign(args.campaign, on_test=on_test)
    for loss in losses:   # after the progress line is gone
        print(f"accelrig: warning: {loss}", file=sys.stderr)
    if args.output:
        write_report(report, args.output, overwrite=args.force, inputs=[args.campaign])
    if args.json:
        print(to_json(report.to_json_dict()))
    elif not args.output:
        print(report_markdown(report), end="")
    return 0
