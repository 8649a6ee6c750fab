"""Robotiq 2F gripper over Modbus RTU: CRC, frame codec, register map and a pyserial client."""

from ext_sense_drivers.robotiq.client import RobotiqClient
from ext_sense_drivers.robotiq.crc import append_crc, crc16_modbus, crc_ok
from ext_sense_drivers.robotiq.errors import FaultKind, RobotiqError
from ext_sense_drivers.robotiq.registers import (
    ActivationStatus,
    FaultCode,
    GripperCommand,
    GripperStatus,
    ObjectStatus,
)

__all__ = [
    "ActivationStatus",
    "FaultCode",
    "FaultKind",
    "GripperCommand",
    "GripperStatus",
    "ObjectStatus",
    "RobotiqClient",
    "RobotiqError",
    "append_crc",
    "crc16_modbus",
    "crc_ok",
]
