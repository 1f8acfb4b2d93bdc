"""accelrig profile list|show|validate|diff|apply|add: device profiles on disk and in the store.

PROFILE arguments are a file path, or a device identity to look up in the
store (the latest profile, or the one closest to --date); ``apply`` also
takes ``auto``: the profile of the device the recording names, closest in
time to when it was recorded.  ``apply`` chooses among the profiles that
apply to the recording (chip, range, scale, units) and says which.
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np

from accelrig.commands import add_time_range, add_units, load_from_args
from accelrig.commands.profile_output import STORE_DEFAULT
from accelrig.errors import AccelrigError, ProfileError, printable
from accelrig.profiles.apply import apply_profile
from accelrig.profiles.io import Profile, load_profile
from accelrig.profiles.store import DEFAULT_MAX_AGE_DAYS, ProfileStore
from accelrig.recording import Recording, save_recording
from accelrig.result import Estimate, format_value, to_json
from accelrig.units import STANDARD_GRAVITY


def register(sub, groups) -> None:
    group = groups["profile"]

    p = group.add_parser("list", help="list the stored profiles", description="List the profiles in the store.")
    _store_args(p, choose=False)
    p.add_argument("--device", help="only this device identity")
    p.set_defaults(func=run_list)

    p = group.add_parser("show", help="show a profile", description="Show a profile: device, correction, quality, noise.")
    p.add_argument("profile", help="profile file, or a device identity in the store")
    _store_args(p)
    fmt = p.add_mutually_exclusive_group()
    fmt.add_argument("--json", action="store_true", help="print the whole profile as JSON")
    fmt.add_argument("--yaml", action="store_true", help="print the profile file as stored")
    p.set_defaults(func=run_show)

    p = group.add_parser("validate", help="check profile files against schema v1",
                         description="Check profile files; one line per bad file naming the field, non-zero exit.")
    p.add_argument("files", nargs="+", help="profile files")
    p.set_defaults(func=run_validate)

    p = group.add_parser("diff", help="differences between two profiles",
                         description="Differences between two profiles, field by field; the correction with "
                         "normalised errors E_n (k = 2). Exit 0 when equal, 1 when they differ.")
    p.add_argument("a", help="profile file or device identity")
    p.add_argument("b", help="profile file or device identity")
    _store_args(p)
    p.set_defaults(func=run_diff)

    p = group.add_parser("apply", help="calibrate a recording with a profile",
                         description="Apply a profile's correction to a recording. Refuses data from another "
                         "device, range or unit unless --force.")
    p.add_argument("profile", help="profile file, a device identity in the store (its latest profile that "
                   "applies to the recording: same chip, range and scale), or 'auto' (the device the recording "
                   "names, its applicable profile closest to when it was recorded)")
    p.add_argument("recording", help="raw recording (.csv, .npz, or segments: a .parquet file or a directory)")
    p.add_argument("-o", "--output", required=True, help="calibrated recording (.csv or .npz)")
    p.add_argument("--force", action="store_true",
                   help="apply even to data from another device, range or unit, and replace an existing -o file")
    p.add_argument("--uncertainty", action="store_true",
                   help="add channels u_ax, u_ay, u_az: standard uncertainty of each calibrated sample")
    add_units(p)
    add_time_range(p)
    _store_args(p)
    p.set_defaults(func=run_apply)

    p = group.add_parser("add", help="put profile files into the store",
                         description="Validate profile files and keep copies in the store, filed by device.")
    p.add_argument("files", nargs="+", help="profile files")
    _store_args(p, choose=False)
    p.set_defaults(func=run_add)


def _store_args(p, choose: bool = True) -> None:
    p.add_argument("--store", metavar="DIR", help=f"profile store (default: {STORE_DEFAULT})")
    if choose:
        p.add_argument("--date", help="choose the stored profile closest to this date (ISO, e.g. 2026-11-01)")
        p.add_argument("--max-age-days", type=float, default=DEFAULT_MAX_AGE_DAYS,
                       help=f"warn when the chosen profile is older than this (default {DEFAULT_MAX_AGE_DAYS:g})")


def say(text: str = "") -> None:
    """Print one line of what a profile says: its strings come from a file, so control characters are
    shown escaped (errors.printable), never sent to the terminal."""
    print(printable(text))


def warn(message: str) -> None:
    print(f"accelrig: warning: {printable(message)}", file=sys.stderr)


def resolve(spec: str, args, date: str | None = None, data: Recording | None = None) -> Profile:
    """A profile from a path, or from the store by device identity (with ``data``: the profile that applies
    to that recording, and stderr says which was chosen and why others were passed over)."""
    path = Path(spec)
    if path.exists() or path.suffix.lower() in (".yaml", ".yml"):
        return load_profile(path)
    choice = ProfileStore(args.store).choose(spec, date or args.date, args.max_age_days,
                                             data=None if data is None else data.meta,
                                             units=None if data is None else data.units)
    # stderr names the profile chosen, always (the notes already do when some were passed over)
    for note in choice.notes or [choice.chosen_as]:
        print(f"accelrig: {printable(note)}", file=sys.stderr)
    for w in choice.warnings:
        warn(w)
    return choice.stored.profile


# ------------------------------------------------------------------ list / show / validate / add


def run_list(args) -> int:
    store = ProfileStore(args.store)
    entries, broken = store.scan(args.device)
    if not entries and not broken:
        say(f"no profiles in {store.root}" + (f" for device {args.device!r}" if args.device else ""))
        return 0
    from accelrig.tables import fitted_lines

    titles = ("device", "created", "procedure", "method", "residual rms", "file")
    rows = []
    for e in entries:
        rms = e.profile.data["quality"]["residual_rms"]
        rows.append([printable(c) for c in (   # escaped first, so the columns line up
            e.identity, e.profile.data["provenance"]["created"], e.profile.procedure, e.profile.method,
            "-" if rms is None else f"{rms:.4g} m/s^2", str(e.path.relative_to(store.root)))])
    # an entry that cannot be used is listed as such (and said why on stderr); the others stay usable
    rows += [["BROKEN", "-", "-", "-", "-", printable(str(b.path.relative_to(store.root)))] for b in broken]
    # 80 columns: the file (under the store) stacks under the table when it does not fit beside the rest
    for line in fitted_lines(titles, rows, (0, 1, 2, 3, 4, 5)):
        say(line)
    for b in broken:
        warn(b.warning())
    return 0


def _fmt(value, unc=None, digits: int = 6) -> str:
    if isinstance(value, list):
        if unc is None:
            return "[" + ", ".join(_fmt(v, None, digits) for v in value) + "]"
        return "[" + ", ".join(_fmt(v, u, digits) for v, u in zip(value, unc, strict=True)) + "]"
    if unc is None:
        return f"{value:.{digits}g}"
    return " +- ".join(format_value(value, unc))   # rounded together, as on every face


def run_show(args) -> int:
    profile = resolve(args.profile, args)
    if args.json:
        print(to_json(profile.data))   # JSON escapes control characters itself
        return 0
    if args.yaml:
        from accelrig.profiles.io import dump_yaml

        sys.stdout.write(dump_yaml(profile.data))
        return 0
    d = profile.data
    dev, cal, prov = d["device"], d["calibration"], d["provenance"]
    _say_wrapped(f"profile      {profile.path}")
    _say_wrapped(f"device       {dev['identity'] or '(unknown)'}  chip {dev['chip'] or '?'}  driver {dev['driver'] or '?'}"
          + (f"  WHO_AM_I 0x{dev['who_am_i']:02X}" if dev["who_am_i"] is not None else ""))
    rng = f"+-{dev['range_g']:g} g" if dev["range_g"] is not None else "range ?"
    rate = f"{dev['rate']:g} Hz" if dev["rate"] is not None else "rate ?"
    _say_wrapped(f"             {rng}, {rate}, raw in {d['units']} (counts x nominal scale)")
    # g as every face prints it (report.checks.gravity_text): to 0.01 mm/s^2, with its u where recorded
    g_u = cal["settings"].get("g_u")
    gravity = f"g = {cal['g']:.5f}" + (f" +- {g_u:.2g}" if isinstance(g_u, int | float) else "") + " m/s^2"
    _say_wrapped(f"calibration  {cal['procedure']} / {cal['method']} ({cal['model']}), {gravity}")
    _say_wrapped(f"created      {prov['created']} by accelrig {prov['software_version']}"
          + (f" from {prov['recording_samples']} samples" if prov["recording_samples"] else ""))
    corr = cal["correction"]
    _say_wrapped("correction   calibrated = C @ (raw - b), uncertainties k = 1")
    for i in range(3):
        _say_wrapped(f"  C[{i}]       {_fmt(corr['matrix'][i], corr['matrix_uncertainty'][i])}")
    _say_wrapped(f"  b (m/s^2)  {_fmt(corr['bias'], corr['bias_uncertainty'])}")
    if cal["parameters"]:
        _say_wrapped("parameters")
        width = max(len(n) for n in cal["parameters"])
        for name, est in cal["parameters"].items():
            # angles in degrees, as the calibrate command, the TUI and the certificate show them
            value, u, unit = Estimate(est["value"], est["uncertainty"], est["unit"]).for_display()
            _say_wrapped(f"  {name.ljust(width)}  {_fmt(value, u)} {unit}")
    q = d["quality"]
    for key, value in q.items():
        if value is None:
            continue
        # a count is an integer (YAML may hold it as 11000.0: it read "1.1e+04")
        count = key.startswith("n_") or key == "dof"
        numbers = isinstance(value, list) and all(isinstance(v, int | float) for v in value)
        shown = (f"{value:.0f}" if count and isinstance(value, float) and value.is_integer()
                 else f"{value:.4g}" if isinstance(value, float)
                 else "[" + ", ".join(f"{v:.4g}" for v in value) + "]" if numbers
                 else value if isinstance(value, str)
                 else _short(value, 80 - len(f"quality      {key} ")))
        unit = " m/s^2" if key == "residual_rms" else ""
        _say_wrapped(f"quality      {key} {shown}{unit}")
    if d["noise"] is not None:
        n = d["noise"]
        _say_wrapped(f"noise        {n['duration']:.0f} s still at {n['rate']:.1f} Hz, {n['date']}")
        for axis, f in n["axes"].items():
            dens = f["density"]
            ug = 1e6 / STANDARD_GRAVITY
            bi = f["bias_instability"]
            _say_wrapped(f"  {axis}: {_fmt(dens['value'] * ug, dens['uncertainty'] * ug)} ug/sqrt(Hz)"
                  + (f", bias instability {bi['value'] * ug:.1f} ug at {f['bias_instability_tau']:.3g} s" if bi else ""))
    for w in d["warnings"]:
        _say_wrapped(f"warning      {w}")
    return 0


def _say_wrapped(text: str) -> None:
    """A labelled line of ``profile show`` wrapped at 80 columns under its value (a sentence is read whole)."""
    import textwrap

    for line in textwrap.wrap(text, 80, subsequent_indent=" " * 13, break_long_words=False, break_on_hyphens=False):
        say(line)


def run_validate(args) -> int:
    """Every file is checked and reported, one line each, whatever the others hold."""
    if len(args.files) == 1:
        p = load_profile(args.files[0])
        say(f"{args.files[0]}: ok (schema v1, device {p.identity or '(unknown)'}, {p.procedure}/{p.method})")
        return 0
    failed = 0
    for name in args.files:
        try:
            p = load_profile(name)
        except AccelrigError as exc:
            failed += 1
            print(f"accelrig: error: {printable(exc)}", file=sys.stderr)
            continue
        say(f"{name}: ok (schema v1, device {p.identity or '(unknown)'}, {p.procedure}/{p.method})")
    return ProfileError.exit_code if failed else 0


def run_add(args) -> int:
    store = ProfileStore(args.store)
    profiles = [load_profile(name) for name in args.files]   # all valid before any is stored
    for p in profiles:
        say(store.add(p))
    return 0


# ------------------------------------------------------------------ diff


SUMMARISED = ("calibration.correction.covariance", "calibration.parameter_covariance",
              "calibration.correction.matrix_uncertainty", "calibration.correction.bias_uncertainty")


def _diff_node(a, b, path: str, lines: list[str]) -> None:
    if a == b:
        return
    if isinstance(a, dict) and isinstance(b, dict):
        for key in list(a) + [k for k in b if k not in a]:
            child = f"{path}.{key}" if path else key
            if key not in b:
                lines.append(f"{child}: only in A")
            elif key not in a:
                lines.append(f"{child}: only in B")
            else:
                _diff_node(a[key], b[key], child, lines)
        return
    if path in SUMMARISED and isinstance(a, list) and isinstance(b, list):
        xa, xb = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
        if xa.shape == xb.shape:
            lines.append(f"{path}: differs (largest change {np.max(np.abs(xa - xb)):.3g})")
            return
    lines.append(f"{path}: {_short(a)} -> {_short(b)}")


def diff_profiles(a: Profile, b: Profile) -> list[str]:
    """Human-readable differences; the correction elements with E_n (k = 2)."""
    lines: list[str] = []
    _diff_node(a.data, b.data, "", lines)
    ca, cb = a.correction, b.correction
    if not (np.array_equal(ca.matrix, cb.matrix) and np.array_equal(ca.bias, cb.bias)):
        va = np.concatenate([ca.matrix.ravel(), ca.bias])
        vb = np.concatenate([cb.matrix.ravel(), cb.bias])
        u = np.sqrt(np.diag(ca.covariance) + np.diag(cb.covariance))
        names = [f"C[{i}][{j}]" for i in range(3) for j in range(3)] + [f"b[{i}]" for i in range(3)]
        lines.append("correction A -> B, E_n = (A - B) / sqrt(U_A^2 + U_B^2), U = 2u (|E_n| <= 1: consistent):")
        for name, x, y, uu in zip(names, va, vb, u, strict=True):
            en = (x - y) / (2.0 * uu) if uu > 0 else (math.inf if x != y else 0.0)
            lines.append(f"  {name:8s} {x:+.6g} -> {y:+.6g}  E_n {en:+.2f}")
    return lines


def _short(value, width: int = 80) -> str:
    """A structure as JSON on one line of at most ``width`` characters (``--json`` shows it whole)."""
    text = json.dumps(value)
    return text if len(text) <= width else text[:width - 3] + "..."


def run_diff(args) -> int:
    a, b = resolve(args.a, args), resolve(args.b, args)
    lines = diff_profiles(a, b)
    for line in lines:
        say(line)
    return 1 if lines else 0


# ------------------------------------------------------------------ apply


def run_apply(args) -> int:
    from accelrig.files import writable_target

    writable_target(args.output, args.force, inputs=[args.recording])
    rec = load_from_args(args, args.recording)
    if args.profile == "auto":
        identity = rec.meta.get("identity")
        if not identity:
            raise ProfileError(f"{args.recording} does not name its device, so 'auto' cannot choose a profile",
                               "give the profile file or the device identity")
        profile = resolve(str(identity), args, date=args.date or rec.meta.get("start_time"), data=rec)
    else:
        profile = resolve(args.profile, args, data=rec)
    out, warnings = apply_profile(profile, rec, force=args.force, uncertainty=args.uncertainty)
    for w in warnings:
        warn(w)
    inputs = [args.recording] + ([profile.path] if profile.path is not None else [])
    save_recording(out, args.output, overwrite=args.force, inputs=inputs)
    return 0
