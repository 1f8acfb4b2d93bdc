"""Storage and pacing benchmarks (issue 13): prints tables.

    python tests/benchmarks/bench_storage.py [sim] [record] [read]  [--hours H] [--devices N] [--seconds S]

sim     CPU per simulated device in realtime pace (sessions pumping, as the TUI and the daemon run them)
record  `accelrig record` of H hours (default 1) at 2048 Hz from a fast-paced simulator through the real
        writer path (the CLI in a subprocess): peak RSS sampled every 0.5 s, bytes per sample on disk
read    reading those H hours back (load_recording of the directory, and of a time range) against
        numpy.load of the same samples in an .npz: wall time and peak RSS, each in a fresh process
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

RATE = 2048


def sim_cpu(devices: int, seconds: float, rate: int = RATE) -> dict:
    """CPU (user + system) of this process per realtime simulated device, % of one core."""
    from accelrig.acquisition.session import Session

    sessions = [Session.open_and_start(f"sim://still?seed={k}&rate={rate}") for k in range(devices)]
    readers = [s.reader() for s in sessions]
    time.sleep(1.0)   # settle
    for r in readers:
        r.read()
    before = resource.getrusage(resource.RUSAGE_SELF)
    start = time.monotonic()
    delivered = 0
    while time.monotonic() - start < seconds:
        time.sleep(0.25)
        delivered += sum(r.read().n for r in readers)
    after = resource.getrusage(resource.RUSAGE_SELF)
    wall = time.monotonic() - start
    for s in sessions:
        s.stop()
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return {"devices": devices, "rate": rate, "wall_s": wall, "cpu_pct_per_device": 100 * cpu / wall / devices,
            "delivered_hz_per_device": delivered / wall / devices}


def rss_of(pid: int) -> tuple[int, int]:
    """Resident set of a process tree (the process and its children) and its anonymous part
    (RssAnon: without the shared libraries' code pages), bytes."""
    total = anon = 0
    for p in [pid, *_children(pid)]:
        try:
            with open(f"/proc/{p}/status") as fh:
                fields = {line.split(":")[0]: line.split()[1:] for line in fh}
        except OSError:
            continue
        total += int(fields["VmRSS"][0]) * 1024
        anon += int(fields["RssAnon"][0]) * 1024
    return total, anon


def _children(pid: int) -> list[int]:
    try:
        with open(f"/proc/{pid}/task/{pid}/children") as fh:
            kids = [int(k) for k in fh.read().split()]
    except OSError:
        return []
    return kids + [g for k in kids for g in _children(k)]


def run_sampled(cmd: list[str], interval: float = 0.5) -> dict:
    """Run a command, sampling its RSS every ``interval`` s; returns wall time, peaks and the samples."""
    start = time.monotonic()
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    samples = []
    while proc.poll() is None:
        samples.append((time.monotonic() - start, rss_of(proc.pid)))
        time.sleep(interval)
    out, err = proc.communicate()
    if proc.returncode:
        raise SystemExit(f"{cmd} failed: {err}")
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return {"wall_s": time.monotonic() - start, "peak_rss": max((s[1][0] for s in samples), default=0),
            "peak_anon": max((s[1][1] for s in samples), default=0),
            "samples": samples, "stdout": out, "maxrss_children": usage.ru_maxrss * 1024}


def record_bench(hours: float, work: Path) -> dict:
    out = work / "hour"
    seconds = hours * 3600
    cmd = [sys.executable, "-m", "accelrig", "record", f"sim://still?seed=1&pace=fast&rate={RATE}&block=2048",
           "--seconds", str(seconds), "-o", str(out)]
    r = run_sampled(cmd)
    files = sorted(out.glob("*.parquet"))
    size = sum(f.stat().st_size for f in files)
    import pyarrow.parquet as pq
    n = sum(pq.ParquetFile(f).metadata.num_rows for f in files)
    rss = [s[1][0] for s in r["samples"]]
    # flat: the second half's peak against the first half's (after start-up)
    half = len(rss) // 2
    return {"hours": hours, "samples": n, "wall_s": r["wall_s"], "peak_rss_mb": r["peak_rss"] / 2**20,
            "peak_anon_mb": r["peak_anon"] / 2**20,
            "rss_first_half_mb": max(rss[1:half] or [0]) / 2**20, "rss_second_half_mb": max(rss[half:]) / 2**20,
            "files": len(files), "bytes": size, "bytes_per_sample": size / n, "out": str(out),
            "over_time": [(t, m[0] / 2**20) for t, m in r["samples"]]}


READ_PROBE = textwrap.dedent("""
    import json, sys, time
    start = time.perf_counter()
    kind, path = sys.argv[1], sys.argv[2]
    if kind == "npz":
        import numpy as np
        with np.load(path) as z:
            t, acc = z["t"], z["acc"]
        n = t.size
    elif kind == "segments":
        from accelrig.recording import load_recording
        n = len(load_recording(path))
    elif kind == "range":
        from accelrig.recording import load_recording
        n = len(load_recording(path, start=1800, stop=1860))
    else:
        import pandas
        n = len(pandas.read_parquet(path))
    wall = time.perf_counter() - start
    # VmHWM, not ru_maxrss: a child's ru_maxrss starts at its parent's at fork
    hwm = next(int(line.split()[1]) * 1024 for line in open("/proc/self/status") if line.startswith("VmHWM"))
    print(json.dumps({"n": n, "wall_s": wall, "maxrss": hwm}))
""")


def read_bench(directory: Path, work: Path) -> list[dict]:
    from accelrig.recording import load_recording, save_recording

    npz = work / "hour.npz"
    rec = load_recording(directory)
    save_recording(rec, npz)   # the same samples in the native format (float64 t and m/s^2)
    del rec
    rows = []
    first = sorted(directory.glob("*.parquet"))[0]
    for kind, path, what in (("npz", npz, "numpy.load of the .npz (t, acc float64)"),
                             ("segments", directory, "load_recording(directory) -> Recording (float64)"),
                             ("range", directory, "load_recording(directory, start=1800, stop=1860)"),
                             ("pandas", first, "pandas.read_parquet(one segment), no accelrig")):
        if kind == "pandas":
            try:
                import pandas  # noqa: F401
            except ImportError:
                continue
        done = subprocess.run([sys.executable, "-c", READ_PROBE, kind, str(path)], capture_output=True, text=True,
                              check=True)
        r = json.loads(done.stdout)
        size = npz.stat().st_size if kind == "npz" else sum(f.stat().st_size for f in directory.glob("*.parquet"))
        if kind == "pandas":
            size = first.stat().st_size
        rows.append({"what": what, "samples": r["n"], "wall_s": r["wall_s"], "peak_rss_mb": r["maxrss"] / 2**20,
                     "file_mb": size / 2**20})
    return rows


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("parts", nargs="*", default=["sim", "record", "read"])
    ap.add_argument("--hours", type=float, default=1.0)
    ap.add_argument("--devices", type=int, default=4)
    ap.add_argument("--seconds", type=float, default=10.0)
    args = ap.parse_args()
    if "sim" in args.parts:
        print("## Simulated driver, realtime pace: CPU per device\n")
        print("| devices | rate Hz | delivered Hz/device | CPU % of one core per device |")
        print("|---|---|---|---|")
        for rate in (200, RATE):
            r = sim_cpu(args.devices, args.seconds, rate)
            print(f"| {r['devices']} | {rate} | {r['delivered_hz_per_device']:.0f} | {r['cpu_pct_per_device']:.2f} |")
        print()
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        rec = None
        if "record" in args.parts or "read" in args.parts:
            rec = record_bench(args.hours, work)
        if "record" in args.parts:
            print(f"## accelrig record, {args.hours:g} h at {RATE} Hz (fast-paced sim, real writer path)\n")
            print("| samples | wall s | peak RSS MB | of which anonymous MB | RSS peak 1st half / 2nd half MB "
                  "| segments | bytes on disk | bytes/sample |")
            print("|---|---|---|---|---|---|---|---|")
            print(f"| {rec['samples']} | {rec['wall_s']:.1f} | {rec['peak_rss_mb']:.1f} | {rec['peak_anon_mb']:.1f} | "
                  f"{rec['rss_first_half_mb']:.1f} / {rec['rss_second_half_mb']:.1f} | {rec['files']} | "
                  f"{rec['bytes']} | {rec['bytes_per_sample']:.2f} |\n")
            series = rec["over_time"]
            step = max(len(series) // 12, 1)
            print("RSS over the run (wall s: MB): " + ", ".join(f"{t:.0f}: {mb:.0f}" for t, mb in series[::step])
                  + "\n")
        if "read" in args.parts:
            print(f"## Reading {args.hours:g} h back (fresh process each)\n")
            print("| reader | samples | wall s | peak RSS MB | file MB |")
            print("|---|---|---|---|---|")
            for r in read_bench(Path(rec["out"]), work):
                print(f"| {r['what']} | {r['samples']} | {r['wall_s']:.2f} | {r['peak_rss_mb']:.0f} | "
                      f"{r['file_mb']:.1f} |")
            print()


if __name__ == "__main__":
    main()
