"""What every supported I2C accelerometer chip offers, and the logic they share.

A chip module declares its register map as data (a RegisterMap) and a
ChipSpec, and implements the few operations whose registers differ (reset,
FIFO control, rate).  Identity checks, the configuration sequence, rate
planning and the offset-register arithmetic live here once.
"""

from __future__ import annotations

import abc
from dataclasses import dataclass, field

import numpy as np

from accelrig.acquisition.chips.decimate import resampling_ratio
from accelrig.acquisition.registers import RegisterAccessor
from accelrig.errors import DeviceError
from accelrig.units import MEMS_RANGES_G, STANDARD_GRAVITY

# Full-scale ranges (+-g) and their ACCEL_FS_SEL codes, the same on both chips.
RANGE_CODES = {r: code for code, r in enumerate(MEMS_RANGES_G)}  # the 2-bit ACCEL_FS_SEL code

# Offset registers: 15-bit two's complement in bits 15:1 at +-16 g scale,
# i.e. 1/1024 g per step ("0.98 mg" in the register map); bit 0 is reserved and
# must be written back as read.
OFFSET_STEP = STANDARD_GRAVITY / 1024.0
OFFSET_MIN, OFFSET_MAX = -(1 << 14), (1 << 14) - 1

FRAME_BYTES = 6  # one accelerometer sample in the FIFO: x, y, z big-endian int16


@dataclass(frozen=True)
class ChipSpec:
    """Datasheet facts of one chip (see REFERENCES.md; uncertain ones are checked at run time)."""

    name: str                       # URL name: "mpu9250", "icm20948"
    label: str                      # "MPU-9250"
    who_am_i: dict[int, str]        # accepted WHO_AM_I values -> part name (known variants)
    dlpf_base_rate: float           # Hz, sample rate = base / (1 + divider) with the DLPF on
    max_divider: int                # largest sample-rate divider
    bypass_rate: float              # Hz with the accelerometer filter bypassed
    fifo_capacity: int              # bytes, nominal (always read FIFO_COUNT)
    reset_time: float               # s to wait after DEVICE_RESET
    offset_registers: tuple[str, str, str]  # names shown in flash plans


@dataclass(frozen=True)
class RatePlan:
    """How a requested rate is delivered: chip setting, then optional L/M resampling."""

    requested: float
    bypass: bool
    divider: int
    chip_rate: float      # nominal rate the FIFO fills at, Hz
    up: int = 1
    down: int = 1

    @property
    def delivered_rate(self) -> float:
        """Nominal delivered rate, Hz (the true one is estimated from the sample counter)."""
        return self.chip_rate * self.up / self.down

    def describe(self) -> str:
        if not self.bypass:
            return f"DLPF on, divider {self.divider}: {self.chip_rate:g} Hz"
        if self.up == self.down:
            return f"filter bypass: {self.chip_rate:g} Hz"
        return (f"filter bypass at {self.chip_rate:g} Hz, resampled by {self.up}/{self.down} "
                f"with an anti-alias FIR to {self.delivered_rate:g} Hz")


def plan_rate(spec: ChipSpec, requested: float) -> RatePlan:
    """Choose the chip setting that delivers ``requested`` Hz, or the nearest deliverable rate.

    Up to the DLPF base rate, the divider giving the nearest rate; above it,
    bypass and a proper resampling filter down to the requested rate.
    """
    if not np.isfinite(requested) or requested <= 0:
        raise DeviceError(f"rate={requested} Hz is not a positive rate")
    if requested <= spec.dlpf_base_rate:
        div = int(np.clip(round(spec.dlpf_base_rate / requested) - 1, 0, spec.max_divider))
        # round() on the divider is not round() on the rate: check the neighbours.
        candidates = [d for d in (div - 1, div, div + 1) if 0 <= d <= spec.max_divider]
        div = min(candidates, key=lambda d: abs(spec.dlpf_base_rate / (1 + d) - requested))
        return RatePlan(requested, False, div, spec.dlpf_base_rate / (1 + div))
    if requested >= spec.bypass_rate:
        return RatePlan(requested, True, 0, spec.bypass_rate)
    ratio = resampling_ratio(spec.bypass_rate, requested)
    return RatePlan(requested, True, 0, spec.bypass_rate, ratio.numerator, ratio.denominator)


def offset_value(word: int) -> int:
    """The signed 15-bit offset held in bits 15:1 of a register pair read as unsigned 16 bits."""
    signed = word - 0x10000 if word & 0x8000 else word
    return signed >> 1


def offset_word(value: int, reserved_bit: int) -> int:
    """Register pair (unsigned 16 bits) holding ``value`` in bits 15:1 and ``reserved_bit`` in bit 0."""
    if not OFFSET_MIN <= value <= OFFSET_MAX:
        raise DeviceError(
            f"offset register value {value} is outside the 15-bit range {OFFSET_MIN} .. {OFFSET_MAX}",
            "the bias is too large for the chip's offset registers; keep it in the host profile",
        )
    return ((value << 1) & 0xFFFF) | (reserved_bit & 1)


