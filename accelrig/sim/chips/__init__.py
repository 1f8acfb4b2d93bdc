"""Register-level emulators of the I2C chips behind an smbus2-shaped emulated bus."""

from __future__ import annotations

from accelrig.sim.chips.bus import EmulatedBus
from accelrig.sim.chips.emulator import ChipEmulator
from accelrig.sim.chips.icm20948 import ICM20948Emulator
from accelrig.sim.chips.mpu9250 import MPU9250Emulator

EMULATORS: dict[str, type[ChipEmulator]] = {
    "mpu9250": MPU9250Emulator,
    "icm20948": ICM20948Emulator,
}

__all__ = ["EMULATORS", "ChipEmulator", "EmulatedBus", "ICM20948Emulator", "MPU9250Emulator"]
