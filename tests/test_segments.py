"""The streaming segment writer: exact round trip, rotation, atomic finishing, crash recovery, disk full,
and every reader over a directory and a time range."""

from __future__ import annotations

import errno
import json
import os
import re
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest

from accelrig import segments
from accelrig.errors import DataError, StorageError, StorageFull
from accelrig.recording import load_recording, read_segments
from accelrig.segments import SegmentWriter, read_arrays, recover, scan, to_ns

RATE = 2048.0
T0 = 1_763_950_000.123456   # a UTC epoch time: float64 holds it to ~0.24 us


def block(i: int, n: int = 64, t0: float = T0, jitter: bool = True):
    """Block ``i`` of a deterministic stream: (t, counts, theta)."""
    rng = np.random.default_rng(i)
    k = np.arange(i * n, (i + 1) * n)
    t = t0 + k / RATE + (rng.normal(0, 20e-6, n) if jitter else 0.0)
    counts = rng.integers(-32768, 32768, (n, 3)).astype(np.int16)
    return t, counts, np.sin(k / 100.0)


def write_blocks(writer: SegmentWriter, blocks: range, **kw):
    for i in blocks:
        t, c, theta = block(i, **kw)
        writer.write(t, c, {"theta": theta} if writer.channels else None)


def expected(blocks: range, **kw):
    parts = [block(i, **kw) for i in blocks]
    return (np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts]),
            np.concatenate([p[2] for p in parts]))


def test_round_trip_is_exact_counts_times_channels_and_metadata(tmp_path):
    meta = {"device": "sim://still?seed=1", "identity": "sim-random-1", "range_g": 2.0, "nominal_rate": RATE}
    with SegmentWriter(tmp_path, stem="bench-a", meta=meta, scale=0.000598, channels=("theta",)) as w:
        write_blocks(w, range(40))
    files = sorted(tmp_path.iterdir())
    assert [f.suffix for f in files] == [".parquet"]            # finished, nothing open or temporary left
    t, counts, theta = expected(range(40))
    # read without accelrig: pyarrow alone, raw int16 counts and int64 ns times
    table = pq.read_table(files[0])
    assert table.schema.field("ax").type == "int16"
    stored_ns = table.column("time").cast("int64").to_numpy()
    np.testing.assert_array_equal(stored_ns, to_ns(t))
    np.testing.assert_array_equal(segments.ns_to_seconds(stored_ns), t)      # float64 epoch times exactly
    np.testing.assert_array_equal(np.column_stack([table.column(a).to_numpy() for a in ("ax", "ay", "az")]), counts)
    np.testing.assert_array_equal(table.column("theta").to_numpy(), theta)
    info = json.loads(table.schema.metadata[b"accelrig"])
    assert info["scale"] == 0.000598 and info["meta"]["identity"] == "sim-random-1" and info["samples"] == t.size
    # and through accelrig, in counts and in m/s^2
    t_rel, acc, units, channels, rmeta = read_arrays(tmp_path, units="counts")
    np.testing.assert_array_equal(acc, counts)
    assert rmeta["time_origin_ns"] == to_ns(t)[0]
    np.testing.assert_allclose(t_rel, t - t[0], atol=1e-9)
    rec = read_segments(tmp_path)
    np.testing.assert_array_equal(rec.acc, counts * 0.000598)
    assert rec.meta["identity"] == "sim-random-1" and rec.units == "m/s^2"


def test_pandas_reads_a_finished_segment_without_accelrig(tmp_path):
    pandas = pytest.importorskip("pandas")
    with SegmentWriter(tmp_path, stem="dev", meta={}, scale=0.001) as w:
        write_blocks(w, range(3))
    frame = pandas.read_parquet(next(tmp_path.glob("*.parquet")))
    assert list(frame.columns) == ["time", "ax", "ay", "az"]
    assert str(frame["time"].dt.tz) == "UTC" and len(frame) == 192
    assert frame["ax"].dtype == np.int16