@dataclass
class OffsetPlan:
    """The offset-register writes that remove a bias, and what they cannot remove."""

    current_words: list[int]          # as read (unsigned 16-bit)
    new_words: list[int]
    steps: list[int]                  # register steps subtracted per axis
    residual: np.ndarray              # m/s^2 the registers cannot represent (bias - steps * step)
    meaning: list[str] = field(default_factory=list)


def plan_offsets(current_words: list[int], bias: np.ndarray) -> OffsetPlan:
    """Subtract ``bias`` (m/s^2, raw frame) from factory-trimmed offset registers in 1/1024 g steps.

    The register adds to the output, so subtracting round(b / step) removes
    the bias up to half a step; bit 0 (reserved) is kept as read.
    """
    bias = np.asarray(bias, dtype=float).reshape(3)
    steps = [int(round(b / OFFSET_STEP)) for b in bias]
    new_words, meaning = [], []
    for axis, (word, step) in enumerate(zip(current_words, steps, strict=True)):
        new_words.append(offset_word(offset_value(word) - step, word & 1))
        meaning.append(f"offset {'xyz'[axis]}: bias {bias[axis]:+.5f} m/s^2 -> {-step:+d} steps of 0.98 mg")
    residual = bias - np.array(steps) * OFFSET_STEP
    return OffsetPlan(list(current_words), new_words, steps, residual, meaning)


class AccelChip(abc.ABC):
    """One chip on one bus, driven through its register map."""

    spec: ChipSpec

    def __init__(self, accessor: RegisterAccessor, clock):
        self.accessor = accessor
        self.clock = clock
        self.regs = self.register_map(accessor)

    @staticmethod
    @abc.abstractmethod
    def register_map(accessor: RegisterAccessor):
        """The chip's RegisterMap over ``accessor``."""

    # -- identity and configuration (shared sequence) -------------------------
    def identify(self) -> tuple[int, str]:
        who = self.read_who_am_i()
        if who not in self.spec.who_am_i:
            known = ", ".join(f"0x{v:02x} ({n})" for v, n in self.spec.who_am_i.items())
            raise DeviceError(
                f"{self.accessor.label} answers WHO_AM_I=0x{who:02x}, which is not a {self.spec.label} ({known})",
                "check chip= in the URL (mpu9250 or icm20948) and the address",
            )
        return who, self.spec.who_am_i[who]

    def configure(self, range_g: float, requested_rate: float) -> RatePlan:
        """Reset, wake, set range and rate; every write read back.  FIFO left off."""
        if range_g not in RANGE_CODES:
            raise DeviceError(f"range={range_g:g} g is not a range of the {self.spec.label}", "use 2, 4, 8 or 16")
        plan = plan_rate(self.spec, requested_rate)
        self.reset()
        self.wake()
        self.set_range_code(RANGE_CODES[range_g])
        self.set_rate(plan)
        return plan

    # -- chip-specific operations --------------------------------------------
    @abc.abstractmethod
    def read_who_am_i(self) -> int: ...

    @abc.abstractmethod
    def reset(self) -> None:
        """DEVICE_RESET, wait, and check the chip came back (reset bit cleared)."""

    @abc.abstractmethod
    def wake(self) -> None:
        """Leave sleep, select the PLL clock, enable the accelerometer axes."""

    @abc.abstractmethod
    def set_range_code(self, code: int) -> None: ...

    @abc.abstractmethod
    def set_rate(self, plan: RatePlan) -> None: ...

    @abc.abstractmethod
    def fifo_start(self) -> None:
        """Stream (overwrite) mode, accelerometer only, reset, enable."""

    @abc.abstractmethod
    def fifo_reset(self) -> float:
        """Empty the FIFO; returns the host time just after the write from which it keeps frames again
        (its first frame is taken within one period after that), before any read-back."""

    @abc.abstractmethod
    def fifo_overflowed(self) -> bool:
        """Read (and so clear) the overflow status."""

    # Both register maps name these fields alike (fifo_count, fifo_r_w, xa/ya/za_offset),
    # so the chips share one implementation; banks are the register map's business.
    def fifo_count(self) -> int:
        return self.regs.fifo_count

    def fifo_read(self, length: int) -> bytes:
        """Burst-read ``length`` bytes from the FIFO data port (I2C_RDWR)."""
        return self.regs.fifo_r_w(length)

    def read_offset_words(self) -> list[int]:
        """The three offset register pairs as unsigned 16-bit words."""
        return [self.regs.xa_offset[0], self.regs.ya_offset[0], self.regs.za_offset[0]]

    def write_offset_words(self, words: list[int]) -> None:
        """Write the three offset register pairs (each read back and compared)."""
        x, y, z = words
        self.regs.xa_offset = (x,)
        self.regs.ya_offset = (y,)
        self.regs.za_offset = (z,)
