"""I2C accelerometer chips: register maps as data, configuration, FIFO streaming, timing."""

from __future__ import annotations

from accelrig.acquisition.chips.base import AccelChip
from accelrig.acquisition.chips.icm20948 import ICM20948
from accelrig.acquisition.chips.mpu9250 import MPU9250

# URL name (chip=...) -> chip class
CHIPS: dict[str, type[AccelChip]] = {
    "mpu9250": MPU9250,
    "icm20948": ICM20948,
}
