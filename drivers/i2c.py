"""i2c://BUS/ADDRESS?chip=mpu9250|icm20948: an InvenSense accelerometer on a Linux I2C bus.

Options:
    chip=mpu9250|icm20948   the part (default mpu9250); WHO_AM_I is checked, with known variants
    range=G                 full scale +-2, 4, 8 or 16 g (default 2)
    rate=HZ                 requested rate (default 1000).  Up to 1 kHz (1.125 kHz ICM-20948)
                            the DLPF divider giving the nearest rate; above, filter bypass at
                            4 kHz (4.5 kHz) resampled by an anti-alias FIR to the rate asked
                            (2000 and 2048 exactly).  The rate delivered is reported and
                            then measured from the sample counter.
    profile=PATH            a device profile whose bias is written to the chip's offset
                            registers on every open (they are volatile: lost at power-off);
                            loaded and written by accelrig.profiles.flash.flash_url_profile
    poll=S                  FIFO poll interval (default a third of a FIFO fill, at most 10 ms);
                            a read polls for about 50 ms (each poll: overflow status, count,
                            one burst of the whole frames) and then resamples and times its
                            frames at once, one block per gapless run

Example: ``i2c://1/0x68?chip=icm20948&range=4&rate=2048``.  The bus is opened
with smbus2 (``pip install 'accelrig[i2c]'``); tests and ``i2c-sim://`` hand
the same driver an emulated bus instead (any object with smbus2.SMBus's
interface can be passed as ``bus=``).
"""

from __future__ import annotations

import glob
import re

import numpy as np

from accelrig.acquisition.block import Block
from accelrig.acquisition.chips import CHIPS
from accelrig.acquisition.chips.base import OFFSET_STEP, plan_offsets
from accelrig.acquisition.chips.icm20948 import REG_BANK_SEL
from accelrig.acquisition.chips.stream import FifoStream
from accelrig.acquisition.chips.timing import HostClock
from accelrig.acquisition.driver import DeviceInfo, Driver
from accelrig.acquisition.flash import FlashPlan, FlashReport, FlashWrite
from accelrig.acquisition.registers import RegisterAccessor
from accelrig.errors import DeviceError, require_extra
from accelrig.result import Correction
from accelrig.units import scale_for_range

I2C_OPTIONS = {
    "chip": "mpu9250 (default) or icm20948; WHO_AM_I is checked, with known variants",
    "range": "full scale +-G: 2 (default), 4, 8, 16",
    "rate": "requested sample rate, Hz (default 1000); the rate delivered is reported, then measured",
    "profile": "a device profile whose bias is written to the chip's offset registers on every open",
    "poll": "FIFO poll interval, s (default a third of a FIFO fill, at most 10 ms)",
}
DEFAULT_RATE = 1000.0


def import_smbus2():
    return require_extra("smbus2", "I2C", "smbus2", "i2c")


