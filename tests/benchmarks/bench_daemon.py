"""Daemon soak: 8 simulated devices at 2048 Hz in one daemon, CPU per device, RSS over time, loss.

    python tests/benchmarks/bench_daemon.py [--seconds 600] [--kind-seconds 30] [--kinds i2c-sim]

Part 1, CPU per device by driver: for each of sim, serial-sim, i2c-sim, a daemon with 8
devices of that kind runs ``--kind-seconds``; CPU (user + system, from /proc) of the daemon
process over the run, divided by 8, in % of one core, and the samples lost (FIFO overflow,
lost frames, all in gap records) in % of all: a starved daemon polls less, so its CPU
reads low while its loss grows.  The simulators (firmware on a pty,
register-level chips) run inside the daemon's process, so their cost is counted too.

Part 2, soak: one daemon with 8 devices (3 sim, 3 serial-sim, 2 i2c-sim) for ``--seconds``,
segments rotated every 60 s; RSS sampled every 10 s; at the end, per device, delivered =
written + dropped and the gap records, from the journal and the segment files.

The machine may be shared: CPU figures read high when other work runs (load average shown).
A FIFO overflows when the host wakes a reader late, whatever the daemon does: beside each run a
lone probe process sleeps at the I2C poll interval (7.1 ms) and reports how late it woke
(p99.9 and max, ms); an MPU-9250 at 4 kHz overflows when a poll is about 14 ms late.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import yaml

URLS = {
    "sim": "sim://still?seed={i}&rate=2048",
    "serial-sim": "serial-sim://still?seed={i}&rate=2048",
    "i2c-sim": "i2c-sim://mpu9250?rig=still&rate=2048&seed={i}",
}
TARGETS = {"sim": 3.0, "serial-sim": 3.0, "i2c-sim": 6.0}   # CPU per device, % of one core (issue #13)
TICKS = os.sysconf("SC_CLK_TCK")
# The wake-up probe: one process, one thread, no work; how late its sleeps end (ms, sorted).
PROBE = """
import sys, time
interval, end = 0.0071, time.monotonic() + float(sys.argv[1])
late, due = [], time.monotonic() + interval
while due < end:
    time.sleep(max(due - time.monotonic(), 0))
    now = time.monotonic()
    late.append(1e3 * (now - due))
    due = max(due + interval, now)
