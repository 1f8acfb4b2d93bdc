"""Register maps as data: descriptors over a swappable bus accessor.

In the manner of Adafruit's ``adafruit_register`` (``RWBits``, ``Struct``,
``register_accessor``): a chip's datasheet register map becomes class
attributes of a :class:`RegisterMap`, and reading or assigning an attribute
talks to the chip through a :class:`RegisterAccessor`.  Two things are added:

* **banks**: every field names its bank; the accessor writes the bank-select
  register (ICM-20948 REG_BANK_SEL) only when the bank changes, and verifies
  that write once after each reset;
* **read-back verification**: every write of a field that is not
  self-clearing is read back and compared; a mismatch is a DeviceError naming
  the register, because a register that does not hold what was written means
  the register map (or the part) is not what we think.

The bus is any object with smbus2.SMBus's interface (``read_byte_data``,
``write_byte_data``, ``read_i2c_block_data``, ``write_i2c_block_data``,
``i2c_rdwr``), so tests pass an emulated bus and run this very code.
"""

from __future__ import annotations

import functools
import struct

from accelrig.errors import DeviceError

# smbus2 (and the kernel's SMBus block transfer) refuse more than 32 bytes.
SMBUS_BLOCK_MAX = 32
# Linux i2c-dev refuses I2C_RDWR messages longer than 8192 bytes.
I2C_RDWR_MAX = 8192


class RegisterAccessor:
    """Reads and writes registers of one device on one bus, bank aware.

    ``bank_select``: address of the bank-select register (present in every
    bank) and the bit shift of the bank number in it, or None for a chip
    without banks.  ``msg_class`` is smbus2's ``i2c_msg`` (or any class with
    the same ``read``/``write`` constructors); it is needed for bursts only.
    """

    def __init__(self, bus, address: int, bank_select: tuple[int, int] | None = None,
                 msg_class=None, label: str = ""):
        self.bus = bus
        self.address = address
        self.bank_select = bank_select
        self.msg_class = msg_class
        self.label = label or f"I2C device 0x{address:02x}"
        self._bank: int | None = None  # unknown until selected
        self._burst_messages: dict[int, tuple] = {}   # register -> (write, read) messages, reused

    # -- banks ---------------------------------------------------------------
    def forget_bank(self) -> None:
        """After a reset the chip is back in bank 0 but we do not rely on it."""
        self._bank = None

    def select(self, bank: int) -> None:
        if self.bank_select is None:
            if bank != 0:
                raise DeviceError(f"{self.label}: register bank {bank} asked of a chip without banks")
            return
        if bank == self._bank:
            return
        reg, shift = self.bank_select
        value = bank << shift
        self._call("write", reg, self.bus.write_byte_data, self.address, reg, value)
        if self._bank is None:
            # First selection after open/reset: check the bank register exists
            # and holds what we wrote (cheap, and catches a wrong chip early).
            back = self._call("read", reg, self.bus.read_byte_data, self.address, reg)
            if back != value:
                raise DeviceError(
                    f"{self.label}: bank select register 0x{reg:02x} reads 0x{back:02x} after writing 0x{value:02x}",
                    "the chip is not the one named in the URL, or the bus is unreliable",
                )
        self._bank = bank

    # -- transfers -----------------------------------------------------------
    def read(self, bank: int, reg: int, length: int) -> bytes:
        """Read ``length`` consecutive registers (or a FIFO port) starting at ``reg``."""
        self.select(bank)
        if length == 1:
            return bytes([self._call("read", reg, self.bus.read_byte_data, self.address, reg)])
        if length <= SMBUS_BLOCK_MAX:
            return bytes(self._call("read", reg, self.bus.read_i2c_block_data, self.address, reg, length))
        return self.burst_read(bank, reg, length)

    def burst_read(self, bank: int, reg: int, length: int) -> bytes:
        """One combined write-register/read-N transaction (I2C_RDWR), beyond the 32-byte SMBus limit.

        A FIFO is read this way a hundred times a second: the two messages are made
        once per register and reused (the read message's buffer holds the most one
        transaction may carry; its length is set per transfer).
        """
        if self.msg_class is None:
            raise DeviceError(f"{self.label}: a burst read needs smbus2's i2c_msg (install accelrig[i2c])")
        self.select(bank)
        messages = self._burst_messages.get(reg)
        if messages is None:
            messages = self._burst_messages[reg] = (self.msg_class.write(self.address, [reg]),
                                                    self.msg_class.read(self.address, I2C_RDWR_MAX))
        write, read = messages
        chunks = []
        while length > 0:
            take = min(length, I2C_RDWR_MAX)
            read.len = take
            self._call("burst read", reg, self.bus.i2c_rdwr, write, read)
            chunk = bytes(read)
            if len(chunk) != take:
                raise DeviceError(f"{self.label}: burst read of {take} bytes at 0x{reg:02x} returned {len(chunk)}")
            chunks.append(chunk)
            length -= take
        return chunks[0] if len(chunks) == 1 else b"".join(chunks)

    def write(self, bank: int, reg: int, data: bytes) -> None:
        self.select(bank)
        data = bytes(data)
        if len(data) == 1:
            self._call("write", reg, self.bus.write_byte_data, self.address, reg, data[0])
        else:
            self._call("write", reg, self.bus.write_i2c_block_data, self.address, reg, list(data))

    def _call(self, what: str, reg: int, fn, *args):
        try:
            return fn(*args)
        except OSError as exc:
            raise DeviceError(
                f"{self.label}: {what} of register 0x{reg:02x} failed: {exc}",
                "check the wiring, the bus number and the address (0x68 or 0x69 with AD0 high)",
            ) from exc


