"""accelrig record URL [--seconds N] -o OUTPUT

Samples stream to disk segments as they arrive (accelrig.segments), so memory
stays bounded however long the recording runs, and Ctrl+C keeps everything
taken so far.
"""

from __future__ import annotations

import gc
import signal
import sys
import time
from pathlib import Path

from accelrig.errors import DataError, DeviceError, DeviceStalled

SINGLE_FILE_SUFFIXES = (".csv", ".npz", ".parquet")
# A .csv or .npz output is assembled in memory at the end (about 40 bytes a sample while it
# is built); beyond this many samples (17 min at 2048 Hz, under 100 MB) it is refused up
# front, or an open-ended recording stops there: a folder of segments holds any length.
IN_MEMORY_SAMPLES = 1 << 21
# stderr that is not a terminal (a pipe, a log, a CI job) gets whole progress lines this often: a person
# reading the log sees the recording advance, and a long run does not fill the log
LOG_PROGRESS_SECONDS = 10.0


def register(sub, groups) -> None:
    p = sub.add_parser(
        "record",
        description="Record a device to disk. Samples stream to segment files as they arrive (memory stays "
        "bounded however long it runs); Ctrl+C (or SIGTERM) stops and keeps everything recorded so far. "
        "Progress goes to stderr (a line updated in place on a terminal, a whole line every "
        f"{LOG_PROGRESS_SECONDS:.0f} s when stderr is a pipe or a log), and at the end one line says what was "
        "kept: samples, duration, rate, file and any samples the link lost; stdout stays empty. A link that "
        "is down when the recording ends (a BLE device reconnecting, a device gone) leaves the time from the "
        "last sample to the end as a gap of that length in the file, counted and said like any other loss. "
        "Exit status: 0 the recording ran to its end (any loss is said on stderr and kept as gaps in the file; "
        "more than 1%% lost is a warning); 3 the device went away before the end (what was taken is kept); "
        "130 Ctrl+C or SIGTERM cut a requested --seconds/--samples short (what was taken is kept).",
    )
    p.add_argument("url", help="device URL, e.g. 'sim://static?seed=1' or replay://run.csv")
    length = p.add_mutually_exclusive_group()
    length.add_argument("--seconds", type=float, help="seconds of device time to record (default: until Ctrl+C "
                        "or the end of a finite source)")
    length.add_argument("--samples", type=int, help="number of samples to record")
    p.add_argument("-o", "--output", required=True,
                   help="a directory (Parquet segments, rotated; any duration), or one file: .parquet "
                   "(any duration), .csv interchange or .npz native (assembled in memory at the end: at most "
                   f"{IN_MEMORY_SAMPLES} samples, 17 min at 2048 Hz)")
    p.add_argument("--units", choices=("m/s2", "counts"), default="m/s2",
                   help="units of ax, ay, az in a .csv or .npz output (default m/s2); segments always hold "
                   "int16 counts and the scale")
    p.add_argument("--segment-minutes", type=float, default=60.0,
                   help="directory output: start a new segment after this many minutes (default 60)")
    p.add_argument("--segment-mb", type=float, default=256.0,
                   help="directory output: or once the open segment reaches this many MiB (default 256)")
    p.add_argument("--csv-copies", action="store_true",
                   help="directory output: also write an interchange CSV beside each finished segment")
    p.add_argument("--force", action="store_true", help="replace the output file if it exists")
    p.set_defaults(func=run)


