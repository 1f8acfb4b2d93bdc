"""I2C driver over the emulated chips: delivered rate, timing accuracy, losses, cost.

    python tests/benchmarks/bench_i2c.py [--seconds 60]

For each chip and requested rate, the real driver runs against the
register-level emulator on an emulated clock (host wake-up jitter 0.5 ms, the
chip's oscillator 0.4 % fast) with a sawtooth ramp rig whose x reading tells
when each sample was taken.  Prints a Markdown table: the rate plan, the
measured delivered rate against the truth (in units of its own standard
uncertainty), the sample-time error against the truth, samples lost, I2C bus
utilisation at 400 kHz, and CPU cost per second of emulated real time.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from accelrig.acquisition.chips.timing import EmulatedClock
from accelrig.acquisition.url import DeviceURL
from accelrig.sim.chips import EMULATORS, EmulatedBus
from accelrig.sim.chips.ramp import RampRig
from accelrig.sim.sensor import SensorModel
from accelrig_drivers.i2c import I2CDriver

RATE_ERROR = 0.004


def run(chip: str, rate: float, seconds: float, seed: int = 0) -> dict:
    clock = EmulatedClock(wake_jitter=0.0005, rng=np.random.default_rng(seed))
    rig = RampRig(period=10.0)
    emulator = EMULATORS[chip](rig, SensorModel(noise_density=0.0, range_g=16.0), clock, seed=seed,
                               rate_error=RATE_ERROR)
    bus = EmulatedBus(clock)
    bus.attach(0x68, emulator)
    driver = I2CDriver(DeviceURL.parse(f"i2c://1/0x68?chip={chip}&rate={rate:g}&range=16"), bus=bus, clock=clock)
    cpu0 = time.process_time()
    info = driver.open()
    t_start = clock.now()
    bytes0 = bus.bytes_moved
    blocks = []
    while clock.now() < t_start + seconds:
        blocks.extend(driver.read(timeout=0.1))
    cpu = time.process_time() - cpu0
    elapsed = clock.now() - t_start
    stream = driver.stream
    t = np.concatenate([b.t for b in blocks])
    x = np.concatenate([b.counts[:, 0] for b in blocks]) * info.scale
    true_t = rig.decode(x, t)
    # Skip the first second (the fit settling) and samples near the sawtooth's jumps (filtered edges).
    phase = np.mod(t, rig.period)      # the driver's time: a filtered jump decodes to nonsense
    ok = (t > t[0] + 1.0) & (phase > 0.05) & (phase < rig.period - 0.05)
    err = (t - true_t)[ok]
    true_rate = info.nominal_rate * (1 + RATE_ERROR)
    lost = sum(max(b.gap_before, 0) for b in blocks) + stream.overflows
    driver.close()
    return {
        "chip": chip, "requested": rate, "plan": info.rate_plan, "delivered": info.nominal_rate,
        "measured": stream.delivered_rate, "z": (stream.delivered_rate - true_rate) / stream.delivered_rate_uncertainty,
        "u_rate": stream.delivered_rate_uncertainty,
        "mean_err_us": 1e6 * err.mean(), "sd_err_us": 1e6 * err.std(), "p99_err_us": 1e6 * np.percentile(np.abs(err), 99),
        "lost": lost, "fifo_lost_bytes": emulator.bytes_lost,
        "bus": (bus.bytes_moved - bytes0) * 9 / 400e3 / elapsed,
        "cpu_per_s": cpu / elapsed, "samples": len(t),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=60.0, help="emulated seconds per run (default 60)")
    args = parser.parse_args()
    print(f"## I2C driver over emulated chips: {args.seconds:g} s of emulated real time per row, "
          f"oscillator +{RATE_ERROR:.1%}, host wake-up jitter 0.5 ms.")
    resolution = 16 * 9.80665 / 32768 / RampRig().slope      # s per count of x at +-16 g
    print(f"Time error: driver time stamp minus the time decoded from the ramp; decoding resolves "
          f"{resolution * 1e6:.0f} us, an sd floor of about {resolution / 12 ** 0.5 * 1e6:.0f} us.\n")
    print("| chip | requested Hz | how | delivered Hz (nominal) | measured Hz | u(measured) Hz | "
          "(measured - true)/u | time error mean / sd / p99 (us) | samples lost | I2C bus use | CPU s per s |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for chip in ("mpu9250", "icm20948"):
        for rate in (200, 1000, 2000, 2048):
            r = run(chip, rate, args.seconds)
            print(f"| {r['chip']} | {r['requested']:g} | {r['plan']} | {r['delivered']:.2f} | {r['measured']:.3f} | "
                  f"{r['u_rate']:.4f} | {r['z']:+.2f} | {r['mean_err_us']:+.1f} / {r['sd_err_us']:.1f} / "
                  f"{r['p99_err_us']:.1f} | {r['lost']} | {r['bus']:.0%} | {r['cpu_per_s']:.3f} |")


if __name__ == "__main__":
    main()
