"""sim://RIG?options: a simulated sensor on a simulated rig, with known ground truth.

Sensor and pacing options (every rig): SENSOR_OPTIONS below; rig options: each rig's ``options``.
Both are listed by ``accelrig devices --verbose``.
"""

from __future__ import annotations

import time

import numpy as np

from accelrig.acquisition.block import Block
from accelrig.acquisition.driver import DeviceInfo, Driver
from accelrig.errors import DeviceError
from accelrig.sim.device import Faults, SimDevice
from accelrig.sim.rigs import RIGS
from accelrig.sim.sensor import SensorModel, SimClock

FIFO_PERIOD = 0.05   # s: realtime pace delivers at least this often (a block may be due sooner)

# every rig's sensor and pacing options, with what people read in `accelrig devices --verbose`
SENSOR_OPTIONS = {
    "seed": "deterministic run (default 0)",
    "pace": "realtime: deliver at the device rate, a block at a time (default; TUI, daemon); "
            "fast: as fast as possible (tests, benchmarks)",
    "rate": "nominal sample rate, Hz (default 200)",
    "rate_error": "relative error of the true rate (default 0.004, i.e. +0.4 %)",
    "jitter": "timestamp jitter sd, s (default 20e-6)",
    "range": "full scale +-G, g (default 2; 8 on the rotary bench, whose swing exceeds 2 g)",
    "noise": "white noise sd per sample, m/s^2 (default: MPU-9250 density)",
    "truth": "random: an imperfect sensor drawn from the seed (default); ideal: a perfect one",
    "block": "samples per block (default 256; realtime pace delivers at least every 50 ms)",
    "drop": "probability that a block is lost on the link, 0-0.99 (default 0)",
    "disconnect_after": "seconds of device time after which the device is gone (an unplugged cable)",
}


def sim_options(url) -> set[str]:
    """The options of a sim:// URL: the sensor's and its rig's (the target names the rig)."""
    rig_cls = RIGS.get(url.target)
    if rig_cls is None:
        raise DeviceError(
            f"unknown simulated rig {url.target!r} in {url.raw!r}",
            f"available: {', '.join('sim://' + r for r in sorted(RIGS))}",
        )
    return set(SENSOR_OPTIONS) | set(rig_cls.options)


def build_device(url) -> tuple[SimDevice, str]:
    """Build the SimDevice an URL describes; returns (device, pace)."""
    url.check_known(sim_options(url))   # unknown rig or option: refused here
    rig_cls = RIGS[url.target]
    seed = url.get_int("seed", 0, low=0)
    pace = url.get_choice("pace", ("realtime", "fast"), "realtime")
    rate = url.get_rate(200.0)
    range_g = url.get_range_g(rig_cls.default_range_g)
    block = url.get_int("block", 256, low=1, high=65536)
    seq = np.random.SeedSequence(seed)
    rig_seed, sensor_seed, device_seed = seq.spawn(3)
    rig = rig_cls.from_url(url, np.random.default_rng(rig_seed))
    truth_kind = url.get_choice("truth", ("random", "ideal"), "random")
    sensor_rng = np.random.default_rng(sensor_seed)
    sensor = SensorModel.random(sensor_rng, range_g=range_g) if truth_kind == "random" else SensorModel(range_g=range_g)
    noise = url.get_float("noise", low=0.0, high=100.0, unit="m/s^2")
    if noise is not None:
        sensor.noise_density = SensorModel.noise_density_for_sd(noise, rate)
    # a clock 50 % off is no clock; jitter beyond 10 ms is not timestamping; drop=1 would deliver nothing, ever
    clock = SimClock(rate, url.get_float("rate_error", 0.004, low=-0.5, high=0.5),
                     url.get_float("jitter", 20e-6, low=0.0, high=0.01, unit="s"))
    faults = Faults(url.get_float("drop", 0.0, low=0.0, high=0.99),
                    url.get_float("disconnect_after", low=0.0, low_open=True, unit="s"))
    device = SimDevice(rig, sensor, clock, seed=int(device_seed.generate_state(1)[0]), block_size=block, faults=faults)
    device.seed = seed
    return device, pace


class SimDriver(Driver):
    scheme = "sim"
    sensor_options = SENSOR_OPTIONS
    description = "simulated sensor on a simulated rig (" + ", ".join(sorted(RIGS)) + ")"

    def __init__(self, url):
        super().__init__(url)
        self.device: SimDevice | None = None
        self.pace = "realtime"
        self._t0 = 0.0

    @classmethod
    def discover(cls) -> list[str]:
        return [f"sim://{name}" for name in sorted(RIGS)]

    def chip_named(self) -> str:
        return "sim"

    def known_options(self) -> set[str]:
        return sim_options(self.url)

    def open(self) -> DeviceInfo:
        self.device, self.pace = build_device(self.url)
        self._t0 = time.monotonic()
        d = self.device
        self.info = DeviceInfo(
            driver="sim",
            url=self.url.raw,
            chip="sim",
            # named by the sensor, not the rig: the same seed is the same simulated part on
            # every rig, so a profile calibrated on one rig applies on another
            identity=f"sim-{self.url.get_str('truth', 'random')}-{d.seed}",
            range_g=d.sensor.range_g,
            scale=d.sensor.scale,
            requested_rate=d.clock.nominal_rate,
            nominal_rate=d.clock.nominal_rate,
            channels=tuple(d.rig.channel_names),
            truth=d.truth(),
            extra={"pace": self.pace},
        )
        return self.info

    @property
    def at_end(self) -> bool:
        return self.device is not None and self.device.exhausted

    def read(self, timeout: float = 0.1) -> list[Block]:
        d = self.device
        if d is None:
            raise DeviceError("the simulated device is not open")
        if d.disconnected:
            raise DeviceError(f"simulated device {self.url.raw} disconnected", "reconnect or check the cable")
        if d.exhausted:
            tail = d.lost_tail(time.monotonic())
            return [tail] if tail is not None else []
        if self.pace == "fast":
            n = d.block_size
        else:
            # Like a driver reading a FIFO: wake once a block is due (a whole block, or
            # FIFO_PERIOD's worth of samples at low rates, so a live view never lags), not
            # once per sample: per-sample wake-ups cost a quarter of a core at 2048 Hz.
            want = max(1, min(d.block_size, int(d.clock.true_rate * FIFO_PERIOD)))
            n = d.samples_due(time.monotonic() - self._t0)
            if n < want:
                wait = (d.counter + want) / d.clock.true_rate - (time.monotonic() - self._t0)
                time.sleep(min(max(wait, 0.0), timeout))
                n = d.samples_due(time.monotonic() - self._t0)
        blocks = []
        host_time = time.monotonic()
        while n > 0 and not d.disconnected:
            take = min(n, d.block_size)
            block = d.next_block(take, host_time)
            n -= take
            if block is not None:
                blocks.append(block)
        tail = d.lost_tail(host_time)
        return blocks + [tail] if tail is not None else blocks

    def close(self) -> None:
        self.device = None
