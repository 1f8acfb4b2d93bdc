"""An emulated I2C bus with smbus2.SMBus's interface, for register-level chip emulators.

It behaves as the kernel and smbus2 do where a driver could get it wrong:
``read_i2c_block_data`` / ``write_i2c_block_data`` refuse more than 32 bytes
(ValueError, as smbus2 raises), ``i2c_rdwr`` fills read messages in place with
``ctypes.memmove`` into ``msg.buf`` (as the kernel's I2C_RDWR ioctl does) and
refuses messages over 8192 bytes or more than 42 messages (EINVAL), a read
message anywhere but last (EOPNOTSUPP, as the Raspberry Pi's i2c-bcm2835
adapter refuses it: a driver that combines, say, two register reads in one
transaction would fail on the most common host), and an address nobody
answers gives OSError EREMOTEIO (errno 121).  Each transfer
spends its duration at the bus clock on the shared time source, so bus load is
visible in the driver's timing.
"""

from __future__ import annotations

import ctypes
import errno

SMBUS_BLOCK_MAX = 32
I2C_M_RD = 0x0001
I2C_RDWR_MAX_MSGS = 42
I2C_RDWR_MAX_LEN = 8192
BITS_PER_BYTE = 9  # 8 data bits and the ACK


class EmulatedBus:
    """An I2C bus segment holding emulated devices by 7-bit address."""

    def __init__(self, clock=None, bus_hz: float = 400_000.0, gone_after: float | None = None):
        self.clock = clock
        self.bus_hz = bus_hz
        # an unplugged cable: every transfer fails, as a real adapter NAKs, once the clock has
        # run this many seconds from now (None: never)
        self.gone_at = None if gone_after is None else clock.now() + gone_after
        self.devices: dict[int, object] = {}
        self.closed = False
        self.transfers = 0
        self.bytes_moved = 0

    def attach(self, address: int, device) -> None:
        self.devices[address] = device

    # -- smbus2.SMBus interface ----------------------------------------------
    def read_byte_data(self, i2c_addr: int, register: int, force=None) -> int:
        dev = self._device(i2c_addr)
        self._spend([1, 1])
        dev.pointer = register
        return dev.read(1)[0]

    def write_byte_data(self, i2c_addr: int, register: int, value: int, force=None) -> None:
        dev = self._device(i2c_addr)
        self._spend([2])
        dev.pointer = register
        dev.write(bytes([value & 0xFF]))

    def read_i2c_block_data(self, i2c_addr: int, register: int, length: int, force=None) -> list[int]:
        if length > SMBUS_BLOCK_MAX:
            raise ValueError(f"Desired block length over {SMBUS_BLOCK_MAX} bytes")
        dev = self._device(i2c_addr)
        self._spend([1, length])
        dev.pointer = register
        return list(dev.read(length))

    def write_i2c_block_data(self, i2c_addr: int, register: int, data, force=None) -> None:
        if len(data) > SMBUS_BLOCK_MAX:
            raise ValueError(f"Data length cannot exceed {SMBUS_BLOCK_MAX} bytes")
        dev = self._device(i2c_addr)
        self._spend([1 + len(data)])
        dev.pointer = register
        dev.write(bytes(data))

    def i2c_rdwr(self, *i2c_msgs) -> None:
        """Combined transaction: write messages set the register pointer (and write), reads fill buffers."""
        self._check_open()
        if len(i2c_msgs) > I2C_RDWR_MAX_MSGS or any(m.len > I2C_RDWR_MAX_LEN for m in i2c_msgs):
            raise OSError(errno.EINVAL, "Invalid argument")
        if any(m.flags & I2C_M_RD for m in i2c_msgs[:-1]):
            raise OSError(errno.EOPNOTSUPP, "Operation not supported (only the last message may be a read)")
        for msg in i2c_msgs:
            dev = self._device(msg.addr)
            if msg.flags & I2C_M_RD:
                data = dev.read(msg.len)
                ctypes.memmove(msg.buf, bytes(data), msg.len)
            else:
                payload = ctypes.string_at(msg.buf, msg.len)
                if payload:
                    dev.pointer = payload[0]
                    if len(payload) > 1:
                        dev.write(payload[1:])
        self._spend([m.len for m in i2c_msgs])

    def close(self) -> None:
        self.closed = True

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # -- internals -----------------------------------------------------------
    def _check_open(self) -> None:
        if self.closed:
            raise OSError(errno.EBADF, "Bad file descriptor (bus closed)")

    def _device(self, address: int):
        self._check_open()
        dev = self.devices.get(address)
        if dev is None or (self.gone_at is not None and self.clock.now() >= self.gone_at):
            raise OSError(errno.EREMOTEIO, "Remote I/O error")
        return dev

    def _spend(self, message_lengths: list[int]) -> None:
        """Start + address byte per message, the bytes, and the stop."""
        self.transfers += 1
        n = sum(message_lengths)
        self.bytes_moved += n
        if self.clock is not None:
            bits = BITS_PER_BYTE * (n + len(message_lengths)) + 2 * len(message_lengths)
            self.clock.spend(bits / self.bus_hz)
