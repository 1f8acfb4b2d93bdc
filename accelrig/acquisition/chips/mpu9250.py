"""InvenSense MPU-9250 (and its MPU-9255 / MPU-6500 relatives): register map as data.

Register addresses and bit positions from the MPU-9250 register map (rev 1.6),
collected in REFERENCES.md.  Uncertain facts are checked at run time:
the FIFO rate in accelerometer filter bypass (4 kHz assumed) is compared with
the rate measured from the sample counter (see FifoStream), and every
configuration write is read back.
"""

from __future__ import annotations

from accelrig.acquisition.chips.base import AccelChip, ChipSpec, RatePlan
from accelrig.acquisition.registers import Bits, Port, RegisterAccessor, RegisterMap, ROBits, Struct
from accelrig.errors import DeviceError


class MPU9250Registers(RegisterMap):
    smplrt_div = Bits(0x19, 0, 8)
    fifo_mode = Bits(0x1A, 6)                 # 1 = stop when full, 0 = overwrite oldest
    dlpf_cfg = Bits(0x1A, 0, 3)               # gyro DLPF: 1..6 makes the internal rate 1 kHz and SMPLRT_DIV effective
    accel_fs_sel = Bits(0x1C, 3, 2)
    accel_fchoice_b = Bits(0x1D, 3)           # 1 = bypass the accelerometer DLPF (4 kHz)
    a_dlpfcfg = Bits(0x1D, 0, 3)
    fifo_en = Bits(0x23, 0, 8)                # bit 3: accelerometer into the FIFO
    int_status = ROBits(0x3A)                 # bit 4 FIFO_OFLOW_INT, bit 0 RAW_DATA_RDY; cleared on read
    accel_out = Struct(0x3B, ">hhh", readonly=True)
    user_fifo_en = Bits(0x6A, 6)
    user_fifo_rst = Bits(0x6A, 2, verify=False)   # self-clearing
    device_reset = Bits(0x6B, 7, verify=False)    # self-clearing
    sleep = Bits(0x6B, 6)
    clksel = Bits(0x6B, 0, 3)
    disable_accel = Bits(0x6C, 3, 3)          # DISABLE_XA, _YA, _ZA
    fifo_count = ROBits(0x72, 0, 13, nbytes=2)
    fifo_r_w = Port(0x74)
    who_am_i = ROBits(0x75)
    xa_offset = Struct(0x77, ">H")
    ya_offset = Struct(0x7A, ">H")
    za_offset = Struct(0x7D, ">H")


FIFO_OFLOW_INT = 1 << 4
FIFO_EN_ACCEL = 1 << 3

SPEC = ChipSpec(
    name="mpu9250",
    label="MPU-9250",
    who_am_i={0x71: "MPU-9250", 0x73: "MPU-9255", 0x70: "MPU-6500"},
    dlpf_base_rate=1000.0,
    max_divider=255,
    bypass_rate=4000.0,        # FIFO rate in bypass: uncertain, measured at run time
    fifo_capacity=512,
    reset_time=0.1,
    offset_registers=("XA_OFFSET_H/L (0x77/0x78)", "YA_OFFSET_H/L (0x7A/0x7B)", "ZA_OFFSET_H/L (0x7D/0x7E)"),
)


class MPU9250(AccelChip):
    spec = SPEC

    @staticmethod
    def register_map(accessor: RegisterAccessor) -> MPU9250Registers:
        return MPU9250Registers(accessor)

    def read_who_am_i(self) -> int:
        return self.regs.who_am_i

    def reset(self) -> None:
        self.regs.device_reset = 1
        self.clock.sleep(self.spec.reset_time)
        if self.regs.device_reset:
            raise DeviceError(f"{self.accessor.label}: DEVICE_RESET did not clear after {self.spec.reset_time} s")

    def wake(self) -> None:
        self.regs.sleep = 0
        self.regs.clksel = 1          # PLL when ready, else internal oscillator
        self.regs.disable_accel = 0

    def set_range_code(self, code: int) -> None:
        self.regs.accel_fs_sel = code

    def set_rate(self, plan: RatePlan) -> None:
        self.regs.accel_fchoice_b = 1 if plan.bypass else 0
        if plan.bypass:
            # The FIFO's rate in accelerometer bypass is the uncertain fact: with the
            # gyro DLPF off the sample-rate generator is not the 1 kHz one; the rate
            # actually delivered is measured and checked by FifoStream.
            self.regs.dlpf_cfg = 0
        else:
            # The register map: SMPLRT_DIV is effective only with 0 < DLPF_CFG < 7
            # (internal rate 1 kHz); otherwise the FIFO runs at the 8 kHz gyro rate.
            self.regs.dlpf_cfg = 1
            self.regs.a_dlpfcfg = 1   # 184 Hz accelerometer bandwidth at 1 kHz
            self.regs.smplrt_div = plan.divider

    def fifo_start(self) -> None:
        self.regs.user_fifo_en = 0
        self.regs.fifo_mode = 0       # overwrite: an overflow is seen in INT_STATUS and by count
        self.regs.fifo_en = FIFO_EN_ACCEL
        self.fifo_reset()
        _ = self.regs.int_status      # clear a stale overflow flag (read clears)
        self.regs.user_fifo_en = 1

    def fifo_reset(self) -> float:
        self.regs.user_fifo_rst = 1   # self-clearing: not read back
        return self.clock.now()

    def fifo_overflowed(self) -> bool:
        return bool(self.regs.int_status & FIFO_OFLOW_INT)
