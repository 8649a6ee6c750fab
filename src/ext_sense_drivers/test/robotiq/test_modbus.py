"""Robotiq Modbus RTU codec: CRC, frames byte for byte, register map."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from ext_sense_drivers.robotiq import (
    ActivationStatus,
    FaultKind,
    GripperCommand,
    GripperStatus,
    ObjectStatus,
    RobotiqError,
    append_crc,
    crc16_modbus,
    crc_ok,
    modbus,
)


def crc_bitwise(data: bytes) -> int:
    """Reference CRC-16/Modbus straight from its definition (no table)."""
    crc = 0xFFFF
    for byte in data:
        crc ^= byte
        for _ in range(8):
            lsb = crc & 1
            crc >>= 1
            if lsb:
                crc ^= 0xA001
    return crc


def test_crc_catalogue_check_value():
    # CRC-16/MODBUS check value from the CRC catalogue: "123456789" -> 0x4B37.
    assert crc16_modbus(b"123456789") == 0x4B37


@given(st.binary(max_size=64))
def test_crc_table_matches_bitwise_definition(data):
    assert crc16_modbus(data) == crc_bitwise(data)
    assert crc_ok(append_crc(data)) == (len(data) >= 1)


# Frames written out by hand from the Robotiq 2F manual's register map (slave 9); the CRC bytes
# were computed by hand with the bitwise definition above (low byte first) and agree with the
# example frames printed in the Robotiq 2F-85/140 manual.
MANUAL_FRAMES = [
    # read 1 status register at 0x07D0
    (modbus.encode_read_request(9, 0x07D0, 1), "09 03 07 d0 00 01 85 cf"),
    # read 3 status registers at 0x07D0 (the whole status block)
    (modbus.encode_read_request(9, 0x07D0, 3), "09 03 07 d0 00 03 04 0e"),
    # clear rACT (reset)
    (
        modbus.encode_write_request(9, 0x03E8, [0x0000, 0x0000, 0x0000]),
        "09 10 03 e8 00 03 06 00 00 00 00 00 00 73 30",
    ),
    # set rACT (activate)
    (
        modbus.encode_write_request(9, 0x03E8, [0x0100, 0x0000, 0x0000]),
        "09 10 03 e8 00 03 06 01 00 00 00 00 00 72 e1",
    ),
    # rACT + rGTO, close fully at full speed and force
    (
        modbus.encode_write_request(
            9,
            0x03E8,
            GripperCommand(
                activate=True, go_to=True, position=255, speed=255, force=255
            ).to_registers(),
        ),
        "09 10 03 e8 00 03 06 09 00 00 ff ff ff 42 29",
    ),
    # the gripper's answer to any 3-register write at 0x03E8
    (modbus.encode_write_reply(9, 0x03E8, 3), "09 10 03 e8 00 03 01 30"),
    # exception reply: illegal data address to a read
    (
        modbus.encode_exception(9, 0x03, modbus.ExceptionCode.ILLEGAL_DATA_ADDRESS),
        "09 83 02 " + crc_bitwise(bytes([9, 0x83, 2])).to_bytes(2, "little").hex(" "),
    ),
]


@pytest.mark.parametrize(("frame", "expected"), MANUAL_FRAMES)
def test_frames_byte_for_byte(frame, expected):
    assert frame.hex(" ") == expected
    assert crc_bitwise(frame[:-2]) == int.from_bytes(frame[-2:], "little")


def test_status_reply_decodes_manual_example():
    # Status after activation, fingers closed on an object at gPO=0xBD: gOBJ=2, gSTA=3,
    # gGTO=1, gACT=1 -> status byte 0b10111001 = 0xB9.
    raw = bytes.fromhex("09 03 06 b9 00 00 ff bd 00")
    frame = raw + crc_bitwise(raw).to_bytes(2, "little")
    regs = modbus.decode_read_reply(frame, 9, 3)
    status = GripperStatus.from_registers(regs)
    assert status.activated
    assert status.go_to
    assert status.activation == ActivationStatus.COMPLETED
    assert status.object == ObjectStatus.DETECTED_CLOSING
    assert status.object_held
    assert status.motion_done
    assert status.ready
    assert (status.position_request, status.position, status.current) == (0xFF, 0xBD, 0)
    assert status.to_registers() == regs


def test_bad_crc_is_reported():
    frame = bytearray(modbus.encode_write_reply(9, 0x03E8, 3))
    frame[-1] ^= 0x01
    with pytest.raises(RobotiqError, match="CRC mismatch") as info:
        modbus.decode_write_reply(bytes(frame), 9, 0x03E8, 3)
    assert info.value.kind == FaultKind.BAD_CRC


def test_exception_reply_is_reported():
    frame = modbus.encode_exception(9, 0x10, modbus.ExceptionCode.ILLEGAL_FUNCTION)
    with pytest.raises(RobotiqError, match="ILLEGAL_FUNCTION") as info:
        modbus.decode_write_reply(frame, 9, 0x03E8, 3)
    assert info.value.kind == FaultKind.EXCEPTION_REPLY


@pytest.mark.parametrize(
    ("frame", "match"),
    [
        (b"\x09\x03", "too short"),
        (modbus.encode_read_reply(8, 3, [0, 0, 0]), "slave 8"),
        (modbus.encode_read_reply(9, 4, [0, 0, 0]), "function 0x04"),
        (modbus.encode_read_reply(9, 3, [0, 0]), "3 registers"),
    ],
)
def test_malformed_read_replies(frame, match):
    with pytest.raises(RobotiqError, match=match):
        modbus.decode_read_reply(frame, 9, 3)


def test_write_echo_mismatch():
    with pytest.raises(RobotiqError, match="echoes address"):
        modbus.decode_write_reply(modbus.encode_write_reply(9, 0x03E9, 3), 9, 0x03E8, 3)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"slave": 0, "address": 0, "count": 1}, "'slave'"),
        ({"slave": 9, "address": 0x10000, "count": 1}, "'address'"),
        ({"slave": 9, "address": 0, "count": 126}, "'count'"),
    ],
)
def test_request_arguments_checked(kwargs, match):
    with pytest.raises(RobotiqError, match=match):
        modbus.encode_read_request(**kwargs)


def test_command_byte_range_checked():
    with pytest.raises(RobotiqError, match="'position' field must be an int in"):
        GripperCommand(position=256)


@given(
    st.booleans(),
    st.booleans(),
    st.booleans(),
    st.booleans(),
    st.integers(0, 255),
    st.integers(0, 255),
    st.integers(0, 255),
)
def test_command_round_trip(act, gto, atr, ard, pos, speed, force):
    cmd = GripperCommand(act, gto, atr, ard, pos, speed, force)
    assert GripperCommand.from_registers(cmd.to_registers()) == cmd
    frame = modbus.encode_write_request(9, 0x03E8, cmd.to_registers())
    request = modbus.decode_request(frame)
    assert request.values == cmd.to_registers()
    assert modbus.request_length(frame[:7]) == len(frame)


@pytest.mark.parametrize("activation", list(ActivationStatus))
@pytest.mark.parametrize("obj", list(ObjectStatus))
def test_status_round_trip_every_enum(activation, obj):
    status = GripperStatus(True, True, activation, obj, 0x0E, 0x3, 17, 200, 42)
    assert GripperStatus.from_registers(status.to_registers()) == status


def test_request_side_rejects_bad_crc():
    frame = bytearray(modbus.encode_read_request(9, 0x07D0, 3))
    frame[3] ^= 0x40
    with pytest.raises(RobotiqError, match="CRC mismatch") as info:
        modbus.decode_request(bytes(frame))
    assert info.value.kind == FaultKind.BAD_CRC