class I2CDriver(Driver):
    scheme = "i2c"
    description = "MPU-9250 / ICM-20948 on a Linux I2C bus (FIFO burst reads, offsets flashable)"
    extra = "i2c"

    def __init__(self, url, bus=None, clock=None):
        """``bus``: an smbus2.SMBus-like object to use instead of opening /dev/i2c-N;
        ``clock``: the time source (default the host clock)."""
        super().__init__(url)
        self._injected_bus = bus
        self.bus = None
        self.clock = clock or HostClock()
        self.chip = None
        self.stream: FifoStream | None = None
        self.factory_words: list[int] | None = None
        self.applied_offsets: dict | None = None
        self._owns_bus = False

    # -- discovery and options ---------------------------------------------------
    @classmethod
    def discover(cls) -> list[str]:
        """The I2C buses present (/dev/i2c-N), at the chips' default address; nothing is probed."""
        import_smbus2()
        buses = sorted(int(m.group(1)) for p in glob.glob("/dev/i2c-*") if (m := re.search(r"i2c-(\d+)$", p)))
        return [f"i2c://{n}/0x68" for n in buses]

    def chip_named(self) -> str:
        return self.chip_name()

    @classmethod
    def option_help(cls) -> dict[str, str]:
        return dict(I2C_OPTIONS)

    def known_options(self) -> set[str]:
        return set(I2C_OPTIONS)

    def chip_name(self) -> str:
        return self.url.get_choice("chip", tuple(CHIPS), "mpu9250")

    def target(self) -> tuple[int, int]:
        m = re.fullmatch(r"/*(\d+)/(0x[0-9a-fA-F]+|\d+)/?", self.url.target)
        if not m:
            raise DeviceError(
                f"{self.url.raw!r} does not name a bus and an address",
                "write it as i2c://BUS/ADDRESS, e.g. i2c://1/0x68",
            )
        bus, address = int(m.group(1)), int(m.group(2), 0)
        if not 0x03 <= address <= 0x77:
            raise DeviceError(f"I2C address 0x{address:02x} in {self.url.raw!r} is outside 0x03 .. 0x77")
        return bus, address

    def identity(self) -> str:
        bus, address = self.target()
        return f"i2c-{bus}-0x{address:02x}"

    def open_bus(self):
        """(bus, i2c_msg class).  The real bus: smbus2 on /dev/i2c-N."""
        smbus2 = import_smbus2()
        if self._injected_bus is not None:
            return self._injected_bus, smbus2.i2c_msg
        number, _ = self.target()
        try:
            bus = smbus2.SMBus(number)
        except (OSError, FileNotFoundError) as exc:
            raise DeviceError(
                f"cannot open I2C bus {number} (/dev/i2c-{number}): {exc}",
                "enable I2C (e.g. raspi-config), check the bus number, and that you may use /dev/i2c-*",
            ) from None
        self._owns_bus = True
        return bus, smbus2.i2c_msg

    # -- Driver interface -----------------------------------------------------------
    def open(self) -> DeviceInfo:
        self.url.check_known(self.known_options())
        name = self.chip_name()
        _, address = self.target()
        range_g = self.url.get_range_g(2.0)
        rate = self.url.get_rate(DEFAULT_RATE)
        poll = self.url.get_float("poll")
        if poll is not None and not 0.001 <= poll <= 0.1:
            raise DeviceError(f"poll={poll} s in {self.url.raw!r} is outside 0.001 .. 0.1 s")
        chip_cls = CHIPS[name]
        self.bus, msg_class = self.open_bus()
        try:
            accessor = RegisterAccessor(
                self.bus, address,
                bank_select=(REG_BANK_SEL, 4) if name == "icm20948" else None,
                msg_class=msg_class,
                label=f"{chip_cls.spec.label} at {self.identity()}",
            )
            self.chip = chip_cls(accessor, self.clock)
            who, part = self.chip.identify()
            plan = self.chip.configure(range_g, rate)
            # Right after reset the offset registers hold the factory trim; every
            # flash starts from these, so flashing twice never subtracts twice.
            self.factory_words = self.chip.read_offset_words()
            scale = scale_for_range(range_g)
            self.info = DeviceInfo(
                driver=self.scheme,
                url=self.url.raw,
                chip=name,
                identity=self.identity(),
                range_g=range_g,
                scale=scale,
                requested_rate=rate,
                nominal_rate=plan.delivered_rate,
                who_am_i=who,
                part=part,
                rate_plan=plan.describe(),
                extra={
                    "chip_rate": plan.chip_rate,
                    "factory_offset_words": [f"0x{w:04x}" for w in self.factory_words],
                },
            )
            # the FIFO starts at the first read, so offsets flashed right after open
            # (a profile=PATH) apply to every sample
            self.stream = FifoStream(self.chip, self.clock, plan, scale, poll)
            self.info.extra["poll_interval"] = self.stream.poll_interval
        except BaseException:
            self.close()
            raise
        return self.info

    def read(self, timeout: float = 0.1) -> list[Block]:
        if self.stream is None:
            raise DeviceError(f"{self.url.raw} is not open")
        if not self.stream.started:
            self.stream.start()
        return self.stream.read(timeout)

    def close(self) -> None:
        if self._owns_bus and self.bus is not None:
            try:
                self.bus.close()
            except OSError:
                pass
        self.bus = None
        self.stream = None
        self._owns_bus = False

    @property
    def delivered_rate(self) -> float:
        """Rate measured from the sample counter against the host clock, Hz."""
        if self.stream is None:
            raise DeviceError(f"{self.url.raw} is not open")
        return self.stream.delivered_rate

    # -- flashing the offset registers -----------------------------------------------
    def plan_flash(self, correction: Correction, profile_id: bytes) -> FlashPlan:
        """The offset-register writes removing ``correction``'s bias; reads the chip, writes nothing.

        The bias is subtracted from the factory trim read at open, in 1/1024 g
        (0.98 mg) steps, keeping the reserved bit 0.  What the registers cannot
        hold (the sub-step remainder; gain and misalignment) stays in the host
        profile.  The registers differ between parts: the plan says so
        (``chip_specific``).
        """
        if self.chip is None or self.info is None:
            raise DeviceError(f"{self.url.raw} must be open to plan a flash")
        op = plan_offsets(self.factory_words, correction.bias)
        current = self.chip.read_offset_words()
        names = self.chip.spec.offset_registers
        writes = [
            FlashWrite(target=names[i], current=f"0x{current[i]:04x}", new=f"0x{op.new_words[i]:04x}",
                       meaning=op.meaning[i])
            for i in range(3)
        ]
        residual = {
            "bias_remaining_m_s2": op.residual.tolist(),
            "bias_removed_m_s2": (np.array(op.steps) * OFFSET_STEP).tolist(),
            "register_step_m_s2": OFFSET_STEP,
            "matrix": np.asarray(correction.matrix).tolist(),
            "meaning": "the chip now subtracts bias_removed; apply calibrated = C @ (raw - bias_remaining) on the host",
        }
        notes = [
            "offset registers are volatile: they return to the factory trim at power-off and reset, so the "
            "profile is re-applied on every connect (open the device with profile=PATH)",
            "gain and misalignment (the matrix C) cannot be stored in the chip and stay in the host profile",
        ]
        if current != self.factory_words:
            notes.append("the registers were written since the reset; the plan starts from the factory trim read "
                         "at open, so nothing is subtracted twice")
        payload = {"driver": id(self), "words": op.new_words}
        return FlashPlan(device=self.info.identity, writes=writes, residual=residual, notes=notes, payload=payload,
                         chip_specific=True)

    def flash(self, plan: FlashPlan) -> FlashReport:
        """Write the planned offset words, read them back, compare.  On a failure the previous words are restored."""
        if self.chip is None:
            raise DeviceError(f"{self.url.raw} must be open to flash")
        payload = plan.payload if isinstance(plan.payload, dict) else {}
        if payload.get("driver") != id(self):
            raise DeviceError("this flash plan was made for another connection", "plan again on this device")
        words = payload["words"]
        before = self.chip.read_offset_words()
        try:
            self.chip.write_offset_words(words)
            back = self.chip.read_offset_words()
        except DeviceError as exc:
            try:
                self.chip.write_offset_words(before)
                restored = "the previous offsets were restored"
            except DeviceError:
                restored = "restoring the previous offsets failed too: power-cycle the sensor"
            raise DeviceError(f"flashing the offsets failed: {exc.message}; {restored}", exc.hint) from exc
        readback = [FlashWrite(target=w.target, current=f"0x{b:04x}", new=f"0x{n:04x}", meaning=w.meaning)
                    for w, b, n in zip(plan.writes, back, words, strict=True)]
        verified = back == list(words)
        if not verified:
            raise DeviceError(
                "the offset registers read back "
                + ", ".join(f"0x{b:04x}" for b in back) + " instead of " + ", ".join(f"0x{n:04x}" for n in words),
                "the register layout is not what this driver assumes for this part; keep the bias in the host profile",
            )
        self.applied_offsets = plan.residual
        # from now on the chip's output already lacks this much bias (see profiles.correction_for)
        self.info.hardware_bias_removed = list(plan.residual["bias_removed_m_s2"])
        return FlashReport(device=plan.device, verified=True, readback=readback, residual=plan.residual,
                           notes=list(plan.notes))
