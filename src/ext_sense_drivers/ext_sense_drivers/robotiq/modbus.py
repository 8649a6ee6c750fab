"""Modbus RTU frames for the functions a Robotiq 2F uses, for client and device (emulator).

Registers are 16-bit big-endian on the wire; the CRC-16/Modbus goes low byte first.
"""

from __future__ import annotations

import struct
from collections.abc import Sequence
from enum import IntEnum
from typing import NamedTuple

from ext_sense_drivers.robotiq.crc import append_crc, crc16_modbus, crc_ok
from ext_sense_drivers.robotiq.errors import FaultKind, RobotiqError

_HEADER = struct.Struct(">BBHH")  # slave, function, start address, register count
_EXCEPTION_BIT = 0x80
EXCEPTION_REPLY_LENGTH = 5
"""slave, function | 0x80, exception code, CRC (2)."""
MAX_READ_REGISTERS = 125
MAX_WRITE_REGISTERS = 123


class Function(IntEnum):
    """Modbus function codes the Robotiq 2F understands."""

    READ_HOLDING_REGISTERS = 0x03
    READ_INPUT_REGISTERS = 0x04
    WRITE_MULTIPLE_REGISTERS = 0x10


class ExceptionCode(IntEnum):
    """Modbus exception codes (reply function code has bit 7 set)."""

    ILLEGAL_FUNCTION = 0x01
    ILLEGAL_DATA_ADDRESS = 0x02
    ILLEGAL_DATA_VALUE = 0x03
    SERVER_DEVICE_FAILURE = 0x04


class Request(NamedTuple):
    """A decoded request as the device sees it; ``values`` is empty for reads."""

    slave: int
    function: int
    address: int
    count: int
    values: tuple[int, ...]


def _check_range(name: str, value: int, low: int, high: int) -> int:
    if not isinstance(value, int) or isinstance(value, bool) or not low <= value <= high:
        raise RobotiqError(
            f"The '{name}' argument must be an int in [{low}, {high}]. Got {value!r} instead.",
            FaultKind.BAD_ARGUMENT,
        )
    return value


def encode_read_request(
    slave: int, address: int, count: int, function: Function = Function.READ_HOLDING_REGISTERS
) -> bytes:
    """The 8-byte request to read ``count`` (1..125) registers from ``address``."""
    _check_range("slave", slave, 1, 247)
    _check_range("address", address, 0, 0xFFFF)
    _check_range("count", count, 1, MAX_READ_REGISTERS)
    if function not in (Function.READ_HOLDING_REGISTERS, Function.READ_INPUT_REGISTERS):
        raise RobotiqError(
            f"The 'function' argument must be 0x03 or 0x04. Got {int(function):#04x} instead.",
            FaultKind.BAD_ARGUMENT,
        )
    return append_crc(_HEADER.pack(slave, int(function), address, count))


def encode_write_request(slave: int, address: int, values: Sequence[int]) -> bytes:
    """The request (0x10) writing 1..123 ``values`` to consecutive registers from ``address``."""
    _check_range("slave", slave, 1, 247)
    _check_range("address", address, 0, 0xFFFF)
    _check_range("len(values)", len(values), 1, MAX_WRITE_REGISTERS)
    for value in values:
        _check_range("values[i]", value, 0, 0xFFFF)
    body = _HEADER.pack(slave, Function.WRITE_MULTIPLE_REGISTERS, address, len(values))
    body += bytes([2 * len(values)]) + struct.pack(f">{len(values)}H", *values)
    return append_crc(body)


def read_reply_length(count: int) -> int:
    """Bytes in a normal reply to a read of ``count`` registers."""
    return 5 + 2 * count


WRITE_REPLY_LENGTH = 8
"""slave, 0x10, start address, register count, CRC."""


def _check_reply(frame: bytes, slave: int, function: int) -> None:
    if len(frame) < EXCEPTION_REPLY_LENGTH:
        raise RobotiqError(
            f"Reply too short: expected at least {EXCEPTION_REPLY_LENGTH} bytes, "
            f"got {len(frame)} ({frame.hex(' ')}).",
            FaultKind.BAD_FRAME,
        )
    if not crc_ok(frame):
        raise RobotiqError(
            f"Reply CRC mismatch: computed {crc16_modbus(frame[:-2]):#06x}, "
            f"received {int.from_bytes(frame[-2:], 'little'):#06x} ({frame.hex(' ')}).",
            FaultKind.BAD_CRC,
        )
    if frame[0] != slave:
        raise RobotiqError(
            f"Reply from slave {frame[0]}, expected slave {slave}.", FaultKind.BAD_FRAME
        )
    if frame[1] == function | _EXCEPTION_BIT:
        code = frame[2]
        name = ExceptionCode(code).name if code in ExceptionCode._value2member_map_ else "unknown"
        raise RobotiqError(
            f"Gripper answered function {function:#04x} with Modbus exception "
            f"{code:#04x} ({name}).",
            FaultKind.EXCEPTION_REPLY,
        )
    if frame[1] != function:
        raise RobotiqError(
            f"Reply function {frame[1]:#04x}, expected {function:#04x}.", FaultKind.BAD_FRAME
        )


