"""Register-level MPU-9250 emulator (accelerometer part)."""

from __future__ import annotations

from accelrig.sim.chips.emulator import ChipEmulator, Layout
from accelrig.units import MEMS_RANGES_G

PWR_MGMT_1 = 0x6B
USER_CTRL = 0x6A

LAYOUT = Layout(
    banks=1,
    bank_select=None,
    who_am_i=(0, 0x75),
    # Register map rev 1.6: every register resets to 0x00 except PWR_MGMT_1
    # (0x01: awake, auto clock) and WHO_AM_I.
    reset_values={(0, 0x75): 0x71, (0, PWR_MGMT_1): 0x01},
    accel_out=(0, 0x3B),
    fifo_count=(0, 0x72),
    fifo_port=(0, 0x74),
    clear_on_read=frozenset({(0, 0x3A)}),
    overflow_flag=((0, 0x3A), 1 << 4),
    data_ready_flag=((0, 0x3A), 1 << 0),
    offsets=((0, 0x77), (0, 0x7A), (0, 0x7D)),
    # data and count registers; 0x7F is not in the map (modelled as reserved: writes ignored)
    read_only=frozenset({(0, r) for r in (*range(0x3B, 0x49), 0x72, 0x73, 0x7F)}),
)


class MPU9250Emulator(ChipEmulator):
    layout = LAYOUT
    name = "mpu9250"
    bypass_rate = 4000.0

    def sleeping(self) -> bool:
        return bool(self.get(0, PWR_MGMT_1) & 0x40)

    def accel_enabled(self) -> bool:
        return (self.get(0, 0x6C) & 0x38) != 0x38

    def fifo_enabled(self) -> bool:
        return bool(self.get(0, USER_CTRL) & 0x40) and bool(self.get(0, 0x23) & 0x08)

    def fifo_overwrites(self) -> bool:
        return not self.get(0, 0x1A) & 0x40

    def range_g(self) -> float:
        return MEMS_RANGES_G[(self.get(0, 0x1C) >> 3) & 3]

    def output_rate(self) -> float:
        if self.get(0, 0x1D) & 0x08:          # ACCEL_FCHOICE_B: DLPF bypassed
            return self.bypass_fifo_rate
        if 1 <= self.get(0, 0x1A) & 0x07 <= 6:  # gyro DLPF on: 1 kHz internal, SMPLRT_DIV effective
            return 1000.0 / (1 + self.get(0, 0x19))
        return 8000.0                          # DLPF_CFG 0 or 7: 8 kHz, SMPLRT_DIV ignored

    def on_write(self, bank: int, reg: int, value: int) -> bool:
        if reg == PWR_MGMT_1 and value & 0x80:
            self.reset()
            return True
        if reg == USER_CTRL:
            if value & 0x04:                  # FIFO_RST, self-clearing
                self.clear_fifo()
            self.regs[0][USER_CTRL] = value & ~0x07
            return True
        return False
