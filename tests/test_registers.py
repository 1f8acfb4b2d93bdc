"""Register descriptors over a swappable accessor: bits, structs, bursts, banks, read-back verification."""

from __future__ import annotations

import pytest
import smbus2  # noqa: E402
from hypothesis import given, settings
from hypothesis import strategies as st

from accelrig.acquisition.chips.timing import EmulatedClock  # noqa: E402
from accelrig.acquisition.registers import (  # noqa: E402
    Bits,
    Port,
    RegisterAccessor,
    RegisterMap,
    ROBits,
    Struct,
)
from accelrig.errors import DeviceError  # noqa: E402
from accelrig.sim.chips import EmulatedBus, ICM20948Emulator, MPU9250Emulator  # noqa: E402
from accelrig.sim.rigs.still import StillRig  # noqa: E402
from accelrig.sim.sensor import SensorModel  # noqa: E402


class CountingBus(EmulatedBus):
    """The emulated bus, recording every register write (to see bank selects)."""

    def __init__(self, clock):
        super().__init__(clock)
        self.writes: list[tuple[int, int]] = []

    def write_byte_data(self, i2c_addr, register, value, force=None):
        self.writes.append((register, value))
        super().write_byte_data(i2c_addr, register, value, force)


def accessor_for(emulator_cls, banked: bool):
    clock = EmulatedClock()
    chip = emulator_cls(StillRig(), SensorModel(noise_density=0.0), clock)
    bus = CountingBus(clock)
    bus.attach(0x68, chip)
    acc = RegisterAccessor(bus, 0x68, bank_select=(0x7F, 4) if banked else None, msg_class=smbus2.i2c_msg)
    return acc, bus, chip, clock


class MpuDemo(RegisterMap):
    smplrt_div = Bits(0x19, 0, 8)
    fs_sel = Bits(0x1C, 3, 2)
    fchoice_b = Bits(0x1D, 3)
    a_dlpf = Bits(0x1D, 0, 3)
    who_am_i = ROBits(0x75)
    data_wrongly_writable = Bits(0x3B, 0, 8)      # a read-only data register declared writable
    xa_offset = Struct(0x77, ">H")
    accel = Struct(0x3B, ">hhh", readonly=True)
    fifo = Port(0x74)


class IcmDemo(RegisterMap):
    who_am_i = ROBits(0x00)
    sleep = Bits(0x06, 6)
    fs_sel = Bits(0x14, 1, 2, bank=2)
    smplrt_div = Bits(0x10, 0, 12, bank=2, nbytes=2)
    xa_offset = Struct(0x14, ">H", bank=1)


def test_bits_read_modify_write_keeps_the_other_bits():
    acc, bus, chip, _ = accessor_for(MPU9250Emulator, banked=False)
    regs = MpuDemo(acc)
    regs.a_dlpf = 5
    regs.fchoice_b = 1
    assert chip.regs[0][0x1D] == 0x08 | 5
    regs.fchoice_b = 0
    assert regs.a_dlpf == 5 and chip.regs[0][0x1D] == 5
    regs.fs_sel = 3
    assert chip.regs[0][0x1C] == 3 << 3
    with pytest.raises(ValueError):
        regs.fs_sel = 4


def test_write_that_does_not_stick_is_a_device_error_naming_the_register():
    acc, *_ = accessor_for(MPU9250Emulator, banked=False)
    regs = MpuDemo(acc)
    with pytest.raises(DeviceError, match="DATA_WRONGLY_WRITABLE"):
        regs.data_wrongly_writable = 0x5A
    with pytest.raises(DeviceError, match="read-only"):
        regs.who_am_i = 1


def test_struct_and_burst_port():
    acc, bus, chip, clock = accessor_for(MPU9250Emulator, banked=False)
    regs = MpuDemo(acc)
    assert regs.xa_offset == (chip.factory_words[0],)
    regs.xa_offset = (0x1235,)
    assert regs.xa_offset == (0x1235,)
    regs.smplrt_div = 0
    bus.write_byte_data(0x68, 0x1A, 0x01)                 # gyro DLPF on: 1 kHz sample rate
    bus.write_byte_data(0x68, 0x23, 0x08)
    bus.write_byte_data(0x68, 0x6A, 0x44)
    clock.sleep(0.05)                                     # about 50 frames = 300 bytes
    count = bus.read_i2c_block_data(0x68, 0x72, 2)
    n = count[0] << 8 | count[1]
    assert n > 32
    data = regs.fifo(n)                                    # one I2C_RDWR beyond the SMBus limit
    assert len(data) == n and len(chip.fifo) < 12


def test_bank_select_written_only_on_change_and_verified_once():
    acc, bus, chip, _ = accessor_for(ICM20948Emulator, banked=True)
    regs = IcmDemo(acc)
    assert regs.who_am_i == 0xEA
    regs.sleep = 0
    bus.writes.clear()
    regs.fs_sel = 2                  # bank 2
    regs.smplrt_div = 0x123          # still bank 2: no new select
    assert [w for w in bus.writes if w[0] == 0x7F] == [(0x7F, 0x20)]
    assert chip.regs[2][0x10] == 0x01 and chip.regs[2][0x11] == 0x23
    assert regs.xa_offset == (chip.factory_words[0],)      # bank 1
    assert regs.who_am_i == 0xEA                           # back to bank 0
    assert [w[1] for w in bus.writes if w[0] == 0x7F] == [0x20, 0x10, 0x00]


def test_bank_select_on_a_chip_without_banks_is_refused():
    acc, *_ = accessor_for(MPU9250Emulator, banked=False)
    with pytest.raises(DeviceError, match="without banks"):
        acc.read(2, 0x14, 1)


def test_bank_register_that_does_not_hold_is_caught():
    # An MPU-9250 addressed as if it had banks: 0x7F is no bank register there.
    acc, *_ = accessor_for(MPU9250Emulator, banked=True)
    with pytest.raises(DeviceError, match="bank select register 0x7f"):
        acc.read(1, 0x14, 1)


def test_bus_errors_become_device_errors_with_a_hint():
    acc, *_ = accessor_for(MPU9250Emulator, banked=False)
    acc.address = 0x69
    with pytest.raises(DeviceError, match="0x69|address"):
        _ = MpuDemo(acc).who_am_i


@settings(max_examples=60, deadline=None)
@given(lowest=st.integers(0, 7), width=st.integers(1, 8), start=st.integers(0, 255), data=st.data())
def test_bits_round_trip_and_leave_the_rest_alone(lowest, width, start, data):
    width = min(width, 8 - lowest)
    acc, bus, chip, _ = accessor_for(MPU9250Emulator, banked=False)
    chip.regs[0][0x19] = start                      # SMPLRT_DIV: a plain read/write register

    class One(RegisterMap):
        field = Bits(0x19, lowest, width)

    value = data.draw(st.integers(0, (1 << width) - 1))
    regs = One(acc)
    regs.field = value
    mask = ((1 << width) - 1) << lowest
    assert regs.field == value
    assert chip.regs[0][0x19] & ~mask & 0xFF == start & ~mask & 0xFF
