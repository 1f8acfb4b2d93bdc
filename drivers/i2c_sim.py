"""i2c-sim://CHIP?rig=RIG&...: the real I2C driver over a register-level chip emulator.

Everything above the bus is the code that runs on hardware (register map,
reset/wake, rate planning, FIFO bursts with I2C_RDWR, overflow handling,
timing by regression, offset flashing); below it, an emulated MPU-9250 or
ICM-20948 sampling a simulated rig.

Options (besides the i2c:// ones: range, rate, profile, poll):
    rig=NAME          simulated rig (default still); its own options pass through
    seed=N            sensor truth, factory trim and noise (default 0)
    pace=realtime     the wall clock (default); pace=fast: an emulated clock, as fast as possible
    truth=random|ideal   imperfect sensor drawn from the seed, or a perfect one
    noise=SD          white noise sd per sample at the chip's rate, m/s^2 (default: datasheet density)
    rate_error=X      relative error of the chip's oscillator (default 0.004)
    jitter=S          host wake-up lateness sd, s, in pace=fast (default 0.0005)
    bypass_fifo_rate=HZ  FIFO rate the emulated part really has in filter bypass (to test the check)
    address=A         I2C address (default 0x68)
    disconnect_after=S   seconds after opening when the cable is unplugged: every transfer then
                      fails as on hardware (the chip's flashed offsets are gone with its power)
Example: ``i2c-sim://icm20948?rig=still&rate=2048&pace=fast``.
"""

from __future__ import annotations

import numpy as np

from accelrig.acquisition.block import Block
from accelrig.acquisition.chips import CHIPS
from accelrig.acquisition.chips.base import plan_rate
from accelrig.acquisition.chips.timing import EmulatedClock, HostClock
from accelrig.errors import DeviceError
from accelrig.sim.chips import EMULATORS, EmulatedBus
from accelrig.sim.rigs import RIGS
from accelrig.sim.sensor import SensorModel
from accelrig_drivers.i2c import DEFAULT_RATE, I2C_OPTIONS, I2CDriver, import_smbus2

SIM_OPTIONS = {
    "rig": "simulated rig (default still); its own options pass through",
    "seed": "sensor truth, factory trim and noise (default 0)",
    "pace": "realtime: the wall clock (default); fast: an emulated clock, as fast as possible",
    "truth": "random: an imperfect sensor drawn from the seed (default); ideal: a perfect one",
    "noise": "white noise sd per sample at the chip's rate, m/s^2 (default: datasheet density)",
    "rate_error": "relative error of the chip's oscillator (default 0.004)",
    "jitter": "host wake-up lateness sd, s, at pace=fast (default 0.0005)",
    "bypass_fifo_rate": "FIFO rate the emulated part really has in filter bypass, Hz (to test the check)",
    "address": "I2C address (default 0x68)",
    "disconnect_after": "seconds after opening when the cable is unplugged: every transfer then fails",
}


class I2CSimDriver(I2CDriver):
    scheme = "i2c-sim"
    description = "the I2C driver over an emulated MPU-9250 / ICM-20948 on a simulated rig"
    extra = "i2c"
    takes_rig_options = True

    @classmethod
    def option_help(cls) -> dict[str, str]:
        return {**{k: v for k, v in I2C_OPTIONS.items() if k != "chip"}, **SIM_OPTIONS}

    def __init__(self, url):
        super().__init__(url)
        self.emulator = None
        self.rig = None

    @classmethod
    def discover(cls) -> list[str]:
        # the static rig: calibrate, then flash the offsets (the chips can store them)
        return [f"i2c-sim://{name}?rig=static" for name in sorted(EMULATORS)]

    def _rig_class(self):
        name = self.url.get_str("rig", "still")
        rig_cls = RIGS.get(name)
        if rig_cls is None:
            raise DeviceError(f"unknown simulated rig {name!r} in {self.url.raw!r}",
                              f"available: {', '.join(sorted(RIGS))}")
        return rig_cls

    def known_options(self) -> set[str]:
        return (set(I2C_OPTIONS) - {"chip"}) | set(SIM_OPTIONS) | set(self._rig_class().options)

    def chip_name(self) -> str:
        name = self.url.target.strip("/")
        if name not in EMULATORS:
            raise DeviceError(f"i2c-sim has no chip {name!r} in {self.url.raw!r}",
                              f"use one of: {', '.join('i2c-sim://' + n for n in sorted(EMULATORS))}")
        return name

    def target(self) -> tuple[int, int]:
        address = self.url.get_int("address", 0x68)
        if address not in (0x68, 0x69):
            raise DeviceError(f"address=0x{address:02x} in {self.url.raw!r}: the chips answer at 0x68 or 0x69")
        return 0, address

    def identity(self) -> str:
        return f"i2c-sim-{self.chip_name()}-seed{self.url.get_int('seed', 0)}"

    def open_bus(self):
        smbus2 = import_smbus2()
        url = self.url
        name = self.chip_name()
        _, address = self.target()
        seed = url.get_int("seed", 0, low=0)
        pace = url.get_choice("pace", ("realtime", "fast"), "realtime")
        rig_seed, sensor_seed, chip_seed, clock_seed = np.random.SeedSequence(seed).spawn(4)
        self.rig = self._rig_class().from_url(url, np.random.default_rng(rig_seed))
        truth = url.get_choice("truth", ("random", "ideal"), "random")
        sensor = (SensorModel.random(np.random.default_rng(sensor_seed)) if truth == "random" else SensorModel())
        noise = url.get_float("noise", low=0.0, high=100.0, unit="m/s^2")
        if noise is not None:
            chip_rate = plan_rate(CHIPS[name].spec, url.get_rate(DEFAULT_RATE)).chip_rate
            sensor.noise_density = SensorModel.noise_density_for_sd(noise, chip_rate)
        if pace == "fast":
            self.clock = EmulatedClock(wake_jitter=url.get_float("jitter", 0.0005, low=0.0, high=0.01, unit="s"),
                                       rng=np.random.default_rng(clock_seed))
        else:
            self.clock = HostClock()
        self.emulator = EMULATORS[name](
            self.rig, sensor, self.clock,
            seed=int(chip_seed.generate_state(1)[0]),
            rate_error=url.get_float("rate_error", 0.004, low=-0.5, high=0.5),
            bypass_fifo_rate=url.get_float("bypass_fifo_rate", low=1.0, high=100000.0, unit="Hz"),
        )
        bus = EmulatedBus(self.clock, gone_after=url.get_float("disconnect_after", low=0.0, low_open=True, unit="s"))
        bus.attach(address, self.emulator)
        return bus, smbus2.i2c_msg

    def open(self):
        info = super().open()
        e = self.emulator
        info.truth = {
            "sensor": e.sensor.truth(),
            "rig": self.rig.truth(),
            "rate_error": e.rate_error,
            "factory_offset_words": [f"0x{w:04x}" for w in e.factory_words],
        }
        info.extra["pace"] = self.url.get_choice("pace", ("realtime", "fast"), "realtime")
        info.channels = ()
        return info

    @property
    def at_end(self) -> bool:
        duration = self.rig.duration if self.rig is not None else None
        return (duration is not None and self.emulator is not None
                and self.clock.now() - self.emulator.t_origin >= duration)

    def read(self, timeout: float = 0.1) -> list[Block]:
        if self.at_end:
            return []
        return super().read(timeout)
