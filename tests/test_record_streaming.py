"""`accelrig record` streams through the segment writer; Ctrl+C keeps what it has; every reader takes segments."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pyarrow.parquet as pq
import pytest

from accelrig.acquisition.driver import driver_for
from accelrig.cli import main
from accelrig.recording import load_recording


def accelrig(*args, **kw):
    return subprocess.run([sys.executable, "-m", "accelrig", *args], capture_output=True, text=True, timeout=120, **kw)


def samples_on_disk(parent) -> int:
    """Samples in the open segments under ``parent`` now (0 while there is none or it has no whole frame)."""
    from accelrig.errors import AccelrigError
    from accelrig.segments import read_arrays

    if not list(parent.glob("*.seg")):
        return 0
    try:
        return len(read_arrays(parent, units="counts")[0])
    except (AccelrigError, OSError, ValueError):   # the header frame not written yet
        return 0


def wait_for_samples(proc, parent, at_least=1, timeout=60.0):
    """Wait until the recording process has written ``at_least`` samples to its open segment (counted on disk,
    not guessed from a fixed sleep: a loaded machine can hold the recorder back for seconds)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if samples_on_disk(parent) >= at_least:
            return
        assert proc.poll() is None, proc.stderr.read()
        time.sleep(0.1)
    raise AssertionError(f"fewer than {at_least} samples written within {timeout:g} s")