def test_rotation_by_duration_keeps_every_sample_in_order(tmp_path):
    with SegmentWriter(tmp_path, stem="dev", meta={}, scale=0.001, segment_seconds=1.0) as w:
        write_blocks(w, range(100), jitter=False)   # 6400 samples, 3.1 s
        assert w.segments_finished == 3            # rotated while writing, not only at close
    files = sorted(tmp_path.glob("*.parquet"))
    assert len(files) == 4
    spans = []
    for f in files:
        info = json.loads(pq.ParquetFile(f).schema_arrow.metadata[b"accelrig"])
        spans.append((info["first_ns"] - to_ns([T0])[0]) / 1e9)
        assert (info["last_ns"] - info["first_ns"]) / 1e9 < 1.0 + 64 / RATE
    assert spans[0] == 0 and all(b - a >= 1.0 for a, b in zip(spans, spans[1:], strict=False))
    t, counts, _ = expected(range(100), jitter=False)
    np.testing.assert_array_equal(read_arrays(tmp_path, units="counts")[1], counts)


def test_rotation_by_size(tmp_path):
    with SegmentWriter(tmp_path, stem="dev", meta={}, scale=0.001, segment_bytes=20_000) as w:
        write_blocks(w, range(60))                 # 64 x 14 bytes + 20 framing per block: ~22 blocks a segment
    files = sorted(tmp_path.glob("*.parquet"))
    assert len(files) == 3
    t, counts, _ = expected(range(60))
    np.testing.assert_array_equal(read_arrays(tmp_path, units="counts")[1], counts)


def test_a_reader_gets_the_open_segment_up_to_its_last_complete_block(tmp_path):
    w = SegmentWriter(tmp_path, stem="dev", meta={}, scale=0.001)
    write_blocks(w, range(10))
    assert w.open_path.suffix == ".seg"
    np.testing.assert_array_equal(read_arrays(tmp_path, units="counts")[1], expected(range(10))[1])
    assert recover(tmp_path) == []                 # a live writer's segment is left alone
    w.close()


def test_finishing_is_atomic_and_a_full_disk_leaves_the_open_segment(tmp_path, monkeypatch):
    import pyarrow.parquet as pq_module

    w = SegmentWriter(tmp_path, stem="dev", meta={}, scale=0.001)
    write_blocks(w, range(10))
    real = pq_module.ParquetWriter.write_table

    def full(self, table, *a, **k):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(pq_module.ParquetWriter, "write_table", full)
    with pytest.raises(StorageFull, match="disk is full"):
        w.close()
    assert [p.suffix for p in tmp_path.iterdir()] == [".seg"]   # no half Parquet file, no temporary
    monkeypatch.setattr(pq_module.ParquetWriter, "write_table", real)
    finished = w.close()                                          # space returned: it finishes now
    assert [p.suffix for p in finished] == [".parquet"] and [p.suffix for p in tmp_path.iterdir()] == [".parquet"]
    np.testing.assert_array_equal(read_arrays(tmp_path, units="counts")[1], expected(range(10))[1])


def test_a_rotation_the_full_disk_cannot_finish_keeps_writing(tmp_path, monkeypatch):
    import pyarrow.parquet as pq_module

    real = pq_module.ParquetWriter.write_table

    def full(self, table, *a, **k):
        raise OSError(errno.ENOSPC, "No space left on device")

    w = SegmentWriter(tmp_path, stem="dev", meta={}, scale=0.001, segment_seconds=1.0)
    monkeypatch.setattr(pq_module.ParquetWriter, "write_table", full)
    write_blocks(w, range(50), jitter=False)        # rotates at 1 s: the first segment cannot be finished
    assert len(w.pending) == 1 and w.samples_written == 50 * 64
    np.testing.assert_array_equal(read_arrays(tmp_path, units="counts")[1], expected(range(50), jitter=False)[1])
    monkeypatch.setattr(pq_module.ParquetWriter, "write_table", real)
    assert len(w.close()) == 2 and not w.pending
    assert sorted(p.suffix for p in tmp_path.iterdir()) == [".parquet", ".parquet"]
    np.testing.assert_array_equal(read_arrays(tmp_path, units="counts")[1], expected(range(50), jitter=False)[1])