def decode_read_reply(
    frame: bytes,
    slave: int,
    count: int,
    function: Function = Function.READ_HOLDING_REGISTERS,
) -> tuple[int, ...]:
    """The ``count`` registers a whole read reply carries (BAD_CRC, EXCEPTION_REPLY, BAD_FRAME)."""
    _check_reply(frame, slave, int(function))
    if len(frame) != read_reply_length(count) or frame[2] != 2 * count:
        raise RobotiqError(
            f"Read reply for {count} registers must be {read_reply_length(count)} bytes with "
            f"byte count {2 * count}; got {len(frame)} bytes, byte count {frame[2]}.",
            FaultKind.BAD_FRAME,
        )
    return struct.unpack_from(f">{count}H", frame, 3)


def decode_write_reply(frame: bytes, slave: int, address: int, count: int) -> None:
    """Check a reply to a write of ``count`` registers at ``address``."""
    _check_reply(frame, slave, Function.WRITE_MULTIPLE_REGISTERS)
    if len(frame) != WRITE_REPLY_LENGTH:
        raise RobotiqError(
            f"Write reply must be {WRITE_REPLY_LENGTH} bytes, got {len(frame)}.",
            FaultKind.BAD_FRAME,
        )
    _, _, echo_address, echo_count = _HEADER.unpack_from(frame)
    if (echo_address, echo_count) != (address, count):
        raise RobotiqError(
            f"Write reply echoes address {echo_address:#06x} count {echo_count}, expected "
            f"{address:#06x} count {count}.",
            FaultKind.BAD_FRAME,
        )


def request_length(prefix: bytes) -> int | None:
    """Length of the request starting with ``prefix``, or ``None`` if more bytes are needed.

    Unknown functions give 8, so the device can still answer ILLEGAL_FUNCTION.
    """
    if len(prefix) < 2:
        return None
    if prefix[1] == Function.WRITE_MULTIPLE_REGISTERS:
        return None if len(prefix) < 7 else 9 + prefix[6]
    return 8


def decode_request(frame: bytes) -> Request:
    """Decode a whole request on the device side (BAD_CRC, BAD_FRAME)."""
    if len(frame) < 8:
        raise RobotiqError(f"Request too short: {len(frame)} bytes.", FaultKind.BAD_FRAME)
    if not crc_ok(frame):
        raise RobotiqError(f"Request CRC mismatch ({frame.hex(' ')}).", FaultKind.BAD_CRC)
    slave, function, address, count = _HEADER.unpack_from(frame)
    values: tuple[int, ...] = ()
    if function == Function.WRITE_MULTIPLE_REGISTERS:
        nbytes = frame[6]
        if nbytes != 2 * count or len(frame) != 9 + nbytes:
            raise RobotiqError(
                f"Write request for {count} registers carries byte count {nbytes} in a "
                f"{len(frame)}-byte frame.",
                FaultKind.BAD_FRAME,
            )
        values = struct.unpack_from(f">{count}H", frame, 7)
    return Request(slave, function, address, count, values)


def encode_read_reply(slave: int, function: int, values: Sequence[int]) -> bytes:
    """Device reply carrying ``values`` for a read request."""
    body = bytes([slave, function, 2 * len(values)]) + struct.pack(f">{len(values)}H", *values)
    return append_crc(body)


def encode_write_reply(slave: int, address: int, count: int) -> bytes:
    """Device reply confirming a write of ``count`` registers at ``address``."""
    return append_crc(_HEADER.pack(slave, Function.WRITE_MULTIPLE_REGISTERS, address, count))


def encode_exception(slave: int, function: int, code: ExceptionCode) -> bytes:
    """Device exception reply: function code with bit 7 set, then the exception code."""
    return append_crc(bytes([slave, (function | _EXCEPTION_BIT) & 0xFF, int(code)]))
