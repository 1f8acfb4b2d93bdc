"""Register-level ICM-20948 emulator (accelerometer part), four register banks."""

from __future__ import annotations

from accelrig.sim.chips.emulator import ChipEmulator, Layout
from accelrig.units import MEMS_RANGES_G

PWR_MGMT_1 = 0x06
FIFO_RST = 0x68

LAYOUT = Layout(
    banks=4,
    bank_select=0x7F,
    who_am_i=(0, 0x00),
    # DS-000189: PWR_MGMT_1 resets to 0x41 (asleep, auto clock), ACCEL_CONFIG
    # (bank 2) to 0x01 (DLPF on), everything else used here to 0x00.
    reset_values={(0, 0x00): 0xEA, (0, PWR_MGMT_1): 0x41, (2, 0x14): 0x01},
    accel_out=(0, 0x2D),
    fifo_count=(0, 0x70),
    fifo_port=(0, 0x72),
    clear_on_read=frozenset({(0, 0x19), (0, 0x1A), (0, 0x1B)}),
    overflow_flag=((0, 0x1B), 0x01),
    data_ready_flag=((0, 0x1A), 0x01),
    offsets=((1, 0x14), (1, 0x17), (1, 0x1A)),
    read_only=frozenset({(0, r) for r in (*range(0x2D, 0x3B), 0x70, 0x71)}),
)


class ICM20948Emulator(ChipEmulator):
    layout = LAYOUT
    name = "icm20948"
    bypass_rate = 4500.0

    def sleeping(self) -> bool:
        return bool(self.get(0, PWR_MGMT_1) & 0x40)

    def accel_enabled(self) -> bool:
        return (self.get(0, 0x07) & 0x38) != 0x38

    def fifo_enabled(self) -> bool:
        return (bool(self.get(0, 0x03) & 0x40) and bool(self.get(0, 0x67) & 0x10)
                and not self.get(0, FIFO_RST) & 0x1F)

    def fifo_overwrites(self) -> bool:
        return not self.get(0, 0x69) & 0x1F

    def range_g(self) -> float:
        return MEMS_RANGES_G[(self.get(2, 0x14) >> 1) & 3]

    def output_rate(self) -> float:
        if not self.get(2, 0x14) & 0x01:       # ACCEL_FCHOICE = 0: DLPF bypassed
            return self.bypass_fifo_rate
        divider = (self.get(2, 0x10) & 0x0F) << 8 | self.get(2, 0x11)
        return 1125.0 / (1 + divider)

    def write_allowed(self, bank: int, reg: int) -> bool:
        # Asleep, the part takes only PWR_MGMT_1 (and the bank select, handled
        # before): a driver that forgets to wake sees its writes not stick.
        return not self.sleeping() or (bank, reg) == (0, PWR_MGMT_1)

    def on_write(self, bank: int, reg: int, value: int) -> bool:
        if (bank, reg) == (0, PWR_MGMT_1) and value & 0x80:
            self.reset()
            return True
        if (bank, reg) == (0, FIFO_RST):
            if value & 0x1F:                  # asserted: FIFO held empty
                self.clear_fifo()
            self.regs[0][FIFO_RST] = value & 0x1F
            return True
        return False