def test_disk_full_injected_leaves_no_partial_block(tmp_path, monkeypatch):
    """ENOSPC part-way through a block (os.write patched): the block is wholly absent; writing resumes."""
    w = SegmentWriter(tmp_path, stem="dev", meta={}, scale=0.001)
    write_blocks(w, range(5))
    real_write = os.write
    state = {"full": True}

    def write(fd, data):
        if state["full"] and fd == w._fd:
            real_write(fd, bytes(data[: len(data) // 2]))     # half the frame lands, then the disk is full
            raise OSError(errno.ENOSPC, "No space left on device")
        return real_write(fd, data)

    monkeypatch.setattr(os, "write", write)
    t, c, theta = block(5)
    with pytest.raises(StorageFull):
        w.write(t, c)
    assert scan(w.open_path).lost_bytes == 0 and w.samples_written == 5 * 64
    state["full"] = False
    w.gap(t[0], 64, "disk full")
    write_blocks(w, range(6, 8))
    w.close()
    rec = read_segments(tmp_path, units="counts")
    np.testing.assert_array_equal(rec.acc, np.concatenate([expected(range(5))[1], expected(range(6, 8))[1]]))
    assert rec.meta["gaps"][0] | {"segment": None} == {"index": 320, "missing": 64, "cause": "disk full",
                                                      "seconds": None, "segment": None}


@pytest.fixture
def tiny_tmpfs(tmp_path):
    """A 2 MiB tmpfs (root only); skipped where mounting is not allowed (the injected test covers that)."""
    mount = tmp_path / "tmpfs"
    mount.mkdir()
    done = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=2M", "tmpfs", str(mount)], capture_output=True)
    if done.returncode:
        pytest.skip(f"cannot mount a tmpfs here ({done.stderr.decode().strip()})")
    yield mount
    subprocess.run(["umount", str(mount)], check=True)


def test_disk_full_on_a_real_tmpfs_then_space_returns(tiny_tmpfs):
    filler = tiny_tmpfs / "filler"
    filler.write_bytes(b"\0" * (1536 * 1024))
    w = SegmentWriter(tiny_tmpfs / "out", stem="dev", meta={}, scale=0.001, channels=("theta",))
    written, dropped = [], []
    i = 0
    while len(dropped) < 3:                        # fill to the brim
        t, c, theta = block(i)
        try:
            w.write(t, c, {"theta": theta})
            written.append(i)
        except StorageFull:
            dropped.append(i)
        i += 1
    assert written and scan(w.open_path).lost_bytes == 0
    assert w.samples_written == len(written) * 64 == scan(w.open_path).samples
    filler.unlink()                                # space returns
    w.gap(block(dropped[0])[0][0], 64 * len(dropped), "disk full")
    write_blocks(w, range(i, i + 4))
    w.close()
    rec = read_segments(tiny_tmpfs / "out", units="counts")
    keep = written + list(range(i, i + 4))
    np.testing.assert_array_equal(rec.acc, np.concatenate([block(k)[1] for k in keep]))
    assert [g["cause"] for g in rec.meta["gaps"]] == ["disk full"]
    assert rec.meta["gaps"][0]["index"] == len(written) * 64 and rec.meta["gaps"][0]["missing"] == 64 * len(dropped)


CHILD = textwrap.dedent("""
    import sys
    import numpy as np
    sys.path.insert(0, {tests!r})
    from test_segments import block
    from accelrig.segments import SegmentWriter
    w = SegmentWriter({out!r}, stem="dev", meta={{"device": "crash-test"}}, scale=0.001, channels=("theta",),
                      fsync_seconds=3600)
    i = 0
    while True:
        t, c, theta = block(i, n=4096)
        w.write(t, c, {{"theta": theta}})
        print(i, flush=True)
        i += 1
""")


def test_kill_9_then_recover_keeps_exactly_the_complete_blocks(tmp_path):
    out = tmp_path / "out"
    child = subprocess.Popen([sys.executable, "-c", CHILD.format(tests=str(Path(__file__).parent), out=str(out))],
                             stdout=subprocess.PIPE, text=True)
    try:
        last = -1
        deadline = time.monotonic() + 60
        while last < 40 and time.monotonic() < deadline:
            last = int(child.stdout.readline())
    finally:
        child.send_signal(signal.SIGKILL)
        child.wait()
    last = max(last, int((child.stdout.read().split() or [last])[-1]))
    assert last >= 40
    # the killed writer's lock file stays behind, but the kernel released its lock: the next writer gets it
    assert (out / ".lock").read_text().startswith(f"{child.pid}: ")
    SegmentWriter(out, stem="other", meta={}, scale=0.001)._dir_lock.release()
    reports = recover(out)
    assert len(reports) == 1
    report = reports[0]
    # every block whose write returned is there; the one in flight is there whole or not at all
    assert report.blocks in (last + 1, last + 2)
    assert report.samples == report.blocks * 4096
    assert report.finished.suffix == ".parquet" and not list(out.glob("*.seg"))
    rec = read_segments(out, units="counts")
    t, counts, theta = expected(range(report.blocks), n=4096)
    np.testing.assert_array_equal(rec.acc, counts)
    np.testing.assert_array_equal(rec.channels["theta"], theta)
    np.testing.assert_array_equal(rec.meta["time_origin_ns"] + np.round(rec.t * 1e9).astype(np.int64), to_ns(t))
    assert "closed after a crash" in str(report)


def test_recover_states_a_torn_last_block(tmp_path):
    w = SegmentWriter(tmp_path, stem="dev", meta={}, scale=0.001)
    write_blocks(w, range(6))
    path = w.open_path
    os.close(w._fd)                                 # the process "dies" here
    with open(path, "r+b") as fh:
        fh.truncate(path.stat().st_size - 100)      # the last block's write was torn
    [report] = recover(tmp_path)
    assert (report.blocks, report.samples, report.lost_samples) == (5, 320, 64)
    assert "an incomplete block of 64 samples" in str(report)
    rec = read_segments(tmp_path, units="counts")
    np.testing.assert_array_equal(rec.acc, expected(range(5))[1])
    assert rec.meta["gaps"] == [{"index": 320, "missing": 64, "cause": "crash (incomplete block)", "seconds": None,
                                 "segment": report.finished.name}]
    info = json.loads(pq.ParquetFile(report.finished).schema_arrow.metadata[b"accelrig"])
    assert info["recovered"]["lost_samples"] == 64


def test_a_new_writer_continues_the_numbering(tmp_path):
    for _ in range(2):
        with SegmentWriter(tmp_path, stem="dev", meta={}, scale=0.001) as w:
            write_blocks(w, range(2), t0=T0 + 100 * _)
    assert [p.name.split(".")[1] for p in sorted(tmp_path.glob("*.parquet"))] == ["000000", "000001"]


def test_time_range_over_a_directory(tmp_path):
    with SegmentWriter(tmp_path, stem="dev", meta={}, scale=0.001, segment_seconds=1.0) as w:
        write_blocks(w, range(100), jitter=False)
        w.gap(T0 + 6400 / RATE, 10, "disconnect", seconds=10 / RATE)
    t, counts, _ = expected(range(100), jitter=False)
    t_rel, acc, _, _, meta = read_arrays(tmp_path, start=T0 + 0.9, stop=T0 + 2.25, units="counts")
    keep = (to_ns(t) >= to_ns([T0 + 0.9])[0]) & (to_ns(t) < to_ns([T0 + 2.25])[0])
    np.testing.assert_array_equal(acc, counts[keep])
    assert len(meta["segments"]) == 3 and meta["gaps"] == []
    # relative seconds and ISO-8601 UTC times through the one loader
    rec = load_recording(tmp_path, start="0.9", stop="2.25", units="counts")
    np.testing.assert_array_equal(rec.acc, counts[keep])
    iso = time.strftime("%Y-%m-%dT%H:%M:%S", time.gmtime(int(T0) + 1)) + "Z"
    rec = load_recording(tmp_path, start=iso, units="counts")
    np.testing.assert_array_equal(rec.acc, counts[to_ns(t) >= int(T0 + 1) * 10**9])
    assert rec.meta["gaps"][0]["cause"] == "disconnect" and rec.meta["gaps"][0]["index"] == len(rec)
    with pytest.raises(DataError, match="no samples between"):
        read_arrays(tmp_path, start=T0 + 100)
    with pytest.raises(DataError, match="neither seconds nor an ISO-8601"):
        load_recording(tmp_path, start="yesterday")


def test_refusals_say_what_to_do(tmp_path):
    for stem in ("a", "b"):
        with SegmentWriter(tmp_path, stem=stem, meta={}, scale=0.001) as w:
            write_blocks(w, range(1))
    with pytest.raises(DataError, match=r"several devices \(a, b\)"):
        read_arrays(tmp_path)
    assert read_arrays(tmp_path, stem="a")[1].shape == (64, 3)
    (tmp_path / "empty").mkdir()
    with pytest.raises(DataError, match="no segments"):
        read_arrays(tmp_path / "empty")
    bogus = tmp_path / "x.parquet"
    bogus.write_bytes(b"not parquet")
    with pytest.raises(DataError, match="not a readable Parquet file"):
        read_arrays(bogus)
    with pytest.raises(DataError, match="letters, digits"):
        SegmentWriter(tmp_path, stem="../evil", meta={}, scale=1.0)
    with pytest.raises(DataError, match="do not increase"):
        with SegmentWriter(tmp_path / "c", stem="c", meta={}, scale=1.0) as w:
            t, c, _ = block(0)
            w.write(t, c)
            w.write(t, c)


def test_an_output_directory_that_cannot_be_made_is_refused(tmp_path):
    (tmp_path / "a-file").write_text("")
    with pytest.raises(StorageError, match="cannot create the output directory"):
        SegmentWriter(tmp_path / "a-file" / "out", stem="dev", meta={}, scale=1.0)


def test_csv_on_request_reads_back_through_the_interchange_reader(tmp_path):
    with SegmentWriter(tmp_path, stem="dev", meta={"chip": "sim"}, scale=0.001, channels=("theta",), csv=True) as w:
        write_blocks(w, range(3))
    [csv_path] = tmp_path.glob("*.csv")
    rec = load_recording(csv_path)
    t, counts, theta = expected(range(3))
    np.testing.assert_array_equal(rec.acc, counts)
    assert rec.units == "counts" and rec.meta["scale"] == 0.001
    np.testing.assert_allclose(rec.t, t, rtol=0, atol=1e-9)


def test_pyarrow_is_imported_only_to_finish_or_read_a_segment():
    probe = ("import sys\nimport accelrig.recording, accelrig.segments, accelrig.acquisition.session\n"
             "from accelrig.cli import main\ntry:\n    main(['record', '--help'])\nexcept SystemExit:\n    pass\n"
             "print('pyarrow' in sys.modules)")
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=120)
    assert done.stdout.strip().splitlines()[-1] == "False", done.stderr


def test_recover_removes_a_segment_torn_while_being_created_and_leaves_a_foreign_file(tmp_path):
    (tmp_path / "dev.000000.seg").write_bytes(segments.FILE_MAGIC[:5])          # killed inside the header write
    (tmp_path / "dev.000001.seg").write_bytes(b"something else entirely" * 500)
    reports = recover(tmp_path)
    assert [str(r) for r in reports] == [
        "dev.000000.seg: the writer stopped while creating it (no samples yet)",
        "dev.000001.seg: left alone: " + str(reports[1].problem).split(": ", 1)[1]]
    assert "not an accelrig open segment" in str(reports[1])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dev.000001.seg"]


def _parquet_contents(path: Path):
    """What a finished segment holds: its columns and the accelrig metadata (file names aside)."""
    table = pq.read_table(path)
    return {name: table.column(name).to_pylist() for name in table.column_names}, \
        json.loads(table.schema.metadata[b"accelrig"])


def test_a_shared_finisher_converts_rotations_one_at_a_time_off_the_writing_thread(tmp_path, monkeypatch):
    """Three writers rotating together: every rotation is converted by the finisher's thread, never two
    at once, and the files are the same as a writer converting in its own thread makes."""
    import threading

    real = segments.finish_segment
    seen = {"threads": [], "running": 0, "most": 0}
    lock = threading.Lock()

    def watched(path, **kw):
        with lock:
            seen["running"] += 1
            seen["most"] = max(seen["most"], seen["running"])
            seen["threads"].append(threading.current_thread().name)
        try:
            time.sleep(0.02)   # long enough for an overlap to show if conversions ran side by side
            return real(path, **kw)
        finally:
            with lock:
                seen["running"] -= 1

    monkeypatch.setattr(segments, "finish_segment", watched)
    finisher = segments.Finisher()
    writers = [SegmentWriter(tmp_path / f"d{k}", stem=f"d{k}", meta={"k": k}, scale=0.001, channels=("theta",),
                             segment_seconds=0.25, finisher=finisher) for k in range(3)]
    for i in range(40):                  # 1.25 s: each writer rotates 4 times
        for w in writers:
            write_blocks(w, range(i, i + 1), jitter=False)
    deadline = time.monotonic() + 20
    while any(w.pending for w in writers) and time.monotonic() < deadline:
        time.sleep(0.01)
    assert seen["most"] == 1 and seen["threads"] == ["accelrig segment finisher"] * 12
    for w in writers:                    # close finishes the open segment in the caller's thread
        w.close()
    assert finisher.close(5.0)
    assert len(seen["threads"]) == 15 and all(w.segments_finished == 5 and not w.pending for w in writers)
    monkeypatch.setattr(segments, "finish_segment", real)
    with SegmentWriter(tmp_path / "own", stem="d0", meta={"k": 0}, scale=0.001, channels=("theta",),
                       segment_seconds=0.25) as own:
        write_blocks(own, range(40), jitter=False)
    ours, theirs = sorted((tmp_path / "own").glob("*.parquet")), sorted((tmp_path / "d0").glob("*.parquet"))
    assert [p.name for p in ours] == [p.name for p in theirs]
    assert [_parquet_contents(p) for p in ours] == [_parquet_contents(p) for p in theirs]


def test_a_rotation_the_finisher_cannot_finish_stays_pending_until_close(tmp_path, monkeypatch):
    real = pq.ParquetWriter.write_table

    def full(self, table, *a, **k):
        raise OSError(errno.ENOSPC, "No space left on device")

    lines = []
    finisher = segments.Finisher(lines.append)
    w = SegmentWriter(tmp_path, stem="dev", meta={}, scale=0.001, segment_seconds=1.0, finisher=finisher)
    monkeypatch.setattr(pq.ParquetWriter, "write_table", full)
    write_blocks(w, range(50), jitter=False)       # rotates at 1 s: the finisher meets a full disk
    deadline = time.monotonic() + 10
    while not lines and time.monotonic() < deadline:
        time.sleep(0.01)
    assert "dev: a rotated segment is not finished yet" in lines[0] and "disk is full" in lines[0]
    assert len(w.pending) == 1 and w.samples_written == 50 * 64
    np.testing.assert_array_equal(read_arrays(tmp_path, units="counts")[1], expected(range(50), jitter=False)[1])
    monkeypatch.setattr(pq.ParquetWriter, "write_table", real)
    assert len(w.close()) == 2 and not w.pending
    assert finisher.close(5.0)
    assert sorted(p.suffix for p in tmp_path.iterdir()) == [".parquet", ".parquet"]
    np.testing.assert_array_equal(read_arrays(tmp_path, units="counts")[1], expected(range(50), jitter=False)[1])


def test_segments_of_earlier_daemons_name_their_device_as_recordings_do(tmp_path):
    """Earlier daemons (and collectors keeping what they announced) wrote the device as a dict under
    "device": read back, it names the device at the top level, where profile checks look."""
    old = {"device": {"driver": "i2c-sim", "url": "i2c-sim://mpu9250?seed=3", "chip": "mpu9250",
                      "identity": "i2c-sim-mpu9250-seed3", "range_g": 2.0, "scale": 0.000598, "who_am_i": 0x71,
                      "requested_rate": 200.0, "nominal_rate": 200.0, "channels": [],
                      "extra": {"hardware_bias_removed": [0.1, -0.2, 0.3], "firmware": None, "part": "MPU-9250"}},
           "name": "chip", "time_base": "utc"}
    with SegmentWriter(tmp_path, stem="chip", meta=old, scale=0.000598) as w:
        write_blocks(w, range(2))
    meta = load_recording(tmp_path).meta
    assert meta["identity"] == "i2c-sim-mpu9250-seed3" and meta["chip"] == "mpu9250" and meta["who_am_i"] == 0x71
    assert meta["hardware_bias_removed"] == [0.1, -0.2, 0.3] and meta["device"] == "i2c-sim://mpu9250?seed=3"
    assert meta["device_facts"]["part"] == "MPU-9250" and "hardware_bias_removed" not in meta["device_facts"]
    from accelrig.recording import check_meta

    check_meta(meta, "read back")   # the recording's own metadata types hold


def test_a_read_over_raw_and_calibrated_segments_says_which_samples_are_which(tmp_path):
    """A daemon recorded raw counts until its profile came, then calibrated channels, then (a reload) with
    another profile: the metadata of the read describe every stretch, not the first segment's alone."""
    cal = ("cal_x", "cal_y", "cal_z")
    first = {"path": "/p/a.yaml", "identity": "x", "created": "2026-11-01T00:00:00Z", "procedure": "static",
             "method": "map"}
    second = dict(first, path="/p/b.yaml", created="2026-11-20T00:00:00Z")
    described = {"cal_x, cal_y, cal_z": "calibrated acceleration, m/s^2"}
    for blocks, meta, channels in (
            (range(2), {"identity": "x", "profile": None, "recording_raw": "no profile for 'x' in the store"}, ()),
            (range(2, 4), {"identity": "x", "profile": first, "calibrated_channels": described}, cal),
            (range(4, 5), {"identity": "x", "profile": first, "calibrated_channels": described}, cal),
            (range(5, 6), {"identity": "x", "profile": second, "calibrated_channels": described}, cal)):
        with SegmentWriter(tmp_path, stem="dev", meta=meta, scale=0.001, channels=channels) as w:
            for i in blocks:
                n, t0 = 64, T0 + 64 * i / RATE
                w.write(t0 + np.arange(n) / RATE, np.full((n, 3), i, dtype=np.int16),
                        {name: np.full(n, 0.5) for name in channels} if channels else None)
    _, _, _, channels, meta = read_arrays(tmp_path, units="counts")
    spans = meta["spans"]
    assert [(s["first"], s["stop"], s["calibrated"], s["profile"]) for s in spans] == [
        (0, 128, False, None), (128, 320, True, first), (320, 384, True, second)]
    assert spans[0]["recording_raw"] == "no profile for 'x' in the store" and spans[1]["segments"][0] != \
        spans[1]["segments"][1]   # two segments, one stretch
    assert "profile" not in meta   # no one profile describes the read
    assert meta["recording_raw"].startswith("samples 0-127 of 384 (dev.000000.") and "no profile for 'x'" in \
        meta["recording_raw"]
    assert np.isnan(channels["cal_x"][:128]).all() and not np.isnan(channels["cal_x"][128:]).any()
    t = T0 + np.arange(384) / RATE
    one = read_arrays(tmp_path, start=float(t[130]), stop=float(t[300]))[4]   # one state: the segment's own
    assert "spans" not in one and one["profile"] == first and "recording_raw" not in one


def test_a_directory_whose_channels_or_flashed_offsets_change_reads_as_one_or_by_stretch(tmp_path):
    """A daemon that recorded raw counts until its profile came, then calibrated (and flashed): a channel
    the raw stretch lacks is NaN there; a change of flashed offsets is refused over both stretches, since
    one recording takes one, and each stretch reads by --start/--stop."""
    with SegmentWriter(tmp_path, stem="dev", meta={"identity": "x"}, scale=0.001) as w:
        write_blocks(w, range(2), jitter=False)
    with SegmentWriter(tmp_path, stem="dev", meta={"identity": "x"}, scale=0.001, channels=("theta",)) as w:
        write_blocks(w, range(2, 4), jitter=False)
    _, counts, theta = expected(range(4), jitter=False)
    _, acc, _, channels, _ = read_arrays(tmp_path, units="counts")
    np.testing.assert_array_equal(acc, counts)
    assert np.isnan(channels["theta"][:128]).all()
    np.testing.assert_array_equal(channels["theta"][128:], theta[128:])
    flashed = {"identity": "x", "hardware_bias_removed": [0.25, -0.0575, 0.0287]}
    with SegmentWriter(tmp_path, stem="dev", meta=flashed, scale=0.001, channels=("theta",)) as w:
        write_blocks(w, range(4, 6), jitter=False)
    with pytest.raises(DataError, match=r"the chip's flashed offsets change between the segments read \(no offsets "
                                        r"flashed from dev\.000000\.\S+ \(\S+\); offsets \[0\.25, -0\.0575, 0\.0287\] "
                                        r"m/s\^2 flashed from dev\.000002\.\S+ \(\S+\)\)") as err:
        read_arrays(tmp_path)
    assert "--stop " in err.value.hint and "--start " in err.value.hint
    t, _, _ = expected(range(6), jitter=False)
    _, acc, _, _, meta = read_arrays(tmp_path, start=float(t[256]), units="counts")   # the flashed stretch alone
    assert len(acc) == 128 and meta["hardware_bias_removed"] == flashed["hardware_bias_removed"]
    assert len(read_arrays(tmp_path, stop=float(t[256]))[1]) == 256


def test_a_second_writer_into_a_directory_is_refused_naming_the_first_and_the_lock_goes_with_close(tmp_path, cli):
    """Two writers in one directory interleave segments overlapping in time that no reader can use."""
    first = SegmentWriter(tmp_path, stem="dev", meta={}, scale=0.001)
    write_blocks(first, range(2))
    with pytest.raises(StorageError, match=rf"another process is recording into it \(pid {os.getpid()}: "):
        SegmentWriter(tmp_path, stem="dev", meta={}, scale=0.001)
    r = cli("record", "sim://still?seed=1", "-o", tmp_path, "--seconds", "0.2")   # `record` alike
    assert r.returncode == StorageError.exit_code and f"{tmp_path}: another process is recording into it" in r.stderr
    first.close()
    assert not (tmp_path / ".lock").exists()
    with SegmentWriter(tmp_path, stem="dev", meta={}, scale=0.001) as again:
        write_blocks(again, range(2), t0=T0 + 100)
    assert read_segments(tmp_path).meta["segments"][0].startswith("dev.000000")


def test_segments_overlapping_in_time_are_said_to_be_two_recordings(tmp_path):
    """What an unlocked second writer left (as the daemon and record did before the lock): the reader names
    the two segments instead of a time-base or gap error."""
    with SegmentWriter(tmp_path, stem="dev", meta={}, scale=0.001) as w:
        write_blocks(w, range(100))                     # 3.1 s
    with SegmentWriter(tmp_path, stem="dev", meta={}, scale=0.001) as w:
        write_blocks(w, range(10), t0=T0 + 1.0)         # begins 1 s into the first
    with pytest.raises(DataError, match=r"two recordings overlap in time in this directory: segments "
                                        r"dev\.000000\.\S+ \(.* to .*\) and dev\.000001\."):
        read_segments(tmp_path)
    assert len(read_segments(tmp_path, stop=T0 + 0.5)) == int(0.5 * RATE) + 1   # the stretch before: one recording


def test_a_change_of_flashed_offsets_in_utc_segments_names_the_time_that_splits_the_stretches(tmp_path):
    """The refusal gives the UTC time of the change, and that one time read as --stop and as --start gives
    exactly the stretch before and the stretch after (a field engineer had to read it out of a file name)."""
    from accelrig.segments import resolve_range

    raw = {"identity": "x", "time_base": "utc"}
    with SegmentWriter(tmp_path, stem="dev", meta=raw, scale=0.001) as w:
        write_blocks(w, range(3), jitter=False)
    with SegmentWriter(tmp_path, stem="dev", meta={**raw, "hardware_bias_removed": [0.25, -0.05, 0.03]},
                       scale=0.001) as w:
        write_blocks(w, range(3, 5), jitter=False)
    with pytest.raises(DataError) as err:
        read_arrays(tmp_path)
    when = re.search(r"--stop (\S+) ends the one before the change, --start \1 begins", err.value.hint).group(1)
    assert when.endswith("Z") and "(2025-11-24T" in err.value.message
    before = read_arrays(tmp_path, *resolve_range(tmp_path, None, when), units="counts")[1]
    after = read_arrays(tmp_path, *resolve_range(tmp_path, when, None), units="counts")[1]
    assert (len(before), len(after)) == (192, 128)


def test_a_writer_that_fails_to_start_leaves_the_directory_unlocked(tmp_path, monkeypatch):
    # reviewer: an error after the lock was taken kept it, so a daemon's reconnect would refuse itself
    def unreadable(*args):
        raise StorageError(f"{tmp_path}: cannot list the directory")

    with monkeypatch.context() as m:
        m.setattr(segments, "_next_index", unreadable)
        with pytest.raises(StorageError, match="cannot list"):
            SegmentWriter(tmp_path, stem="dev", meta={}, scale=0.001)
    SegmentWriter(tmp_path, stem="dev", meta={}, scale=0.001).close()   # not "another process is recording"
