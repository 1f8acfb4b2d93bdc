"""The register-level chip emulators and the smbus2-shaped bus, driven with smbus2's own i2c_msg."""

from __future__ import annotations

import errno

import numpy as np
import pytest
from smbus2 import i2c_msg  # noqa: E402

from accelrig.acquisition.chips.base import OFFSET_STEP, offset_value  # noqa: E402
from accelrig.acquisition.chips.timing import EmulatedClock  # noqa: E402
from accelrig.sim.chips import EmulatedBus, ICM20948Emulator, MPU9250Emulator  # noqa: E402
from accelrig.sim.rigs.still import StillRig  # noqa: E402
from accelrig.sim.sensor import SensorModel  # noqa: E402

ADDR = 0x68


def make(emulator_cls, sensor=None, **kwargs):
    clock = EmulatedClock()
    sensor = sensor or SensorModel(noise_density=0.0)
    chip = emulator_cls(StillRig(), sensor, clock, seed=5, **kwargs)
    bus = EmulatedBus(clock)
    bus.attach(ADDR, chip)
    return bus, chip, clock


def burst(bus, reg, n):
    write, read = i2c_msg.write(ADDR, [reg]), i2c_msg.read(ADDR, n)
    bus.i2c_rdwr(write, read)
    return bytes(read)


def test_who_am_i_and_variants():
    bus, _, _ = make(MPU9250Emulator)
    assert bus.read_byte_data(ADDR, 0x75) == 0x71
    bus, _, _ = make(MPU9250Emulator, who_am_i=0x73)
    assert bus.read_byte_data(ADDR, 0x75) == 0x73
    bus, _, _ = make(ICM20948Emulator)
    assert bus.read_byte_data(ADDR, 0x00) == 0xEA


def test_absent_address_is_remote_io_error_like_the_kernel():
    bus, _, _ = make(MPU9250Emulator)
    with pytest.raises(OSError) as err:
        bus.read_byte_data(0x69, 0x75)
    assert err.value.errno == errno.EREMOTEIO


def test_block_read_refuses_more_than_32_bytes_like_smbus2():
    bus, _, _ = make(MPU9250Emulator)
    assert len(bus.read_i2c_block_data(ADDR, 0x3B, 32)) == 32
    with pytest.raises(ValueError, match="32"):
        bus.read_i2c_block_data(ADDR, 0x3B, 33)
    with pytest.raises(ValueError):
        bus.write_i2c_block_data(ADDR, 0x00, list(range(33)))


def test_rdwr_fills_read_messages_in_place_and_limits_length():
    bus, _, _ = make(MPU9250Emulator)
    out = burst(bus, 0x75, 1)
    assert out == b"\x71"
    with pytest.raises(OSError) as err:
        bus.i2c_rdwr(i2c_msg.write(ADDR, [0x74]), i2c_msg.read(ADDR, 8193))
    assert err.value.errno == errno.EINVAL


def test_rdwr_refuses_a_read_before_the_last_message_like_i2c_bcm2835():
    # status and count in one transaction would save a syscall per poll, and fail on a Raspberry Pi
    bus, _, _ = make(MPU9250Emulator)
    status_then_count = (i2c_msg.write(ADDR, [0x3A]), i2c_msg.read(ADDR, 1),
                         i2c_msg.write(ADDR, [0x72]), i2c_msg.read(ADDR, 2))
    with pytest.raises(OSError) as err:
        bus.i2c_rdwr(*status_then_count)
    assert err.value.errno == errno.EOPNOTSUPP


def test_icm_banks_and_sleep_after_reset():
    bus, chip, _ = make(ICM20948Emulator)
    assert bus.read_byte_data(ADDR, 0x06) == 0x41          # asleep after power-up
    bus.write_byte_data(ADDR, 0x7F, 2 << 4)                 # bank 2
    assert bus.read_byte_data(ADDR, 0x7F) == 2 << 4
    bus.write_byte_data(ADDR, 0x14, 0x07)                   # ACCEL_CONFIG while asleep: ignored
    assert bus.read_byte_data(ADDR, 0x14) == 0x01
    bus.write_byte_data(ADDR, 0x7F, 0)
    bus.write_byte_data(ADDR, 0x06, 0x01)                   # wake
    bus.write_byte_data(ADDR, 0x7F, 2 << 4)
    bus.write_byte_data(ADDR, 0x14, 0x07)
    assert bus.read_byte_data(ADDR, 0x14) == 0x07
    # The same address in bank 0 is another register (WHO_AM_I at 0x00 proves the switch).
    bus.write_byte_data(ADDR, 0x7F, 0)
    assert bus.read_byte_data(ADDR, 0x00) == 0xEA
    bus.write_byte_data(ADDR, 0x06, 0x80)                   # DEVICE_RESET
    assert bus.read_byte_data(ADDR, 0x06) == 0x41
    assert chip.bank == 0


def _start_mpu_fifo(bus, divider, dlpf_cfg=1):
    bus.write_byte_data(ADDR, 0x1A, dlpf_cfg)               # CONFIG: gyro DLPF (sample-rate generator)
    bus.write_byte_data(ADDR, 0x19, divider)                # SMPLRT_DIV
    bus.write_byte_data(ADDR, 0x23, 0x08)                   # accel into FIFO
    bus.write_byte_data(ADDR, 0x6A, 0x44)                   # FIFO enable + reset