def run(args) -> int:

    from accelrig.acquisition.recorder import Recorder, streaming_writer
    from accelrig.acquisition.session import Session, State
    from accelrig.files import writable_target
    from accelrig.profiles.flash import flash_url_profile
    from accelrig.segments import DirectoryLock, SegmentWriter, recover
    from accelrig.settings import Setting

    # nan, inf and a month are refused like any bad number (a NaN length would never be reached)
    Setting("seconds", "", unit="s", low=0.0, low_open=True, high=30 * 86400.0).parse(args.seconds)
    Setting("samples", "", kind="int", low=1, high=2 ** 40).parse(args.samples)
    Setting("segment_minutes", "", unit="min", low=0.0, low_open=True, high=7 * 1440.0).parse(args.segment_minutes)
    Setting("segment_mb", "", unit="MiB", low=0.0, low_open=True, high=2 ** 20).parse(args.segment_mb)
    output = Path(args.output)
    single = output.suffix.lower() in SINGLE_FILE_SUFFIXES
    if single:   # refused before recording, not after; a symlink is written through to its target
        output = writable_target(output, args.force)
    elif output.exists() and not output.is_dir():
        raise DataError(f"{output}: exists and is not a folder: refusing to record into it",
                        "give a folder for segments, or a file name ending .csv, .npz or .parquet")
    # one file: its segment goes to a hidden directory beside it, then becomes the file
    directory = output.parent / f".{output.name}.parts" if single else output
    if directory.is_dir():
        # another process recording into it: refused now, naming it, before the device is opened (the writer
        # takes the lock for the whole recording); a lock left by a killed record is released
        DirectoryLock(directory).release()
    if single and directory.is_dir() and not any(directory.iterdir()):
        directory.rmdir()   # left empty by a record stopped before its first sample
    if single and directory.exists():
        raise DataError(f"{directory} holds the segments of an earlier record into {output} that did not finish",
                        f"read them with e.g. 'accelrig noise {directory}', then remove the directory")
    if directory.is_dir():
        for report in recover(directory):   # a record into this directory that was killed
            print(f"accelrig record: {report}", file=sys.stderr)
    show = sys.stderr.isatty()
    next_log = [time.monotonic() + LOG_PROGRESS_SECONDS]

    def progress(p: Recorder) -> None:
        line = f"{p.samples} samples  {p.seconds:7.2f} s  {p.rate:8.1f} Hz  missing {p.missing} ({p.gap_events} gaps)"
        if show:   # one line rewritten in place
            sys.stderr.write(f"\r{line}  ")
        elif time.monotonic() >= next_log[0]:   # a pipe or a log: whole lines, now and then
            sys.stderr.write(f"accelrig record: {line}\n")
            next_log[0] += LOG_PROGRESS_SECONDS
        else:
            return
        sys.stderr.flush()

    def make_writer(info) -> SegmentWriter:
        return streaming_writer(info, directory,
                                segment_seconds=float("inf") if single else args.segment_minutes * 60.0,
                                segment_bytes=float("inf") if single else args.segment_mb * 2**20,
                                csv=args.csv_copies and not single)

    session = Session.open_and_start(args.url, record=True, prepare=flash_url_profile, writer=make_writer)
    # as the daemon does: what is loaded by now stays for the whole recording; out of the cyclic collector's
    # sight a full collection takes about 1 ms instead of 100, during which the device is not read
    gc.freeze()
    recorder, writer = session.recorder, session.recorder.writer
    in_memory = single and output.suffix.lower() != ".parquet"
    limit = args.samples
    if in_memory:
        wanted = args.samples if args.seconds is None else args.seconds * session.info.nominal_rate
        if wanted is not None and wanted > IN_MEMORY_SAMPLES:
            session.stop()
            recorder.close()
            for path in writer.close():
                path.unlink()
            directory.rmdir()
            raise DataError(f"{output}: {wanted:.0f} samples do not fit a {output.suffix} file, which is built in "
                            f"memory (at most {IN_MEMORY_SAMPLES} samples, "
                            f"{IN_MEMORY_SAMPLES / session.info.nominal_rate / 60:.0f} min at this rate)",
                            "record into a folder of segments (-o DIR) or a .parquet file: any length, read by "
                            "every accelrig command and by numpy/pandas through pyarrow")
        limit = min(limit or IN_MEMORY_SAMPLES, IN_MEMORY_SAMPLES)

    def outage() -> str | None:
        """Why no sample can arrive now (a gap's cause: the link down, the device gone), or None."""
        if session.interrupted:
            kind = "stalled" if isinstance(session.interruption, DeviceStalled) else "disconnected"
            return f"{kind}: {session.interrupted}"
        down = session.driver.link_down
        return f"disconnected: {down}" if down else None

    def pull() -> bool:
        """Give the pump a moment; a device that went away ends the recording with what was taken, and so
        does the time asked for passing (on the host's clock) while the link is down."""
        time.sleep(0.02)
        if session.state in (State.ENDED, State.DISCONNECTED, State.FAILED):
            return True
        return (args.seconds is not None and recorder.samples > 0 and outage() is not None
                and recorder.seconds + recorder.silent_for() >= args.seconds)

    previous_term = signal.signal(signal.SIGTERM, _raise_interrupt)
    stopped_by = None
    try:
        try:
            recorder.take_until(pull, args.seconds, limit, progress)
        except _Terminated:
            stopped_by = "SIGTERM"
        except KeyboardInterrupt:
            stopped_by = "Ctrl+C"
    finally:
        signal.signal(signal.SIGTERM, previous_term)
        why = outage()
        if why is not None and not recorder.full:
            # the link is down as the recording ends: the time since the last sample is lost, and said
            silent = recorder.silent_for()
            if args.seconds is not None:
                silent = min(silent, args.seconds - recorder.seconds)
            if silent > 1.0 / session.info.nominal_rate:   # at least one sample missing
                recorder.end_gap(why, silent - 1.0 / session.info.nominal_rate)
        session.stop()
        recorder.close()
        finished = writer.close()
        if show:
            sys.stderr.write("\n")
    kept = f"{recorder.samples} samples ({recorder.seconds:.2f} s)"
    from accelrig.recording import loss_of

    # gaps of unknown size (a disconnect, a stall) count by the time they lasted, estimated at the nominal rate
    summary = loss_of(recorder.samples, recorder.gap_log, session.info.nominal_rate)
    lost = summary.summary()
    if recorder.open_end is not None:
        end = recorder.open_end
        lost += (f"; no sample came in the last {end['seconds'] + 1.0 / session.info.nominal_rate:.2f} s, "
                 f"counted as lost ({end['cause']})")
    loss = summary.warning()
    if loss is not None:
        print(f"accelrig: warning: {loss}", file=sys.stderr)
    if not recorder.samples:
        if single:
            directory.rmdir()
        raise DeviceError(f"{args.url} delivered no samples", session.interrupted)
    if single:
        _assemble(finished, directory, output, args.units, session.info, recorder, loss)
    if session.interrupted:
        raise DeviceError(f"the device went away ({session.interrupted}); kept {kept} in {output}")
    if in_memory and args.samples is None and args.seconds is None and recorder.samples >= IN_MEMORY_SAMPLES:
        print(f"accelrig record: stopped at {IN_MEMORY_SAMPLES} samples, the most a {output.suffix} file holds; "
              f"kept {kept} in {output} (record into a folder, -o DIR, for longer)", file=sys.stderr)
    if stopped_by:
        print(f"accelrig record: stopped by {stopped_by}; kept {kept} in {output}; {lost}", file=sys.stderr)
        # Ctrl+C is how an open-ended recording ends; cutting a requested length short is not success
        return 0 if args.seconds is None and args.samples is None else 130
    # said on a terminal and in a log alike: a piped record is otherwise silent for its whole length
    # the rate of the stretches without gaps (a gap's time would lower it)
    print(f"accelrig record: kept {recorder.samples} samples ({recorder.seconds:.2f} s at {recorder.rate:.1f} Hz) "
          f"in {output}; {lost}", file=sys.stderr)
    return 0


class _Terminated(KeyboardInterrupt):
    """SIGTERM: stops a recording as Ctrl+C does, and is named as itself."""


def _raise_interrupt(signum, frame) -> None:
    raise _Terminated


def _assemble(finished: list[Path], directory: Path, output: Path, units: str, info, recorder,
              loss: str | None = None) -> None:
    """Turn the one segment of a single-file output into that file, then remove the hidden directory."""
    import os

    from accelrig.acquisition.recorder import recording_meta
    from accelrig.recording import read_segments, save_recording

    if output.suffix.lower() == ".parquet":
        os.replace(finished[0], output)
    else:
        rec = read_segments(directory, units="counts" if units == "counts" else None)
        rates = recording_meta(info, rec.t, rec.meta["gaps"], recorder.missing)
        rec.meta.update(delivered_rate=rates["delivered_rate"], device_rate=rates["device_rate"],
                        lost_samples=rates["lost_samples"], lost_share=rates["lost_share"])
        if loss is not None:
            rec.meta.setdefault("warnings", []).append(loss)   # the file says so too
        for name in ("segments", "source"):
            rec.meta.pop(name, None)
        save_recording(rec, output)
        for path in finished:
            path.unlink()
    directory.rmdir()
