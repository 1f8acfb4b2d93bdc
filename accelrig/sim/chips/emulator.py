"""Register-level emulation of an InvenSense accelerometer, driven by a simulated rig.

What is modelled (each is exercised by the real driver in the tests):
register banks and bank select, WHO_AM_I, reset values (sleep after reset
where the part does it), configuration registers, a sample clock running at
the configured rate times (1 + rate_error) on the shared time source, the data
registers, a FIFO filled at that rate that overflows when not drained
(overwrite mode: oldest bytes lost, frame alignment lost; stop mode: newest
dropped), interrupt status cleared on read, and offset registers holding a
per-part factory trim with the reserved bit 0, added to the output in
hardware, reloaded at reset and power-up (written values are lost).

Samples are computed ahead of the sample clock, ``LOOKAHEAD`` at a time (the
rig, the sensor model and the noise cost per call far more than per sample),
and enter the data registers and the FIFO only when their time comes: what
the host can read at any moment is what the part would hold.  The offset
registers and the range act when a sample is taken, so a write applies from
the next sample on, as in the part.

Not modelled: the DLPF frequency response (the rigs' signals are far below
it), gyroscope and magnetometer, I2C master, interrupts pins, self-test.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from accelrig.acquisition.chips.base import OFFSET_STEP, offset_value
from accelrig.sim.rigs.base import Rig
from accelrig.sim.sensor import SensorModel
from accelrig.units import scale_for_range

Addr = tuple[int, int]  # (bank, register)

# Samples sensed per call of the rig and sensor model (0.25 s at 4 kHz).
LOOKAHEAD = 1024


@dataclass(frozen=True)
class Layout:
    """Where a chip keeps what the emulator needs (data, not code)."""

    banks: int
    bank_select: int | None           # register present in every bank, bank in bits 5:4
    who_am_i: Addr
    reset_values: dict[Addr, int]
    accel_out: Addr                   # 6 bytes, big-endian x, y, z
    fifo_count: Addr                  # 2 bytes, big-endian, 13 bits
    fifo_port: Addr
    clear_on_read: frozenset[Addr]    # interrupt status registers
    overflow_flag: tuple[Addr, int]   # register and mask set on FIFO overflow
    data_ready_flag: tuple[Addr, int]
    offsets: tuple[Addr, Addr, Addr]  # high byte of each axis' offset pair
    read_only: frozenset[Addr] = field(default_factory=frozenset)


class ChipEmulator:
    """Base of the chip emulators: register file, sample clock, FIFO, offsets."""

    layout: Layout
    name: str
    bypass_rate: float

    def __init__(self, rig: Rig, sensor: SensorModel, clock, seed: int = 0, rate_error: float = 0.0,
                 fifo_capacity: int = 512, bypass_fifo_rate: float | None = None, who_am_i: int | None = None):
        self.rig = rig
        self.sensor = sensor
        self.clock = clock
        self.rate_error = rate_error
        self.fifo_capacity = fifo_capacity
        # The FIFO rate in filter bypass is an uncertain datasheet fact: the
        # emulator can be told it is different, so the driver's check is tested.
        self.bypass_fifo_rate = bypass_fifo_rate or self.bypass_rate
        self.who_am_i_value = who_am_i
        self.t_origin = clock.now()   # rig time 0: power-on
        rng = np.random.default_rng(seed)
        self._noise_rng = np.random.default_rng(rng.integers(2**63))
        # Factory trim per part: a 15-bit value near what cancels the raw bias,
        # and the reserved bit 0 as the factory left it (set on some axes).
        self.factory_words = [
            ((int(v) << 1) & 0xFFFF) | int(b)
            for v, b in zip(rng.integers(-3000, 3000, 3), rng.integers(0, 2, 3), strict=True)
        ]
        self._trim = np.array([offset_value(w) for w in self.factory_words])
        self._response_t = sensor.response_matrix.T   # the part does not change while it runs
        # Counters a test can compare with what the driver reports.
        self.samples_taken = 0
        self.frames_into_fifo = 0
        self.bytes_lost = 0
        self.power_cycles = 0
        self.power_cycle()

    # -- power and reset ------------------------------------------------------
    def power_cycle(self) -> None:
        """Power off and on: every register to its reset value, written offsets lost."""
        self.power_cycles += 1
        self._load_reset_values()

    def _load_reset_values(self) -> None:
        self.regs = [bytearray(128) for _ in range(self.layout.banks)]
        for (bank, reg), value in self.layout.reset_values.items():
            self.regs[bank][reg] = value
        if self.who_am_i_value is not None:
            bank, reg = self.layout.who_am_i
            self.regs[bank][reg] = self.who_am_i_value
        for (bank, reg), word in zip(self.layout.offsets, self.factory_words, strict=True):
            self.regs[bank][reg] = word >> 8
            self.regs[bank][reg + 1] = word & 0xFF
        self.bank = 0
        self.pointer = 0
        self.fifo = bytearray()
        self._next_tick: float | None = None
        self._period: float | None = None
        self._latest = np.zeros(3, dtype=np.int16)
        self._forget_ahead()
        self._retime()

    # -- configuration as the chip sees it (per chip) --------------------------
    def sleeping(self) -> bool: raise NotImplementedError
    def accel_enabled(self) -> bool: raise NotImplementedError
    def fifo_enabled(self) -> bool: raise NotImplementedError
    def fifo_overwrites(self) -> bool: raise NotImplementedError
    def range_g(self) -> float: raise NotImplementedError
    def output_rate(self) -> float: raise NotImplementedError

    def on_write(self, bank: int, reg: int, value: int) -> bool:
        """Chip-specific side effects of a write; return True if it was consumed."""
        return False

    def write_allowed(self, bank: int, reg: int) -> bool:
        return True

    def get(self, bank: int, reg: int) -> int:
        return self.regs[bank][reg]

    # -- the bus side ------------------------------------------------------------
    def read(self, length: int) -> bytes:
        """Read ``length`` bytes from the register pointer (auto-increment, except the FIFO port)."""
        self.advance()
        if (self.bank, self.pointer) == self.layout.fifo_port:
            return self._pop_fifo(length)
        out = bytearray()
        for _ in range(length):
            out.append(self._read_register(self.pointer))
            self.pointer = (self.pointer + 1) & 0x7F
        return bytes(out)

    def write(self, data: bytes) -> None:
        self.advance()
        for value in data:
            self._write_register(self.pointer, value)
            self.pointer = (self.pointer + 1) & 0x7F
        # the samples not yet taken are converted again under the registers as they are now
        self._ahead_counts = self._ahead_bytes = None
        self._retime()

    def _read_register(self, reg: int) -> int:
        lay = self.layout
        if lay.bank_select is not None and reg == lay.bank_select:
            return self.bank << 4
        addr = (self.bank, reg)
        bank_out, reg_out = lay.accel_out
        if self.bank == bank_out and reg_out <= reg < reg_out + 6:
            return int(self._latest.astype(">i2").tobytes()[reg - reg_out])
        bank_c, reg_c = lay.fifo_count
        if self.bank == bank_c and reg in (reg_c, reg_c + 1):
            count = min(len(self.fifo), 0x1FFF)
            return count >> 8 if reg == reg_c else count & 0xFF
        value = self.regs[self.bank][reg]
        if addr in lay.clear_on_read:
            self.regs[self.bank][reg] = 0
        return value

    def _write_register(self, reg: int, value: int) -> None:
        lay = self.layout
        if lay.bank_select is not None and reg == lay.bank_select:
            self.bank = (value >> 4) & 0x3
            if self.bank >= lay.banks:
                self.bank = 0
            return
        addr = (self.bank, reg)
        if addr in lay.read_only or addr == lay.who_am_i or addr in lay.clear_on_read:
            return
        if not self.write_allowed(self.bank, reg):
            return
        if self.on_write(self.bank, reg, value):
            return
        self.regs[self.bank][reg] = value

    # -- sampling ----------------------------------------------------------------
    def _retime(self) -> None:
        """Restart the sample clock if the configuration changed its period or stopped it."""
        running = not self.sleeping() and self.accel_enabled()
        if not running:
            self._next_tick = None
            self._period = None
            return
        period = 1.0 / (self.output_rate() * (1.0 + self.rate_error))
        if self._period != period or self._next_tick is None:
            self._period = period
            self._next_tick = self.clock.now() + period
            self._forget_ahead()

    def advance(self) -> None:
        """Take every sample due by now: data registers, data-ready flag, FIFO."""
        if self._next_tick is None:
            return
        now = self.clock.now()
        if now < self._next_tick:
            return
        n = int((now - self._next_tick) // self._period) + 1
        start = self._ahead_pos
        if start + n > len(self._ahead_raw):
            self._sense_ahead(n)
            start = 0
        stop = start + n
        self._ahead_pos = stop
        self._next_tick += n * self._period
        if self._ahead_bytes is None:
            self._convert_ahead()
        self.samples_taken += n
        self._latest = self._ahead_counts[stop - 1]
        (bank, reg), mask = self.layout.data_ready_flag
        self.regs[bank][reg] |= mask
        if self.fifo_enabled():
            self._push_fifo(self._ahead_bytes[6 * start:6 * stop], n)

    def _forget_ahead(self) -> None:
        """Drop the samples computed ahead (the sample clock restarted or changed its period)."""
        self._ahead_raw = np.empty((0, 3))
        self._ahead_pos = 0
        self._ahead_counts = self._ahead_bytes = None

    def _sense_ahead(self, n: int) -> None:
        """Compute the next max(n, LOOKAHEAD) samples from the next tick on (keeping those not yet taken)."""
        kept = self._ahead_raw[self._ahead_pos:]
        m = max(n, LOOKAHEAD)
        first = self._next_tick + len(kept) * self._period
        fresh = self._sense_raw(first + np.arange(m) * self._period)
        self._ahead_raw = np.concatenate([kept, fresh]) if len(kept) else fresh
        self._ahead_pos = 0
        self._ahead_counts = self._ahead_bytes = None

    def _sense_raw(self, times: np.ndarray) -> np.ndarray:
        """The sensor's output at ``times`` with the factory trim in place, m/s^2 (n, 3)."""
        s = self.sensor
        force = self.rig.specific_force(times - self.t_origin)
        raw = force @ self._response_t + s.offset
        if np.any(s.drift_rate != 0):
            raw = raw + (times - self.t_origin)[:, None] * s.drift_rate
        return raw + s.noise(raw.shape[0], self._noise_rng, 1.0 / self._period)

    def _convert_ahead(self) -> None:
        """Counts of the samples ahead under the offset registers and range set now."""
        # The offset registers add (register - factory trim) steps to the output:
        # with the factory trim in place the output bias is sensor.offset.
        held = np.array([offset_value(self._offset_word(axis)) for axis in range(3)])
        counts = np.rint((self._ahead_raw + (held - self._trim) * OFFSET_STEP) / scale_for_range(self.range_g()))
        np.clip(counts, -32768, 32767, out=counts)
        self._ahead_counts = counts.astype(np.int16)
        self._ahead_bytes = self._ahead_counts.astype(">i2").tobytes()

    def _offset_word(self, axis: int) -> int:
        bank, reg = self.layout.offsets[axis]
        return self.regs[bank][reg] << 8 | self.regs[bank][reg + 1]

    def _push_fifo(self, data: bytes, frames: int) -> None:
        self.frames_into_fifo += frames
        self.fifo += data
        excess = len(self.fifo) - self.fifo_capacity
        if excess > 0:
            (bank, reg), mask = self.layout.overflow_flag
            self.regs[bank][reg] |= mask
            self.bytes_lost += excess
            if self.fifo_overwrites():
                del self.fifo[:excess]          # oldest bytes go: frame alignment is lost
            else:
                del self.fifo[self.fifo_capacity:]

    def _pop_fifo(self, length: int) -> bytes:
        out = bytes(self.fifo[:length])
        del self.fifo[:length]
        if len(out) < length:
            # Reading an empty FIFO returns junk on the parts; make it visible.
            out += b"\xff" * (length - len(out))
        return out

    def clear_fifo(self) -> None:
        self.fifo = bytearray()

    def reset(self) -> None:
        """DEVICE_RESET: registers to reset values; the offset trim is reloaded (modelled as OTP reload)."""
        self._load_reset_values()
