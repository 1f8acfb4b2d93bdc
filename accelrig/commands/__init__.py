"""CLI subcommands, one module each (see accelrig.cli)."""


def add_time_range(parser, start_note: str = "", stop_note: str = "") -> None:
    """--start/--stop for a command that reads a recording (load_recording's start/stop); a command may say
    what they are for in its own terms (``start_note``, ``stop_note``, appended to the help)."""
    for name, what, note in (("start", "keep samples from", start_note), ("stop", "keep samples before", stop_note)):
        parser.add_argument(f"--{name}", metavar="T",
                            help=f"{what} T: seconds from the first sample, or (segments) an ISO-8601 UTC time "
                            "such as 2026-11-24T01:00:00Z" + (f"; {note}" if note else ""))


def warn_loss(rec, result) -> None:
    """Heavy link loss in the input: on stderr now and in the result's (and the profile's) warnings."""
    import sys

    from accelrig.recording import loss_warning

    if (loss := loss_warning(rec)) is not None:
        result.warnings.append(loss)
        print(f"accelrig: warning: {loss}", file=sys.stderr)