def with_ctrl_c_default():
    """Ctrl+C's signal at its default in the child, as in a terminal's foreground job: a test run started in the
    background of a non-interactive shell (nohup, `cmd &`, some CI runners) ignores SIGINT, and a child inherits
    that, so `record` never saw the signal and the test waited out its timeout."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


@pytest.mark.parametrize("output", ["segments", "run.parquet", "run.npz", "run.csv"])
def test_ctrl_c_keeps_everything_recorded_so_far(tmp_path, output):
    out = tmp_path / output
    proc = subprocess.Popen([sys.executable, "-m", "accelrig", "record", "sim://still?seed=3&rate=1000", "-o",
                             str(out)], stderr=subprocess.PIPE, text=True, preexec_fn=with_ctrl_c_default)
    seg_dir = out if output == "segments" else tmp_path / f".{output}.parts"
    wait_for_samples(proc, seg_dir, at_least=600)
    proc.send_signal(signal.SIGINT)
    code = proc.wait(timeout=30)
    err = proc.stderr.read()
    assert code == 0, err
    assert "stopped by Ctrl+C; kept" in err and "Traceback" not in err
    kept = int(err.split("kept ")[1].split()[0])
    rec = load_recording(out)
    assert len(rec) == kept > 500
    assert not (tmp_path / f".{output}.parts").exists()          # the hidden parts directory is gone
    if output == "segments":
        assert [p.suffix for p in out.iterdir()] == [".parquet"]  # finished, nothing left open


def test_ctrl_c_cutting_a_requested_length_short_says_so_and_keeps_it(tmp_path):
    out = tmp_path / "segs"
    proc = subprocess.Popen([sys.executable, "-m", "accelrig", "record", "sim://still?seed=3&rate=1000",
                             "--seconds", "600", "-o", str(out)], stderr=subprocess.PIPE, text=True)
    wait_for_samples(proc, out)
    proc.send_signal(signal.SIGTERM)
    assert proc.wait(timeout=30) == 130
    assert "stopped by SIGTERM; kept" in proc.stderr.read()   # the signal it was, not "Ctrl+C"
    assert len(load_recording(out)) > 0


def test_record_to_a_directory_rotates_and_reads_back_exactly(tmp_path):
    out = tmp_path / "segs"
    assert main(["record", "sim://still?seed=1&pace=fast&rate=2048", "--seconds", "150",
                 "--segment-minutes", "1", "-o", str(out)]) == 0
    files = sorted(out.glob("*.parquet"))
    # a segment closes at the first block after its minute: at pace=fast a block can hold many seconds (the
    # simulator outruns the reader on a busy machine), so 150 s make three segments, or two long ones
    assert len(files) in (2, 3) and all(f.name.startswith("sim-random-1.") for f in files)
    first = load_recording(files[0], units="counts")
    assert first.duration >= 60.0 - 1 / 2048
    info = json.loads(pq.ParquetFile(files[0]).schema_arrow.metadata[b"accelrig"])
    assert info["meta"]["device"].startswith("sim://still") and info["meta"]["time_base"] == "utc"
    assert info["units"] == "counts" and info["scale"] > 0
    rec = load_recording(out)
    with driver_for("sim://still?seed=1&pace=fast&rate=2048") as d:   # the same device, deterministic
        from accelrig.acquisition.recorder import record
        direct = record(d, seconds=150, units="counts")
    np.testing.assert_array_equal(load_recording(out, units="counts").acc, direct.acc)
    np.testing.assert_allclose(rec.t, direct.t, atol=1e-9)
    assert rec.meta["time_origin"] > 1.7e9                        # UTC epoch seconds of the first sample


def test_every_reader_takes_a_directory_over_a_time_range(tmp_path, cli):
    # (the commands in this process: a new interpreter for each cost seconds of imports under load)
    out = tmp_path / "still"
    assert main(["record", "sim://still?seed=2&pace=fast&rate=400", "--seconds", "400", "-o", str(out)]) == 0
    r = cli("noise", str(out), "--start", "100", "--stop", "300", "--json")
    assert r.returncode == 0, r.stderr
    figures = json.loads(r.stdout)
    assert abs(figures["still_segment"]["of_total"] - 200.0) < 0.1
    r = cli("record", f"replay://{out}?pace=fast&start=10&stop=20", "-o", str(tmp_path / "part.npz"))
    assert r.returncode == 0, r.stderr
    part = load_recording(tmp_path / "part.npz")
    assert abs(part.duration - 10.0) < 0.01
    r = cli("noise", str(out), "--start", "tomorrow")
    assert r.returncode != 0 and r.stderr.count("\n") == 1 and "neither seconds nor an ISO-8601 time" in r.stderr


def test_record_into_a_directory_a_crash_left_open_recovers_it_first(tmp_path, capsys):
    from accelrig.segments import SegmentWriter

    out = tmp_path / "segs"
    w = SegmentWriter(out, stem="sim-random-1", meta={}, scale=0.001)
    w.write(np.arange(10) / 100.0 + 1.7e9, np.zeros((10, 3), np.int16))
    os.close(w._fd)                                   # the recording process died here
    os.close(w._dir_lock._fd)                         # ... and the kernel released its lock (the file stays)
    assert main(["record", "sim://still?seed=1&pace=fast", "--seconds", "1", "-o", str(out)]) == 0
    assert "closed after a crash: 10 samples in 1 complete blocks kept; no block lost" in capsys.readouterr().err
    assert sorted(p.suffix for p in out.iterdir()) == [".parquet", ".parquet"]


def test_gaps_the_link_reported_are_recorded_where_they_happened(tmp_path):
    out = tmp_path / "lossy"
    assert main(["record", "sim://still?seed=4&pace=fast&rate=1000&block=50&drop=0.2", "--seconds", "20",
                 "-o", str(out)]) == 0
    rec = load_recording(out, units="counts")
    gaps = rec.meta["gaps"]
    assert len(gaps) > 20 and {g["cause"] for g in gaps} == {"samples lost by the device or link"}
    # every jump in the sample times is a gap record at that index, of the size the jump says
    step = np.median(np.diff(rec.t))
    jumps = np.flatnonzero(np.diff(rec.t) > 1.5 * step) + 1
    assert [g["index"] for g in gaps] == jumps.tolist()
    sizes = np.rint(np.diff(rec.t)[jumps - 1] / step).astype(int) - 1
    assert [g["missing"] for g in gaps] == sizes.tolist()
    # each record's duration is its missing samples' (the time between its neighbours less one period)
    assert all(g["seconds"] == pytest.approx(g["missing"] * step, rel=0.01) for g in gaps)
    # the rates over what was read: nominal, delivered (received) and device (with the gap records' samples)
    assert rec.meta["nominal_rate"] == 1000.0
    assert rec.meta["device_rate"] == pytest.approx(1000 * 1.004, rel=1e-3)
    assert rec.meta["delivered_rate"] == pytest.approx(rec.meta["device_rate"] * len(rec)
                                                       / (len(rec) + sum(g["missing"] for g in gaps)), rel=1e-3)
    assert len(rec) + sum(g["missing"] for g in gaps) == pytest.approx(20 * 1000 * 1.004, abs=60)


def test_a_csv_or_npz_too_long_for_memory_is_refused_up_front_or_stops_at_the_limit(tmp_path, capsys, monkeypatch):
    import accelrig.commands.record as record_command

    out = tmp_path / "long.csv"
    code = main(["record", "sim://still?seed=1&pace=fast&rate=2048", "--seconds", "3600", "-o", str(out)])
    err = capsys.readouterr().err
    assert code != 0 and "do not fit a .csv file" in err and "-o DIR" in err
    assert not out.exists() and not list(tmp_path.iterdir())   # nothing left behind
    # open-ended (until Ctrl+C): stops at the limit, keeps what it took, says why
    monkeypatch.setattr(record_command, "IN_MEMORY_SAMPLES", 5000)
    out = tmp_path / "capped.npz"
    assert main(["record", "sim://still?seed=1&pace=fast&rate=2048", "-o", str(out)]) == 0
    assert len(load_recording(out)) == 5000
    assert "stopped at 5000 samples, the most a .npz file holds" in capsys.readouterr().err


def _segments_with_gaps(directory, gaps, rate=200.0, n=2000):
    """A device's segments: ``n`` samples, then each gap (samples, cause, seconds) followed by ``n`` more."""
    from accelrig.segments import SegmentWriter

    meta = {"nominal_rate": rate, "identity": "sim-still-21", "device": "sim://still?seed=21", "driver": "sim",
            "chip": "sim", "range_g": 2.0, "scale": 0.001}
    t = 1_763_950_000.0
    with SegmentWriter(directory, stem="dev", meta=meta, scale=0.001) as w:
        for k, gap in enumerate([*gaps, None]):
            w.write(t + np.arange(n) / rate, np.full((n, 3), k, np.int16))
            t += n / rate
            if gap is not None:
                samples, cause, seconds = gap
                w.gap(t, samples, cause, seconds)
                t += seconds