def _fifo_count(bus, reg=0x72):
    hi, lo = bus.read_i2c_block_data(ADDR, reg, 2)
    return hi << 8 | lo


def test_fifo_fills_at_the_configured_rate_and_overflows_when_not_drained():
    bus, chip, clock = make(MPU9250Emulator, rate_error=0.0)
    _start_mpu_fifo(bus, divider=9)                         # 100 Hz
    clock.sleep(0.2)
    count = _fifo_count(bus)
    assert count // 6 in (19, 20, 21)
    assert count % 6 == 0
    frames = np.frombuffer(burst(bus, 0x74, count), ">i2").reshape(-1, 3)
    assert abs(frames[:, 2].mean() * 2 * 9.80665 / 32768 - 9.80665) < 0.01   # +z up at 2 g range
    assert bus.read_byte_data(ADDR, 0x3A) & 0x10 == 0       # no overflow yet
    clock.sleep(1.0)                                        # 100 frames = 600 B > 512 B
    assert _fifo_count(bus) == 512
    assert bus.read_byte_data(ADDR, 0x3A) & 0x10            # FIFO_OFLOW_INT ...
    assert bus.read_byte_data(ADDR, 0x3A) & 0x10 == 0       # ... cleared on read
    assert chip.bytes_lost > 0


def test_mpu_divider_needs_the_gyro_dlpf_like_the_register_map_says():
    bus, chip, clock = make(MPU9250Emulator, rate_error=0.0)
    _start_mpu_fifo(bus, divider=9, dlpf_cfg=0)             # DLPF_CFG 0: 8 kHz, divider ignored
    clock.sleep(0.005)
    assert _fifo_count(bus) // 6 == pytest.approx(40, abs=1)


def test_icm_fifo_in_bypass_runs_at_4500_hz():
    bus, chip, clock = make(ICM20948Emulator, rate_error=0.0)
    bus.write_byte_data(ADDR, 0x06, 0x01)
    bus.write_byte_data(ADDR, 0x7F, 2 << 4)
    bus.write_byte_data(ADDR, 0x14, 0x00)                   # ACCEL_FCHOICE = 0: bypass
    bus.write_byte_data(ADDR, 0x7F, 0)
    bus.write_byte_data(ADDR, 0x67, 0x10)
    bus.write_byte_data(ADDR, 0x68, 0x1F)
    bus.write_byte_data(ADDR, 0x68, 0x00)
    bus.write_byte_data(ADDR, 0x03, 0x40)
    t0 = clock.now()
    clock.sleep(0.01)
    count = _fifo_count(bus, 0x70)
    expected = (clock.now() - t0) * 4500
    assert abs(count / 6 - expected) <= 2
    assert len(burst(bus, 0x72, count)) == count             # beyond 32 bytes: i2c_rdwr


def test_offset_registers_hold_factory_trim_subtract_in_hardware_and_are_lost_on_power_cycle():
    sensor = SensorModel(offset=[0.3, -0.2, 0.1], noise_density=0.0, range_g=2.0)
    bus, chip, clock = make(MPU9250Emulator, sensor=sensor)
    words = [int.from_bytes(bytes(bus.read_i2c_block_data(ADDR, r, 2)), "big") for r in (0x77, 0x7A, 0x7D)]
    assert words == chip.factory_words
    clock.sleep(0.01)
    before = np.array(bus.read_i2c_block_data(ADDR, 0x3B, 6), dtype=np.uint8).view(">i2").astype(float)
    # Subtract 100 steps on x, keeping bit 0.
    new_x = (((offset_value(words[0]) - 100) << 1) & 0xFFFF) | (words[0] & 1)
    bus.write_i2c_block_data(ADDR, 0x77, [new_x >> 8, new_x & 0xFF])
    clock.sleep(0.01)
    after = np.array(bus.read_i2c_block_data(ADDR, 0x3B, 6), dtype=np.uint8).view(">i2").astype(float)
    scale = 2 * 9.80665 / 32768
    assert (before[0] - after[0]) * scale == pytest.approx(100 * OFFSET_STEP, abs=scale)
    assert before[1] == after[1]
    chip.power_cycle()
    assert int.from_bytes(bytes(bus.read_i2c_block_data(ADDR, 0x77, 2)), "big") == words[0]


def test_sleeping_chip_takes_no_samples():
    bus, chip, clock = make(ICM20948Emulator)
    clock.sleep(0.5)
    assert chip.samples_taken == 0
    bus.write_byte_data(ADDR, 0x06, 0x01)
    clock.sleep(0.5)
    bus.read_i2c_block_data(ADDR, 0x2D, 6)                 # samples are taken as the bus looks
    assert chip.samples_taken == pytest.approx(0.5 * 1125 * (1 + chip.rate_error), abs=2)


def test_bus_time_is_spent_on_the_shared_clock():
    bus, _, clock = make(MPU9250Emulator)
    t0 = clock.now()
    burst(bus, 0x74, 400)
    # 400 data bytes + register byte + two address bytes at 9 bits, 400 kHz: about 9 ms
    assert clock.now() - t0 == pytest.approx(403 * 9 / 400e3, rel=0.05)
