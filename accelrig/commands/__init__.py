"""CLI subcommands, one module each (see accelrig.cli)."""

# What --units accepts wherever a command reads a recording: the units of ax, ay, az.
UNITS = ("m/s2", "g", "mg", "counts")


def add_units(parser, what: str = "ax, ay, az") -> None:
    """--units and --range-g for a command that reads a recording (load_from_args applies them): the one way
    to read data in g, milli-g or counts without a scale in the file."""
    parser.add_argument("--units", choices=UNITS,
                        help=f"units of {what} (default: what the file declares, else m/s2); g and mg (milli-g) "
                        "are standard gravity's")
    parser.add_argument("--range-g", type=float, metavar="G",
                        help="sensor range +-G g, for counts without a scale in the file (16-bit: scale = G g / 32768)")


def load_from_args(args, path, **options):
    """The recording at ``path`` as the command's --units, --range-g, --rate, --start and --stop say (each only
    if the command has it; ``options`` override them)."""
    from accelrig.recording import load_recording
    from accelrig.settings import Setting
    from accelrig.units import scale_for_range

    kwargs = {name: getattr(args, name, None) for name in ("units", "rate", "start", "stop")}
    kwargs.update(options)
    rec = load_recording(path, **kwargs)
    if getattr(args, "range_g", None) is not None:
        Setting("range_g", "sensor range", unit="g", low=0.0, low_open=True, high=64.0).parse(args.range_g)
        rec.meta["range_g"] = args.range_g
        rec.meta["scale"] = scale_for_range(args.range_g)
    return rec


def add_time_range(parser, start_note: str = "", stop_note: str = "") -> None:
    """--start/--stop for a command that reads a recording (load_recording's start/stop); a command may say
    what they are for in its own terms (``start_note``, ``stop_note``, appended to the help)."""
    for name, what, note in (("start", "keep samples from", start_note), ("stop", "keep samples before", stop_note)):
        parser.add_argument(f"--{name}", metavar="T",
                            help=f"{what} T: seconds from the first sample, or a UTC time such as 2026-11-24T01:00:00Z "
                            "(for recordings that carry UTC time: segments, files from record or the daemon)" + (f"; {note}" if note else ""))


def warn_loss(rec, result) -> None:
    """Heavy link loss in the input: on stderr now and in the result's (and the profile's) warnings."""
    import sys

    from accelrig.recording import loss_warning

    if (loss := loss_warning(rec)) is not None:
        result.warnings.append(loss)
        print(f"accelrig: warning: {loss}", file=sys.stderr)
