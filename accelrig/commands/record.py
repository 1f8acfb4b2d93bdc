"""accelrig record URL --seconds N -o FILE"""

from __future__ import annotations

import sys
import time

from accelrig.errors import DataError, DeviceError


def register(sub, groups) -> None:
    p = sub.add_parser(
        "record",
        description="Record a device to a file. A progress line is shown on a terminal; "
        "nothing but the file is written otherwise.",
    )
    p.add_argument("url", help="device URL, e.g. 'sim://static?seed=1' or replay://run.csv")
    length = p.add_mutually_exclusive_group()
    length.add_argument("--seconds", type=float, help="seconds of device time to record")
    length.add_argument("--samples", type=int, help="number of samples to record")
    p.add_argument("-o", "--output", required=True, help="output file (.csv interchange or .npz native)")
    p.add_argument("--units", choices=("m/s2", "counts"), default="m/s2", help="units of ax, ay, az (default m/s2)")
    p.add_argument("--force", action="store_true", help="replace the output file if it exists")
    p.set_defaults(func=run)


def run(args) -> int:
    from accelrig.acquisition.recorder import Recorder
    from accelrig.acquisition.session import Session, State
    from accelrig.profiles.flash import flash_url_profile
    from accelrig.recording import save_recording
    from accelrig.settings import Setting

    # nan, inf and a month are refused like any bad number (a NaN length would never be reached)
    Setting("seconds", "", unit="s", low=0.0, low_open=True, high=30 * 86400.0).parse(args.seconds)
    Setting("samples", "", kind="int", low=1, high=2 ** 40).parse(args.samples)
    from accelrig.files import writable_target

    writable_target(args.output, args.force)   # refused before recording, not after
    show = sys.stderr.isatty()

    def progress(p: Recorder) -> None:
        sys.stderr.write(
            f"\r{p.samples} samples  {p.seconds:7.2f} s  {p.rate:8.1f} Hz  missing {p.missing} ({p.gap_events} gaps)  "
        )
        sys.stderr.flush()

    session = Session.open_and_start(args.url, record=True, prepare=flash_url_profile)

    def pull() -> bool:
        """Give the pump a moment; a device that went away ends the command as it would have ended a read."""
        time.sleep(0.02)
        if session.interrupted:
            raise DeviceError(session.interrupted)
        return session.state == State.ENDED

    try:
        if args.seconds is None and args.samples is None and session.driver.endless:
            raise DataError(f"{args.url} never ends by itself", "give --seconds or --samples")
        session.recorder.take_until(pull, args.seconds, args.samples, progress if show else None)
        rec = session.recorder.recording("counts" if args.units == "counts" else "m/s^2")
    finally:
        session.stop()
    if show:
        sys.stderr.write("\n")
    from accelrig.recording import loss_warning

    if (loss := loss_warning(rec)) is not None:
        rec.meta.setdefault("warnings", []).append(loss)   # the file says so too
        print(f"accelrig: warning: {loss}", file=sys.stderr)
    save_recording(rec, args.output, overwrite=args.force)
    return 0
