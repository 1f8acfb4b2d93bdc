"""accelrig report SOURCE -o FILE.html|FILE.pdf: a calibration certificate a lab can hand over.

The machinery (and matplotlib, the ``report`` extra) is imported only when the command runs.
"""

from __future__ import annotations


def register(sub, groups) -> None:
    p = sub.add_parser(
        "report",
        help="calibration certificate (HTML with figures, or PDF) from a profile, a result or a campaign; "
        "a batch report from several",
        description="Write a calibration certificate in the manner of ISO/IEC 17025: the device, the method and "
        "its paper, the conditions, the recording's hash, the correction and every parameter with u (k = 1) and "
        "U (k = 2), the uncertainty budget, the checks, verdicts, warnings worded as findings for the customer (no advice "
        "to the operator), figures in physical units, and the settings and fit figures in an appendix. "
        "SOURCE is a device profile (.yaml), a result saved with --json, a campaign report "
        "(calibrate rotary --campaign C.yaml -o R.yaml) or a campaign file (its tests are analysed). "
        "A .pdf is printed by headless Chromium. "
        "Several SOURCEs, or a directory of them, give one batch report instead: each device's sensitivity and "
        "bias per axis with U, the group statistics, E_n against the other devices (or --reference), and "
        "outliers flagged by the rule the report states.",
    )
    p.add_argument("source", nargs="+", help="profile, saved result (.json/.yaml) or rotary campaign; several, "
                   "or a directory of them, for a batch report")
    p.add_argument("-o", "--output", required=True, metavar="FILE", help="certificate to write: .html or .pdf")
    p.add_argument("--noise", metavar="NOISE.json", help="Allan curves from 'accelrig noise REC --json' (the "
                   "same recording as the profile's noise figures) to plot the measured curve")
    p.add_argument("--recording", metavar="REC", help="the recording the profile was calibrated from, when it is "
                   "not where the profile says (its sha256 must be the profile's): the figures are drawn from it")
    p.add_argument("--force", action="store_true", help="replace FILE if it exists (an issued certificate is "
                   "never overwritten by accident)")
    p.add_argument("--no-figures", action="store_true", help="leave the figures out (no matplotlib needed)")
    p.add_argument("--reference", metavar="DEVICE", help="batch report: compare every device with this one "
                   "(its identity) instead of with the weighted mean of the others")
    p.add_argument("--number", help="certificate number")
    p.add_argument("--customer", help="customer (name and address)")
    p.add_argument("--customer-reference", metavar="REF", help="the customer's reference or order number, "
                   "printed under the customer")
    p.add_argument("--operator", help="who performed the calibration")
    p.add_argument("--approved-by", metavar="NAME", help="who authorises the certificate (printed above the "
                   "signature line; without it the name is left blank to fill in by hand)")
    p.add_argument("--location", help="where it was performed")
    p.add_argument("--temperature", help="ambient temperature, e.g. '23.0 ± 1.0 °C'")
    p.add_argument("--humidity", help="relative humidity, e.g. '45 ± 10 %%'")
    p.set_defaults(func=run)


def run(args) -> int:
    from pathlib import Path

    from accelrig.errors import DataError
    from accelrig.files import writable_target

    # before anything is rendered: an issued certificate (its number, operator) is not replaced unasked
    writable_target(args.output, args.force, inputs=list(args.source) + [f for f in (args.noise, args.recording) if f])
    conditions = {"certificate_number": args.number, "customer": args.customer,
                  "customer_reference": args.customer_reference, "operator": args.operator,
                  "approved_by": args.approved_by,
                  "location": args.location, "temperature": args.temperature, "humidity": args.humidity}
    if len(args.source) > 1 or Path(args.source[0]).is_dir():
        if args.noise:
            raise DataError("--noise belongs to one device's certificate, not to a batch report",
                            "give one SOURCE with --noise")
        if args.recording:
            raise DataError("--recording belongs to one profile's certificate, not to a batch report",
                            "give one SOURCE with --recording")
        return run_batch(args, conditions)
    if args.reference:
        raise DataError("--reference compares devices: give several sources or a directory")
    import sys

    from accelrig.report import load_source, write_certificate
    from accelrig.report.recompute import recording_hint
    from accelrig.report.source import load_noise

    src = load_source(args.source[0])
    if args.noise:
        src.noise = load_noise(args.noise, src.noise)
    if args.recording:
        src.recording_path = checked_recording(src, args.recording)
    if not args.no_figures and (hint := recording_hint(src)):
        print(f"note: {hint}", file=sys.stderr)
    write_certificate(src, args.output, conditions, figures=not args.no_figures)
    print(f"wrote {args.output}")
    return 0


def checked_recording(src, path: str) -> str:
    """``path`` when it is the recording ``src`` was calibrated from (by its sha256), else the error saying why."""
    from pathlib import Path

    from accelrig.errors import DataError
    from accelrig.recording import load_recording
    from accelrig.report.recompute import needs_recording

    if not needs_recording(src):
        raise DataError(f"--recording draws a static or wheel profile's figures; {src.path} is a {src.kind} of the "
                        f"{src.procedure} procedure" + (" that carries its own" if src.arrays else ""),
                        "leave --recording out")
    if not Path(path).exists():
        raise DataError(f"{path}: no such file", "give the recording the profile was calibrated from")
    got, wanted = load_recording(path).content_hash(), src.provenance.get("recording_hash")
    if got != wanted:
        raise DataError(f"{path}: not the recording this profile was calibrated from (its sha256 is {got}, the "
                        f"profile's {wanted})", "give the file the calibration read")
    return path


def run_batch(args, conditions: dict) -> int:
    import sys

    from accelrig.report.batch import batch_report_html, load_batch
    from accelrig.report.certificate import write_page

    batch = load_batch(args.source, args.reference)
    for file, why in batch.skipped:
        print(f"not read: {file}: {why}", file=sys.stderr)
    write_page(lambda: batch_report_html(batch, conditions, figures=not args.no_figures), args.output)
    flagged = batch.outliers
    if flagged:
        verdict = f"{len(flagged)} outliers: " + ", ".join(f"{j.entry.device} {j.entry.quantity} {j.entry.axis}"
                                                           for j in flagged)
    elif batch.unjudged:
        verdict = (f"outliers not judged: {len(batch.sources)} devices are too few to measure the batch's own "
                   f"spread; name a reference device (--reference) or compare 4 or more")
    else:
        verdict = "no outlier"
    print(f"wrote {args.output}: {len(batch.sources)} sources, {verdict}")
    return 0
