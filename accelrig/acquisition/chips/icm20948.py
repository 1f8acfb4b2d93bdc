"""TDK InvenSense ICM-20948: register map as data, four banks behind REG_BANK_SEL.

Addresses and bits from the ICM-20948 datasheet (DS-000189), collected in
REFERENCES.md.  Uncertain facts, checked at run time rather than assumed:
the FIFO size (512 B here; one source says 4 KB: the driver always reads
FIFO_COUNT and notes counts beyond 512), the bank-1 offset register layout
(assumed identical to the MPU-9250's: every write is read back), and the bypass
rate of 4.5 kHz (compared with the rate measured from the sample counter).
"""

from __future__ import annotations

from accelrig.acquisition.chips.base import AccelChip, ChipSpec, RatePlan
from accelrig.acquisition.registers import Bits, Port, RegisterAccessor, RegisterMap, ROBits, Struct
from accelrig.errors import DeviceError

REG_BANK_SEL = 0x7F   # in every bank; bank number in bits 5:4


class ICM20948Registers(RegisterMap):
    # bank 0
    who_am_i = ROBits(0x00)
    user_fifo_en = Bits(0x03, 6)
    device_reset = Bits(0x06, 7, verify=False)    # self-clearing
    sleep = Bits(0x06, 6)                         # set after reset: the chip sleeps
    lp_en = Bits(0x06, 5)
    clksel = Bits(0x06, 0, 3)
    disable_accel = Bits(0x07, 3, 3)
    int_status_2 = ROBits(0x1B)                   # FIFO_OVERFLOW_INT[4:0]; cleared on read
    accel_out = Struct(0x2D, ">hhh", readonly=True)
    fifo_en_2 = Bits(0x67, 0, 5)                  # bit 4: accelerometer into the FIFO
    fifo_rst = Bits(0x68, 0, 5)
    fifo_mode = Bits(0x69, 0, 5)                  # 0 = stream (overwrite oldest)
    fifo_count = ROBits(0x70, 0, 13, nbytes=2)
    fifo_r_w = Port(0x72)
    # bank 1: factory-trimmed accelerometer offsets
    xa_offset = Struct(0x14, ">H", bank=1)
    ya_offset = Struct(0x17, ">H", bank=1)
    za_offset = Struct(0x1A, ">H", bank=1)
    # bank 2: accelerometer configuration
    accel_smplrt_div = Bits(0x10, 0, 12, bank=2, nbytes=2)   # DIV_1 bits 3:0 are bits 11:8
    accel_dlpfcfg = Bits(0x14, 3, 3, bank=2)
    accel_fs_sel = Bits(0x14, 1, 2, bank=2)
    accel_fchoice = Bits(0x14, 0, 1, bank=2)      # 1 = DLPF on, 0 = bypass (4.5 kHz)


FIFO_EN_ACCEL = 1 << 4
FIFO_RESET_ALL = 0x1F

SPEC = ChipSpec(
    name="icm20948",
    label="ICM-20948",
    who_am_i={0xEA: "ICM-20948"},
    dlpf_base_rate=1125.0,
    max_divider=4095,
    bypass_rate=4500.0,
    fifo_capacity=512,        # uncertain (512 B or 4 KB): FIFO_COUNT is always read
    reset_time=0.1,
    offset_registers=("XA_OFFS_H/L (bank 1, 0x14/0x15)", "YA_OFFS_H/L (bank 1, 0x17/0x18)",
                      "ZA_OFFS_H/L (bank 1, 0x1A/0x1B)"),
)


class ICM20948(AccelChip):
    spec = SPEC

    @staticmethod
    def register_map(accessor: RegisterAccessor) -> ICM20948Registers:
        return ICM20948Registers(accessor)

    def read_who_am_i(self) -> int:
        return self.regs.who_am_i

    def reset(self) -> None:
        self.regs.device_reset = 1
        self.clock.sleep(self.spec.reset_time)
        self.accessor.forget_bank()   # the reset put REG_BANK_SEL back to bank 0
        if self.regs.device_reset:
            raise DeviceError(f"{self.accessor.label}: DEVICE_RESET did not clear after {self.spec.reset_time} s")

    def wake(self) -> None:
        self.regs.sleep = 0
        self.regs.lp_en = 0
        self.regs.clksel = 1
        self.regs.disable_accel = 0

    def set_range_code(self, code: int) -> None:
        self.regs.accel_fs_sel = code

    def set_rate(self, plan: RatePlan) -> None:
        self.regs.accel_fchoice = 0 if plan.bypass else 1
        if not plan.bypass:
            self.regs.accel_dlpfcfg = 1   # 246 Hz bandwidth
            self.regs.accel_smplrt_div = plan.divider

    def fifo_start(self) -> None:
        self.regs.user_fifo_en = 0
        self.regs.fifo_mode = 0
        self.regs.fifo_en_2 = FIFO_EN_ACCEL
        self.fifo_reset()
        _ = self.regs.int_status_2    # clear a stale overflow flag (read clears)
        self.regs.user_fifo_en = 1

    def fifo_reset(self) -> float:
        # Assert then de-assert (the datasheet's sequence).  The assert is not
        # read back (the register may clear itself); the de-assert is, after
        # the time is taken: frames are kept again from the de-assert on.
        field = ICM20948Registers.fifo_rst
        self.accessor.write(field.bank, field.reg, bytes([FIFO_RESET_ALL]))
        self.accessor.write(field.bank, field.reg, bytes([0]))
        restarted = self.clock.now()
        back = self.regs.fifo_rst
        if back != 0:
            raise field._mismatch(self, 0, back)
        return restarted

    def fifo_overflowed(self) -> bool:
        return bool(self.regs.int_status_2 & 0x1F)