late.sort()
print(late[int(0.999 * (len(late) - 1))], late[-1])
"""


def cpu_seconds(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / TICKS   # utime, stime


def rss_mb(pid: int) -> float:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    return float("nan")


def run_daemon(devices: list[dict], seconds: float, work: Path, segment_seconds: float = 60.0,
               sample_every: float = 10.0):
    out = work / "out"
    config = {"output": str(out), "status_interval": 60, "segment_seconds": segment_seconds, "devices": devices}
    path = work / "daemon.yaml"
    path.write_text(yaml.safe_dump(config))
    log = open(work / "daemon.log", "wb")
    proc = subprocess.Popen([sys.executable, "-m", "accelrig", "daemon", "--config", str(path)],
                            stdout=log, stderr=log)
    try:
        deadline = time.monotonic() + 60
        while not (out / "daemon.sock").exists():   # started; devices opening
            if time.monotonic() > deadline or proc.poll() is not None:
                raise SystemExit(f"the daemon did not start: {(work / 'daemon.log').read_text()}")
            time.sleep(0.2)
        time.sleep(3.0)   # every device open and streaming
        probe = subprocess.Popen([sys.executable, "-c", PROBE, str(seconds)], stdout=subprocess.PIPE, text=True)
        c0, t0 = cpu_seconds(proc.pid), time.monotonic()
        rss = [(0.0, rss_mb(proc.pid))]
        while time.monotonic() - t0 < seconds:
            time.sleep(min(sample_every, seconds - (time.monotonic() - t0)) if seconds > 0 else 0)
            rss.append((time.monotonic() - t0, rss_mb(proc.pid)))
        cpu = (cpu_seconds(proc.pid) - c0) / (time.monotonic() - t0)
        late = tuple(float(x) for x in probe.communicate(timeout=30)[0].split())
        proc.send_signal(signal.SIGTERM)
        rc = proc.wait(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
    keep = os.environ.get("BENCH_DAEMON_KEEP")
    if keep:
        subprocess.run(["cp", "-r", str(work), keep])
    return cpu, rss, rc, out, late


def lost_percent(out: Path) -> tuple[float, list[float]]:
    """Samples the devices reported missing (FIFO overflow, lost frames: in gap records), in % of all,
    and per device (in name order)."""
    delivered = missing = 0
    each = []
    for journal in sorted(out.glob("*/journal.jsonl")):
        events = [json.loads(x) for x in journal.read_text().splitlines()]
        stop = [e for e in events if e["event"] == "stop"][-1]["counts"]
        delivered, missing = delivered + stop["delivered"], missing + stop["missing"]
        each.append(100.0 * stop["missing"] / max(stop["delivered"] + stop["missing"], 1))
    return 100.0 * missing / max(delivered + missing, 1), each


def loss_table(out: Path) -> list[str]:
    from accelrig.recording import read_segments
    from accelrig.segments import segment_files

    rows = [f"{'device':10} {'delivered':>10} {'written':>10} {'dropped':>8} {'missing':>8} {'gaps':>5} "
            f"{'files':>5} {'in files':>10} {'unexplained':>11}"]
    for directory in sorted(p for p in out.iterdir() if p.is_dir()):
        events = [json.loads(x) for x in (directory / "journal.jsonl").read_text().splitlines()]
        stop = [e for e in events if e["event"] == "stop"][-1]["counts"]
        rec = read_segments(directory, units="counts")
        dropped_gaps = sum(g["missing"] for g in rec.meta["gaps"] if g["cause"] in ("disk full", "write failed"))
        unexplained = stop["delivered"] - len(rec.t) - dropped_gaps
        rows.append(f"{directory.name:10} {stop['delivered']:>10} {stop['written']:>10} {stop['dropped']:>8} "
                    f"{stop['missing']:>8} {stop['gaps']:>5} {len(segment_files(directory)):>5} {len(rec.t):>10} "
                    f"{unexplained:>11}")
    return rows


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=600.0, help="soak length (default 600; 0: no soak)")
    parser.add_argument("--kind-seconds", type=float, default=30.0, help="CPU run per driver kind (default 30)")
    parser.add_argument("--kinds", nargs="+", choices=list(TARGETS), default=list(TARGETS),
                        help="driver kinds of part 1 (default all)")
    args = parser.parse_args()
    print(f"load average before: {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores")
    print("\nCPU per device, 8 devices at 2048 Hz in one daemon")
    print(f"{'driver':12} {'CPU/device %':>12} {'target %':>9} {'daemon RSS MB':>14} {'lost %':>7} "
          f"{'wake late ms':>13}")
    per_device = []
    for kind in args.kinds:
        target = TARGETS[kind]
        with tempfile.TemporaryDirectory() as tmp:
            devices = [{"name": f"{kind.replace('-', '')}{i}", "url": URLS[kind].format(i=i)} for i in range(8)]
            cpu, rss, rc, out, late = run_daemon(devices, args.kind_seconds, Path(tmp))
            lost, each = lost_percent(out)
            print(f"{kind:12} {100 * cpu / 8:>12.2f} {target:>9.1f} {rss[-1][1]:>14.1f} {lost:>7.2f} "
                  f"{late[0]:>6.1f}/{late[1]:<6.1f}   (exit {rc})")
            per_device.append(f"{kind:12} " + " ".join(f"{x:.2f}" for x in each))
    print("(wake late: a lone process's sleeps, p99.9/max, during the run)")
    print("lost % per device:\n" + "\n".join(per_device))
    if args.seconds <= 0:
        print(f"\n(no soak: --seconds {args.seconds:g})\nload average after: {os.getloadavg()[0]:.2f}")
        return 0
    kinds = ["sim"] * 3 + ["serial-sim"] * 3 + ["i2c-sim"] * 2
    devices = [{"name": f"{k.replace('-', '')}{i}", "url": URLS[k].format(i=i)} for i, k in enumerate(kinds)]
    with tempfile.TemporaryDirectory() as tmp:
        cpu, rss, rc, out, late = run_daemon(devices, args.seconds, Path(tmp))
        print(f"\nSoak: 8 devices (3 sim, 3 serial-sim, 2 i2c-sim) at 2048 Hz for {args.seconds:g} s, "
              f"segments every 60 s; daemon exit {rc}; a lone process woke up to {late[1]:.1f} ms late "
              f"(p99.9 {late[0]:.1f})")
        print(f"CPU: {100 * cpu:.1f} % of one core in all, {100 * cpu / 8:.2f} % per device")
        print("RSS over time (MB): " + ", ".join(f"{t:.0f}s {m:.1f}" for t, m in rss))
        steady = [m for t, m in rss if t >= min(60.0, args.seconds / 2)]
        if steady:
            print(f"RSS after warm-up: min {min(steady):.1f}, max {max(steady):.1f} MB, "
                  f"spread {100 * (max(steady) - min(steady)) / min(steady):.1f} %")
        print()
        print("\n".join(loss_table(out)))
    print(f"\nload average after: {os.getloadavg()[0]:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
