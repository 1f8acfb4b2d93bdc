"""Wire-protocol parser throughput on one core, and the serial driver end to end through a pty.

Run: python tests/benchmarks/bench_protocol.py [--seconds S]
Prints Markdown tables.

* Parser: FrameParser.feed (split on 0x00, COBS decode per block, CRC-16 in C,
  numpy.frombuffer for the samples) over a byte stream cut into 4 KiB reads,
  against a byte-at-a-time COBS state machine (how most firmware-style
  decoders are written) feeding the same CRC and payload decode, in the same
  process.  Payloads come from the simulated firmware (a still sensor at
  +-4 g: many zero bytes, so many COBS blocks) and a worst case of all-zero
  samples (one COBS block per byte).
* Link: the serial driver reading the simulated firmware through a pty at
  2048 Hz on the emulated clock: device seconds delivered per wall second.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from accelrig.acquisition import protocol as P
from accelrig.acquisition.driver import driver_for
from accelrig.acquisition.recorder import record
from accelrig.acquisition.url import DeviceURL
from accelrig_drivers.serial import firmware_from_url

READ_SIZE = 4096


def sim_stream(frame_samples: int, total_samples: int) -> bytes:
    fw, _ = firmware_from_url(DeviceURL.parse("serial-sim://still?seed=1"), 255)
    fw.handle(P.make_body(P.CONFIGURE, P.LinkConfig(4, 2048, frame_samples).payload()))
    fw.handle(P.make_body(P.START))
    bodies = fw.produce((total_samples + frame_samples) / fw.true_rate)
    return b"".join(P.cobs_encode(b) + b"\x00" for b in bodies)


def zero_stream(frame_samples: int, total_samples: int) -> bytes:
    counts = np.zeros((frame_samples, 3), np.int16)
    frames = [P.encode_frame(P.DATA, P.data_payload(s, s * frame_samples, s * 1000, counts))
              for s in range(total_samples // frame_samples)]
    return b"".join(frames)


def naive_cobs_frames(stream: bytes, stats: P.LinkStats):
    """Byte-at-a-time COBS state machine, the usual firmware-style decoder."""
    out = []
    body = bytearray()
    code = remaining = 0
    ok = True
    for byte in stream:
        if byte == 0:
            if ok and remaining == 0 and body:
                frame = P.decode_body(bytes(body), stats)
                if frame is not None:
                    out.append(frame)
            body = bytearray()
            code = remaining = 0
            ok = True
            continue
        if remaining == 0:
            if code and code != 0xFF:
                body.append(0)
            code = remaining = byte
            remaining -= 1
        else:
            body.append(byte)
            remaining -= 1
    return out


def time_parser(stream: bytes, repeats: int = 3) -> tuple[float, int]:
    best = float("inf")
    samples = 0
    for _ in range(repeats):
        parser = P.FrameParser()
        t0 = time.perf_counter()
        for k in range(0, len(stream), READ_SIZE):
            for _ in parser.feed(stream[k:k + READ_SIZE]):
                pass
        best = min(best, time.perf_counter() - t0)
        samples = parser.stats.samples
        assert parser.stats.crc_errors == 0 and parser.stats.cobs_errors == 0
    return best, samples


def time_naive(stream: bytes) -> tuple[float, int]:
    stats = P.LinkStats()
    t0 = time.perf_counter()
    naive_cobs_frames(stream, stats)
    return time.perf_counter() - t0, stats.samples


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=1_000_000, help="samples per parser case")
    ap.add_argument("--seconds", type=float, default=60.0, help="device seconds for the pty run")
    args = ap.parse_args()

    print("## Parser throughput, one core (4 KiB reads)\n")
    print("| payload | samples/frame | bytes/sample on wire | FrameParser samples/s | byte-at-a-time samples/s | speed-up |")
    print("|---|---:|---:|---:|---:|---:|")
    for name, make in (("simulated still sensor", sim_stream), ("all-zero samples (worst case)", zero_stream)):
        for frame in (37, 64, 255):
            stream = make(frame, args.samples)
            dt, n = time_parser(stream)
            naive_n = min(n, 200_000)
            sub = stream[: int(len(stream) * naive_n / n)]
            ndt, nn = time_naive(sub)
            fast, slow = n / dt, nn / ndt
            print(f"| {name} | {frame} | {len(stream) / n:.2f} | {fast:,.0f} | {slow:,.0f} | {fast / slow:.1f} x |")

    print("\n## Serial driver through a pty, emulated clock, 2048 Hz requested\n")
    print("| device s | samples | wall s | device s per wall s | samples/s | lost frames | CRC errors |")
    print("|---:|---:|---:|---:|---:|---:|---:|")
    with driver_for("serial-sim://still?seed=1&pace=fast&rate=2048") as drv:
        t0 = time.perf_counter()
        rec = record(drv, seconds=args.seconds)
        dt = time.perf_counter() - t0
        s = drv.stats
    print(f"| {args.seconds:g} | {len(rec):,} | {dt:.2f} | {args.seconds / dt:.1f} | {len(rec) / dt:,.0f} | "
          f"{s.lost_frames} | {s.crc_errors} |")


if __name__ == "__main__":
    main()
