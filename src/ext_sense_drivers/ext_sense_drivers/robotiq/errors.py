"""The one exception type of the Robotiq Modbus RTU codec and client."""

from __future__ import annotations

from enum import IntEnum


class FaultKind(IntEnum):
    """Why a Robotiq exchange failed; lets callers pick a safe reaction without parsing text."""

    BAD_ARGUMENT = 0
    """A caller passed a value outside its range (slave id, register, byte)."""
    BAD_FRAME = 1
    """A frame is too short, has the wrong slave, function or length."""
    BAD_CRC = 2
    """The CRC-16/Modbus of a frame does not match its contents."""
    NO_ANSWER = 3
    """The gripper did not answer within the timeout (after every retry)."""
    EXCEPTION_REPLY = 4
    """The gripper answered with a Modbus exception (function code | 0x80)."""
    GRIPPER_FAULT = 5
    """The gripper reports a fault in its gFLT status field."""
    SERIAL = 6
    """The serial port could not be opened, or vanished."""
    ACTIVATION = 7
    """Activation did not complete within its timeout."""


class RobotiqError(Exception):
    """A Robotiq frame, exchange or gripper state is not what was expected (see ``kind``)."""

    def __init__(self, message: str, kind: FaultKind = FaultKind.BAD_FRAME) -> None:
        super().__init__(message)
        self.kind = kind