def test_the_summary_states_the_time_gaps_of_unknown_size_took_and_the_rate_between_them(tmp_path, cli):
    """Disconnects and stalls are gaps of unknown size (-1) with a known duration: the summary said "0 samples
    lost in 2 gaps" and averaged the rate across them (171 Hz for a 200 Hz device)."""
    source = tmp_path / "flaky"
    _segments_with_gaps(source, [(-1, "disconnected: gone", 2.0), (-1, "disconnected: gone", 3.0)])
    r = cli("record", f"replay://{source}?pace=fast", "-o", tmp_path / "out.npz")
    assert r.returncode == 0, r.stderr
    summary = r.stderr.splitlines()[-1]
    assert " samples (34.99 s at 200.0 Hz) " in summary, summary
    assert summary.endswith("; 2 gaps, 5.00 s missing: about 1000 samples estimated at the nominal 200 Hz over the "
                            "2 gaps of unknown size (kept as gaps, never filled in)"), summary
    assert "about 1000 of 7000 samples (14.3%" in r.stderr


def test_the_loss_warning_follows_each_gaps_recorded_cause(tmp_path):
    """A full disk is not a cable: the read-back warning names what lost the samples, from the gap records."""
    from accelrig.recording import loss_warning

    _segments_with_gaps(tmp_path / "full", [(600, "disk full", 3.0)])
    warning = loss_warning(load_recording(tmp_path / "full"))
    assert warning.startswith("600 of 4600 samples (13.0%, more than 1%) are missing in 1 gap: 600 dropped while "
                              "the disk was full; kept as gaps, never filled in; give the recordings more disk space")
    assert "cable" not in warning and "link" not in warning
    _segments_with_gaps(tmp_path / "mixed", [(600, "disk full", 3.0), (-1, "stalled: no data for 10 s", 1.0)])
    warning = loss_warning(load_recording(tmp_path / "mixed"))
    assert "about 800 of 6800 samples" in warning and "600 dropped while the disk was full" in warning
    assert "200 not sent while the device stalled" in warning and "check the device's power" in warning


def test_a_replay_passes_each_gaps_recorded_cause_on(tmp_path, cli):
    """Replay used to pass the gaps' sizes on but not their causes: whatever was recorded from it blamed
    the link for every gap (a full disk and a stall became 'frames lost on the link')."""
    from accelrig.recording import loss_warning

    source = tmp_path / "mixed"
    _segments_with_gaps(source, [(600, "disk full", 3.0), (-1, "stalled: no data for 10 s", 1.0)])
    original = [(g["index"], g["missing"], g["cause"]) for g in load_recording(source).meta["gaps"]]
    for out in (tmp_path / "again.npz", tmp_path / "again"):   # kept in memory, and streamed to segments
        r = cli("record", f"replay://{source}?pace=fast", "-o", out)
        assert r.returncode == 0, r.stderr
        back = load_recording(out)
        assert [(g["index"], g["missing"], g["cause"]) for g in back.meta["gaps"]] == original
        assert "disk was full" in loss_warning(back) and "cable" not in loss_warning(back)


def test_a_replay_repeats_gaps_at_one_place_and_after_the_last_sample(tmp_path):
    from accelrig.acquisition.recorder import REPLAYED_GAP, record
    from accelrig.recording import Recording, save_recording

    t = np.arange(300) / 100.0
    gaps = [{"index": 100, "missing": 5, "cause": "disk full"},
            {"index": 100, "missing": -1, "cause": "crash: the recorder was restarted"},
            {"index": 200, "missing": 3},   # no cause recorded
            {"index": 300, "missing": 7, "cause": "stalled: no data for 2 s"}]   # the recording ends with it
    save_recording(Recording(t, np.tile([0.0, 0.0, 9.8], (300, 1)), "m/s^2", {},
                             {"nominal_rate": 100.0, "gaps": gaps}), tmp_path / "r.npz")
    with driver_for(f"replay://{tmp_path / 'r.npz'}?pace=fast&block=64") as d:
        back = record(d)
    assert len(back) == 300
    assert [(g["index"], g["missing"], g["cause"]) for g in back.meta["gaps"]] == [
        (100, 5, "disk full"), (100, -1, "crash: the recorder was restarted"), (200, 3, REPLAYED_GAP),
        (300, 7, "stalled: no data for 2 s")]
