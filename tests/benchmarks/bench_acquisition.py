"""Throughput of driver -> ring buffer -> recorder, and memory over a long run.

Run: python tests/benchmarks/bench_acquisition.py [--samples N]
Prints Markdown tables.  One core: the simulator runs as fast as possible in
the same thread as the consumer (pace=fast), so the figure is what one core
sustains end to end, simulation included.
"""

from __future__ import annotations

import argparse
import resource
import time

from accelrig.acquisition.driver import driver_for
from accelrig.acquisition.recorder import record
from accelrig.acquisition.ringbuffer import RingBuffer


def rss_mib() -> float:
    with open("/proc/self/status") as fh:
        for line in fh:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def bench_record(url: str, samples: int) -> tuple[float, float]:
    with driver_for(url) as drv:
        t0 = time.perf_counter()
        rec = record(drv, samples=samples)
        dt = time.perf_counter() - t0
    assert len(rec) == samples
    return samples / dt, dt


def bench_stream(url: str, samples: int, checkpoints: int = 8):
    """Driver -> ring -> two readers (one drains everything, one polls every 32nd cycle), RSS at checkpoints."""
    rows = []
    with driver_for(url) as drv:
        ring = RingBuffer(1 << 16, drv.info.scale, drv.info.channels)
        main, slow = ring.reader(), ring.reader()
        n = lost_main = lost_slow = 0
        step = samples // checkpoints
        next_cp = step
        t0 = time.perf_counter()
        i = 0
        while n < samples:
            for block in drv.read():
                ring.write(block)
            chunk = main.read()
            n += chunk.n
            lost_main += chunk.lost
            i += 1
            if i % 32 == 0:
                lost_slow += slow.read().lost
            if n >= next_cp:
                rows.append((n, time.perf_counter() - t0, rss_mib(), ring.nbytes / 2**20))
                next_cp += step
        dt = time.perf_counter() - t0
    return n / dt, rows, lost_main, lost_slow


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--samples", type=int, default=4_000_000)
    args = ap.parse_args()
    print("## Throughput, one core, simulator as fast as possible\n")
    print("| pipeline | rig | block | samples | seconds | samples/s | x one 2048 Hz device |")
    print("|---|---|---:|---:|---:|---:|---:|")
    for rig, block in (("still", 4096), ("still", 1024), ("still", 256)):
        url = f"sim://{rig}?pace=fast&block={block}&rate=2048"
        rate, dt = bench_record(url, args.samples // 2)
        print(f"| driver -> ring -> record() | {rig} | {block} | {args.samples // 2:,} | {dt:.2f} | {rate:,.0f} | {rate / 2048:,.0f} |")
    rate, rows, lost_main, lost_slow = bench_stream("sim://still?pace=fast&block=4096&rate=2048", args.samples * 4)
    print(f"| driver -> ring -> 2 readers (streaming) | still | 4096 | {args.samples * 4:,} | {rows[-1][1]:.2f} | {rate:,.0f} | {rate / 2048:,.0f} |")
    print(f"\nStreaming run: the draining reader lost {lost_main} samples; the reader polled every 32nd cycle lost {lost_slow} (counted, as designed).\n")
    print("## Memory over the streaming run (ring buffer of 65,536 samples)\n")
    print("| samples so far | seconds | process RSS (MiB) | ring buffer (MiB) |")
    print("|---:|---:|---:|---:|")
    for n, t, rss, ring in rows:
        print(f"| {n:,} | {t:.2f} | {rss:.1f} | {ring:.2f} |")


if __name__ == "__main__":
    main()
