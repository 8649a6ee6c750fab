"""The Robotiq 2F register map (2F-85/140 manual, 4.4-4.5): command and status blocks.

Each block is 6 bytes in 3 big-endian registers. Command at 0x03E8: action (rACT bit 0, rGTO
3, rATR 4, rARD 5), 2 reserved, rPR, rSP, rFR. Status at 0x07D0: status (gACT bit 0, gGTO 3,
gSTA 4-5, gOBJ 6-7), reserved, fault (gFLT low nibble, kFLT high), gPR, gPO, gCU.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from enum import IntEnum

from ext_sense_drivers.robotiq.errors import FaultKind, RobotiqError

DEFAULT_SLAVE_ID = 0x09
DEFAULT_BAUDRATE = 115200
COMMAND_REGISTER = 0x03E8
STATUS_REGISTER = 0x07D0
STATUS_REGISTER_COUNT = 3
POSITION_OPEN = 0x00
POSITION_CLOSED = 0xFF


class ActivationStatus(IntEnum):
    """gSTA: where the activation sequence is."""

    RESET = 0
    IN_PROGRESS = 1
    NOT_USED = 2
    COMPLETED = 3


class ObjectStatus(IntEnum):
    """gOBJ: motion and object detection (only meaningful while gGTO = 1)."""

    MOVING = 0
    """Fingers moving towards the requested position; no object detected."""
    DETECTED_OPENING = 1
    """Fingers stopped by contact while opening."""
    DETECTED_CLOSING = 2
    """Fingers stopped by contact while closing: an object is held."""
    AT_POSITION = 3
    """Fingers at the requested position; no object detected (or object lost)."""


class FaultCode(IntEnum):
    """gFLT values from the manual; 0x05/0x07 are command-order faults, 0x0A and up are major."""

    NONE = 0x00
    ACTION_DELAYED = 0x05
    ACTIVATION_BIT_NOT_SET = 0x07
    OVER_TEMPERATURE = 0x08
    NO_COMMUNICATION = 0x09
    UNDER_VOLTAGE = 0x0A
    AUTO_RELEASE_IN_PROGRESS = 0x0B
    INTERNAL_FAULT = 0x0C
    ACTIVATION_FAULT = 0x0D
    OVERCURRENT = 0x0E
    AUTO_RELEASE_COMPLETED = 0x0F


def fault_name(code: int) -> str:
    """Readable name of a gFLT value (``"0x03 (unknown)"`` for codes the manual does not list)."""
    if code in FaultCode._value2member_map_:
        return f"{code:#04x} ({FaultCode(code).name})"
    return f"{code:#04x} (unknown)"


def _byte(name: str, value: int) -> int:
    if not isinstance(value, int) or isinstance(value, bool) or not 0 <= value <= 255:
        raise RobotiqError(
            f"The '{name}' field must be an int in [0, 255]. Got {value!r} instead.",
            FaultKind.BAD_ARGUMENT,
        )
    return value


def _bytes_of(registers: Sequence[int], name: str) -> bytes:
    if len(registers) < 3:
        raise RobotiqError(
            f"The '{name}' block needs 3 registers. Got {len(registers)} instead.",
            FaultKind.BAD_FRAME,
        )
    return b"".join(int(r).to_bytes(2, "big") for r in registers[:3])


@dataclass(frozen=True)
class GripperCommand:
    """What the robot asks of the gripper (the command registers).

    The fields in order: rACT (0 resets, a 0 -> 1 edge activates), rGTO, rATR, rARD (1 = open),
    rPR (0 open .. 255 closed), rSP and rFR (0 .. 255).
    """

    activate: bool = True
    go_to: bool = False
    auto_release: bool = False
    auto_release_open: bool = False
    position: int = 0
    speed: int = 255
    force: int = 255

    def __post_init__(self) -> None:
        for name in ("position", "speed", "force"):
            _byte(name, getattr(self, name))

    def to_registers(self) -> tuple[int, int, int]:
        """The three register values to write at :data:`COMMAND_REGISTER`."""
        action = (
            int(self.activate)
            | int(self.go_to) << 3
            | int(self.auto_release) << 4
            | int(self.auto_release_open) << 5
        )
        return (action << 8, self.position, self.speed << 8 | self.force)

    @classmethod
    def from_registers(cls, registers: Sequence[int]) -> GripperCommand:
        """Decode the command block (the device side reads what the robot wrote)."""
        b = _bytes_of(registers, "command")
        return cls(
            activate=bool(b[0] & 0x01),
            go_to=bool(b[0] & 0x08),
            auto_release=bool(b[0] & 0x10),
            auto_release_open=bool(b[0] & 0x20),
            position=b[3],
            speed=b[4],
            force=b[5],
        )


@dataclass(frozen=True)
class GripperStatus:
    """What the gripper reports (the status registers).

    The fields in order: gACT, gGTO, gSTA, gOBJ, gFLT (:class:`FaultCode`), kFLT, gPR, gPO
    (0 open .. 255 closed) and gCU (about 10 mA per count).
    """

    activated: bool = False
    go_to: bool = False
    activation: ActivationStatus = ActivationStatus.RESET
    object: ObjectStatus = ObjectStatus.MOVING
    fault: int = 0
    controller_fault: int = 0
    position_request: int = 0
    position: int = 0
    current: int = 0

    @property
    def ready(self) -> bool:
        """Activated, activation complete and no fault."""
        return self.activated and self.activation == ActivationStatus.COMPLETED and not self.fault

    @property
    def object_held(self) -> bool:
        """The fingers stopped on an object while closing."""
        return self.go_to and self.object == ObjectStatus.DETECTED_CLOSING

    @property
    def motion_done(self) -> bool:
        """The last go-to has ended (at its position or on an object)."""
        return self.go_to and self.object != ObjectStatus.MOVING

    def to_registers(self) -> tuple[int, int, int]:
        """The three register values a device answers at :data:`STATUS_REGISTER`."""
        status = (
            int(self.activated)
            | int(self.go_to) << 3
            | int(self.activation) << 4
            | int(self.object) << 6
        )
        fault_byte = (self.controller_fault & 0x0F) << 4 | (self.fault & 0x0F)
        return (
            status << 8,
            fault_byte << 8 | self.position_request,
            self.position << 8 | self.current,
        )

    @classmethod
    def from_registers(cls, registers: Sequence[int]) -> GripperStatus:
        """Decode the status block from the first three registers read at 0x07D0."""
        b = _bytes_of(registers, "status")
        return cls(
            activated=bool(b[0] & 0x01),
            go_to=bool(b[0] & 0x08),
            activation=ActivationStatus((b[0] >> 4) & 0x03),
            object=ObjectStatus((b[0] >> 6) & 0x03),
            fault=b[2] & 0x0F,
            controller_fault=b[2] >> 4,
            position_request=b[3],
            position=b[4],
            current=b[5],
        )
