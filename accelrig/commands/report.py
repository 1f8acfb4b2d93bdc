"""accelrig report SOURCE -o FILE.html|FILE.pdf: a calibration certificate a lab can hand over.

The machinery (and matplotlib, the ``report`` extra) is imported only when the command runs.
"""

from __future__ import annotations


def register(sub, groups) -> None:
    p = sub.add_parser(
        "report",
        help="calibration certificate (HTML with figures, or PDF) from a profile, a result or a campaign",
        description="Write a calibration certificate in the manner of ISO/IEC 17025: the device, the method and "
        "its paper, the conditions, the recording's hash, the correction and every parameter with u (k = 1) and "
        "U (k = 2), the uncertainty budget, quality figures, verdicts, warnings, and figures in physical units. "
        "SOURCE is a device profile (.yaml), a result saved with --json, a campaign report "
        "(calibrate rotary --campaign C.yaml -o R.yaml) or a campaign file (its tests are analysed). "
        "A .pdf is printed by headless Chromium.",
    )
    p.add_argument("source", help="profile, saved result (.json/.yaml) or rotary campaign")
    p.add_argument("-o", "--output", required=True, metavar="FILE", help="certificate to write: .html or .pdf")
    p.add_argument("--noise", metavar="NOISE.json", help="Allan curves from 'accelrig noise REC --json' (the "
                   "same recording as the profile's noise figures) to plot the measured curve")
    p.add_argument("--no-figures", action="store_true", help="leave the figures out (no matplotlib needed)")
    p.add_argument("--number", help="certificate number")
    p.add_argument("--customer", help="customer (name and address)")
    p.add_argument("--operator", help="who performed the calibration")
    p.add_argument("--location", help="where it was performed")
    p.add_argument("--temperature", help="ambient temperature, e.g. '23.0 ± 1.0 °C'")
    p.add_argument("--humidity", help="relative humidity, e.g. '45 ± 10 %%'")
    p.set_defaults(func=run)


def run(args) -> int:
    from accelrig.report import load_source, write_certificate
    from accelrig.report.source import load_noise

    src = load_source(args.source)
    if args.noise:
        src.noise = load_noise(args.noise, src.noise)
    conditions = {"certificate_number": args.number, "customer": args.customer, "operator": args.operator,
                  "location": args.location, "temperature": args.temperature, "humidity": args.humidity}
    write_certificate(src, args.output, conditions, figures=not args.no_figures)
    print(f"wrote {args.output}")
    return 0
