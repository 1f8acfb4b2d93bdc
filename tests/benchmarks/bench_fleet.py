"""Fleet load: N simulated devices at 2048 Hz -> one Mosquitto -> one collector, on loopback.

    python tests/benchmarks/bench_fleet.py [--devices 10 25] [--per-daemon 5] [--seconds 20]

For each N: ceil(N / per-daemon) daemon processes, each publishing its devices (sim, realtime
pace, 2048 Hz) to one Mosquitto started here (``mosquitto -c`` on a free loopback port); one
collector runs in this process (``accelrig.daemon.collector.Collector``, writing segment files).
Measured over ``--seconds`` after a warm-up:

* messages/s and samples/s taken by the collector;
* end-to-end latency: the collector's clock when a block is taken minus the UTC time of the
  block's last sample (the daemon stamps samples on the host clock): sampling -> device FIFO
  -> daemon (0.2 s batches) -> spool -> broker -> collector;
* CPU of the collector (this process) per device, % of one core, and of each part;
* loss: at the end, per device, the samples in the daemon's local segment files against the
  samples the collector stored; "not received" gap records counted.

The machine may be shared: CPU figures read high when other work runs (load average shown).
"""

from __future__ import annotations

import argparse
import math
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np
import yaml

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))   # tests/: the tests' own mqtt_support
from mqtt_support import free_port  # noqa: E402  (the project's one: below the ephemeral range)

TICKS = os.sysconf("SC_CLK_TCK")


def cpu_seconds(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / TICKS


def run(n: int, per_daemon: int, seconds: float, work: Path) -> dict:
    from accelrig.daemon.collector import Collector

    port = free_port()
    conf = work / "mosquitto.conf"
    conf.write_text(f"listener {port} 127.0.0.1\nallow_anonymous true\nmax_queued_messages 1000000\n"
                    f"max_inflight_messages 100\n")
    broker = subprocess.Popen(["mosquitto", "-c", str(conf)], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    time.sleep(0.5)
    latencies: list[float] = []
    taken = {"messages": 0, "samples": 0}
    measuring = threading.Event()

    class Timed(Collector):
        def _take(self, stream, m):
            super()._take(stream, m)
            if measuring.is_set() and m.t_ns is not None:
                latencies.append(time.time() - int(m.t_ns[-1]) / 1e9)
                taken["messages"] += 1
                taken["samples"] += m.samples

    collector = Timed(f"mqtt://127.0.0.1:{port}", work / "fleet", client_id=f"bench-{n}", log=lambda line: None)
    collector.connect()
    stop = threading.Event()
    saver = threading.Thread(target=collector.run, args=(stop,), daemon=True)
    saver.start()
    daemons = []
    for d in range(math.ceil(n / per_daemon)):
        devices = [{"url": f"sim://still?seed={i}&rate=2048&pace=realtime", "name": f"dev{i:03d}"}
                   for i in range(d * per_daemon, min(n, (d + 1) * per_daemon))]
        config = {"output": str(work / f"out{d}"), "status_interval": 0, "devices": devices,
                  "mqtt": {"broker": f"mqtt://127.0.0.1:{port}", "site": "bench", "status_seconds": 5}}
        path = work / f"daemon{d}.yaml"
        path.write_text(yaml.safe_dump(config))
        log = open(work / f"daemon{d}.log", "wb")
        daemons.append(subprocess.Popen([sys.executable, "-m", "accelrig", "daemon", "--config", str(path)],
                                        stdout=log, stderr=log))
    # warm-up: every device connected and its blocks arriving (daemon start-up takes longer with more of them
    # on a loaded machine), then 3 s more so the start-up backlog is through
    deadline = time.monotonic() + 90
    while len(collector.streams) < n and time.monotonic() < deadline:
        time.sleep(0.5)
    started = len(collector.streams)
    time.sleep(3.0)
    measuring.set()
    cpu0, broker0, wall0 = time.process_time(), cpu_seconds(broker.pid), time.monotonic()
    daemon0 = sum(cpu_seconds(p.pid) for p in daemons)
    time.sleep(seconds)
    wall = time.monotonic() - wall0
    cpu = time.process_time() - cpu0
    broker_cpu = cpu_seconds(broker.pid) - broker0
    daemon_cpu = sum(cpu_seconds(p.pid) for p in daemons) - daemon0
    measuring.clear()
    for p in daemons:
        p.send_signal(signal.SIGTERM)
    for p in daemons:
        p.wait(30)
    time.sleep(2.0)    # the last blocks through the broker
    stop.set()
    collector.close()
    broker.send_signal(signal.SIGTERM)
    broker.wait(10)
    # loss, per device: the samples in the daemon's local files = stored by the collector + in its
    # "not received" gap records (the collector's count of those samples)
    from accelrig.segments import read_arrays

    delivered = stored = not_received = 0
    unexplained = []
    for d in range(len(daemons)):
        for directory in sorted(p for p in (work / f"out{d}").iterdir() if p.is_dir()):
            local = read_arrays(directory, units="counts")[0].size
            stream = collector.streams.get(("bench", directory.name))
            got = stream.counts["samples"] if stream else 0
            gaps = stream.counts["not_received"] if stream else 0
            delivered += local
            stored += got
            not_received += gaps
            if got < local and not gaps:
                unexplained.append((directory.name, local - got))
    lat = np.array(latencies) * 1e3
    return {"n": n, "daemons": len(daemons), "streaming at start": started, "seconds": wall, "messages/s": taken["messages"] / wall,
            "samples/s": taken["samples"] / wall, "p50 ms": float(np.percentile(lat, 50)) if lat.size else math.nan,
            "p99 ms": float(np.percentile(lat, 99)) if lat.size else math.nan,
            "collector %/dev": 100 * cpu / wall / n, "broker %": 100 * broker_cpu / wall,
            "daemons %/dev": 100 * daemon_cpu / wall / n, "delivered": delivered, "stored": stored,
            "not received gaps": not_received, "unexplained": unexplained}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--devices", type=int, nargs="+", default=[10, 25])
    parser.add_argument("--per-daemon", type=int, default=5)
    parser.add_argument("--seconds", type=float, default=20.0)
    args = parser.parse_args()
    if shutil.which("mosquitto") is None:
        print("mosquitto is not installed (apt-get install mosquitto)", file=sys.stderr)
        return 2
    print(f"load average {os.getloadavg()[0]:.2f}, {os.cpu_count()} cores; {args.seconds:g} s measured per row\n")
    loads = []
    print("| devices | daemons | streaming when measured | messages/s | samples/s | latency p50 ms | p99 ms | collector CPU %/device "
          "| broker CPU % | daemons CPU %/device | samples in local files | stored by the collector | not received gaps | loss unexplained |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for n in args.devices:
        with tempfile.TemporaryDirectory(prefix="bench-fleet-") as tmp:
            r = run(n, args.per_daemon, args.seconds, Path(tmp))
        print(f"| {r['n']} | {r['daemons']} | {r['streaming at start']} | {r['messages/s']:.0f} | {r['samples/s']:.0f} | {r['p50 ms']:.0f} "
              f"| {r['p99 ms']:.0f} | {r['collector %/dev']:.2f} | {r['broker %']:.1f} | {r['daemons %/dev']:.1f} "
              f"| {r['delivered']} | {r['stored']} | {r['not received gaps']} | {r['unexplained'] or 'none'} |",
              flush=True)
        loads.append(os.getloadavg()[0])
    print("\nload average after each row: " + ", ".join(f"{v:.2f}" for v in loads))
    return 0


if __name__ == "__main__":
    sys.exit(main())