class RegisterMap:
    """Base of a chip's register map: subclasses declare fields as class attributes."""

    def __init__(self, accessor: RegisterAccessor):
        self.accessor = accessor


class Field:
    """Common part of the descriptors: where the field lives and how writes are checked."""

    def __init__(self, reg: int, bank: int = 0, verify: bool = True, readonly: bool = False):
        self.reg = reg
        self.bank = bank
        self.verify = verify
        self.readonly = readonly
        self.name = f"0x{reg:02x}"

    def __set_name__(self, owner, name) -> None:
        bank = f" bank {self.bank}" if self.bank else ""
        self.name = f"{name.upper()} (0x{self.reg:02x}{bank})"

    def _refuse_readonly(self, obj) -> None:
        if self.readonly:
            raise DeviceError(f"{obj.accessor.label}: register {self.name} is read-only")

    def _mismatch(self, obj, wrote, read) -> DeviceError:
        return DeviceError(
            f"{obj.accessor.label}: register {self.name} reads back {read!r} after writing {wrote!r}",
            "the register map does not match this part, or the write was refused (is the chip asleep?)",
        )


class Bits(Field):
    """``width`` bits starting at bit ``lowest`` of a register spanning ``nbytes`` bytes (big-endian).

    ``verify=False`` for self-clearing bits (resets): they read back 0.
    """

    def __init__(self, reg: int, lowest: int = 0, width: int = 1, bank: int = 0, nbytes: int = 1,
                 verify: bool = True, readonly: bool = False):
        super().__init__(reg, bank, verify, readonly)
        self.lowest = lowest
        self.width = width
        self.nbytes = nbytes
        self.mask = ((1 << width) - 1) << lowest

    def _read_raw(self, obj) -> int:
        return int.from_bytes(obj.accessor.read(self.bank, self.reg, self.nbytes), "big")

    def __get__(self, obj, objtype=None):
        if obj is None:
            return self
        return (self._read_raw(obj) & self.mask) >> self.lowest

    def __set__(self, obj, value: int) -> None:
        self._refuse_readonly(obj)
        value = int(value)
        if value < 0 or value >= 1 << self.width:
            raise ValueError(f"{self.name}: {value} does not fit in {self.width} bit(s)")
        if self.width == 8 * self.nbytes:
            current = 0  # the whole register: no need to read first
        else:
            current = self._read_raw(obj)
        new = (current & ~self.mask) | (value << self.lowest)
        obj.accessor.write(self.bank, self.reg, new.to_bytes(self.nbytes, "big"))
        if self.verify:
            back = (self._read_raw(obj) & self.mask) >> self.lowest
            if back != value:
                raise self._mismatch(obj, value, back)


class ROBits(Bits):
    """Read-only bits (identity, status, counts)."""

    def __init__(self, reg: int, lowest: int = 0, width: int = 8, bank: int = 0, nbytes: int = 1):
        super().__init__(reg, lowest, width, bank, nbytes, verify=False, readonly=True)


class Struct(Field):
    """Consecutive registers packed as a ``struct`` format (e.g. ``">hhh"`` for accel data)."""

    def __init__(self, reg: int, fmt: str, bank: int = 0, verify: bool = True, readonly: bool = False):
        super().__init__(reg, bank, verify, readonly)
        self.fmt = fmt
        self.size = struct.calcsize(fmt)

    def __get__(self, obj, objtype=None):
        if obj is None:
            return self
        return struct.unpack(self.fmt, obj.accessor.read(self.bank, self.reg, self.size))

    def __set__(self, obj, values) -> None:
        self._refuse_readonly(obj)
        values = tuple(int(v) for v in (values if isinstance(values, (tuple, list)) else (values,)))
        obj.accessor.write(self.bank, self.reg, struct.pack(self.fmt, *values))
        if self.verify:
            back = struct.unpack(self.fmt, obj.accessor.read(self.bank, self.reg, self.size))
            if back != values:
                raise self._mismatch(obj, values, back)


class Port(Field):
    """A register read repeatedly without address increment (a FIFO data port)."""

    def __init__(self, reg: int, bank: int = 0):
        super().__init__(reg, bank, verify=False, readonly=True)

    def __get__(self, obj, objtype=None):
        if obj is None:
            return self
        return functools.partial(self.read, obj)  # regs.fifo_r_w(n) burst-reads n bytes

    def read(self, obj: RegisterMap, length: int) -> bytes:
        """Burst-read ``length`` bytes with I2C_RDWR (the 32-byte SMBus block limit is real)."""
        return obj.accessor.burst_read(self.bank, self.reg, length)
