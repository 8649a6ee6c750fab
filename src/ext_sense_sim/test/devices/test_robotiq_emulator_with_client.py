"""Robotiq client against the emulator over an in-memory link: retries, timeouts, faults."""

from __future__ import annotations

import contextlib

import pytest
from hypothesis import given
from hypothesis import strategies as st

from ext_sense_drivers.robotiq import (
    ActivationStatus,
    FaultCode,
    FaultKind,
    ObjectStatus,
    RobotiqClient,
    RobotiqError,
    modbus,
)
from ext_sense_sim.devices.robotiq_emulator import (
    GripperModel,
    LinkFault,
    RobotiqEmulator,
    RtuFramer,
)


class FakeClock:
    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        return self.t

    def sleep(self, dt: float) -> None:
        self.t += dt


class LoopbackSerial:
    """A serial port whose far end is an emulator; each exchange costs 2 ms of fake time."""

    def __init__(self, emulator: RobotiqEmulator, clock: FakeClock) -> None:
        self.emulator, self.clock = emulator, clock
        self.timeout: float | None = 0.5
        self._rx = b""
        self.written: list[bytes] = []

    def write(self, data: bytes) -> int:
        self.written.append(bytes(data))
        self.clock.t += 0.002
        reply = self.emulator.handle(bytes(data))
        if reply is not None:
            self._rx += reply
        return len(data)

    def read(self, size: int = 1) -> bytes:
        if not self._rx:
            self.clock.t += self.timeout or 0.0  # a real port blocks for the timeout
            return b""
        out, self._rx = self._rx[:size], self._rx[size:]
        return out

    def reset_input_buffer(self) -> None:
        self._rx = b""

    def close(self) -> None:
        pass


def make(object_position=None, retries=2):
    clock = FakeClock()
    emulator = RobotiqEmulator(
        GripperModel(activation_s=0.3, object_position=object_position), clock=clock
    )
    port = LoopbackSerial(emulator, clock)
    client = RobotiqClient(port, timeout_s=0.1, retries=retries, sleep=clock.sleep, clock=clock)
    return client, emulator, port, clock


def test_activate_close_on_object_and_open():
    client, _emulator, _, _ = make(object_position=140)
    status = client.activate()
    assert status.ready
    assert status.activation == ActivationStatus.COMPLETED
    client.close_fingers()
    status = client.wait_for_motion()
    assert status.object == ObjectStatus.DETECTED_CLOSING
    assert status.position == 140
    assert status.current > 0
    client.open_fingers()
    status = client.wait_for_motion()
    assert status.object == ObjectStatus.AT_POSITION
    assert status.position == 0
    assert client.counters.retries == 0


def test_close_without_object_reaches_position():
    client, _, _, _ = make()
    client.activate()
    client.move(200, speed=0)
    status = client.wait_for_motion()
    assert status.object == ObjectStatus.AT_POSITION
    assert status.position == 200


def test_no_answer_retries_then_raises():
    client, emulator, _port, _ = make(retries=2)
    client.activate()
    emulator.set_fault(LinkFault.NO_ANSWER)
    with pytest.raises(RobotiqError, match=r"No answer from Robotiq slave 9 .* 3 attempts") as info:
        client.read_status()
    assert info.value.kind == FaultKind.NO_ANSWER
    assert client.counters.timeouts == 3
    assert client.counters.retries == 2
    assert emulator.counters.ignored_no_answer == 3


def test_bad_crc_retries_then_raises():
    client, emulator, _, _ = make(retries=1)
    client.activate()
    emulator.set_fault(LinkFault.BAD_CRC)
    with pytest.raises(RobotiqError, match="CRC mismatch") as info:
        client.read_status()
    assert info.value.kind == FaultKind.BAD_CRC
    assert client.counters.crc_errors == 2


def test_bad_crc_on_write_loses_only_the_acknowledgement():
    client, emulator, _, _ = make(retries=0)
    client.activate()
    emulator.set_fault(LinkFault.BAD_CRC_ON_WRITE)
    assert client.read_status().ready  # reads still answer cleanly
    with pytest.raises(RobotiqError, match="CRC mismatch"):
        client.move(position=200, speed=255, force=10)
    assert emulator.status().position_request == 200  # the write itself was carried out


def test_link_recovers_after_a_transient_fault():
    client, emulator, _port, _ = make(retries=2)
    client.activate()
    emulator.set_fault(LinkFault.BAD_CRC)
    original = emulator.handle
    calls = {"n": 0}

    def flaky(frame):
        calls["n"] += 1
        if calls["n"] == 2:
            emulator.set_fault(LinkFault.NONE)
        return original(frame)

    emulator.handle = flaky  # type: ignore[method-assign]
    status = client.read_status()
    assert status.ready
    assert client.counters.crc_errors == 1
    assert client.counters.retries == 1


def test_gripper_fault_is_raised_and_cleared_by_reset():
    client, emulator, _, _ = make(object_position=100)
    client.activate()
    emulator.set_fault(LinkFault.GRIPPER_FAULT, FaultCode.OVERCURRENT)
    status = client.read_status()
    assert status.fault == FaultCode.OVERCURRENT
    assert not status.ready
    with pytest.raises(RobotiqError, match=r"gFLT=0x0e \(OVERCURRENT\)") as info:
        client.read_status(raise_on_fault=True)
    assert info.value.kind == FaultKind.GRIPPER_FAULT
    # A move is refused while the major fault stands: the fingers do not move.
    client.close_fingers()
    assert client.read_status().position == 0
    status = client.activate()  # reset (rACT=0) then activate clears it
    assert status.ready
    assert status.fault == 0


def test_exception_reply_is_not_retried():
    client, _, port, _ = make()
    with pytest.raises(RobotiqError, match="ILLEGAL_DATA_ADDRESS") as info:
        client.read_registers(0x1000, 2)
    assert info.value.kind == FaultKind.EXCEPTION_REPLY
    assert len(port.written) == 1


def test_action_before_activation_is_a_fault():
    client, _, _, _ = make()
    client.move(255)
    status = client.read_status()
    assert (
        status.fault == FaultCode.ACTIVATION_BIT_NOT_SET or status.fault == FaultCode.ACTION_DELAYED
    )


def test_activation_timeout():
    client, emulator, _, _ = make()
    emulator.model.activation_s = 100.0
    with pytest.raises(RobotiqError, match=r"Activation did not complete within 1\.0 s") as info:
        client.activate(timeout_s=1.0)
    assert info.value.kind == FaultKind.ACTIVATION


def test_client_arguments_checked():
    clock = FakeClock()
    port = LoopbackSerial(RobotiqEmulator(clock=clock), clock)
    with pytest.raises(RobotiqError, match="'timeout_s' parameter must be > 0"):
        RobotiqClient(port, timeout_s=0)
    with pytest.raises(RobotiqError, match="'retries' parameter"):
        RobotiqClient(port, retries=-1)


def test_framer_splits_and_drops_partial_frames():
    from ext_sense_drivers.robotiq import modbus

    framer = RtuFramer(gap_s=0.05)
    read = modbus.encode_read_request(9, 0x07D0, 3)
    write = modbus.encode_write_request(9, 0x03E8, [0x0100, 0, 0])
    assert framer.feed(read[:3], 0.0) == []
    assert framer.feed(read[3:] + write[:5], 0.001) == [read]
    assert framer.feed(write[5:], 0.002) == [write]
    assert framer.feed(read[:4], 0.010) == []
    assert framer.feed(read, 0.200) == [read]  # silence dropped the stale half frame
    assert framer.dropped_bytes == 4


def test_emulator_silent_on_other_slave_and_bad_crc():
    from ext_sense_drivers.robotiq import modbus

    emulator = RobotiqEmulator()
    assert emulator.handle(modbus.encode_read_request(7, 0x07D0, 3)) is None
    bad = bytearray(modbus.encode_read_request(9, 0x07D0, 3))
    bad[-1] ^= 0xFF
    assert emulator.handle(bytes(bad)) is None
    assert emulator.counters.other_slave == 1
    assert emulator.counters.bad_crc_requests == 1


def test_partial_reply_is_no_answer_not_crc():
    client, emulator, _, _ = make(retries=0)
    client.activate()
    original = emulator.handle
    emulator.handle = lambda frame: original(frame)[:7]  # type: ignore[method-assign]
    with pytest.raises(RobotiqError, match=r"Incomplete answer .* 7 of 11 bytes") as info:
        client.read_status()
    assert info.value.kind == FaultKind.NO_ANSWER
    assert client.counters.crc_errors == 0


def test_object_taken_from_the_hand_lets_the_fingers_close():
    client, emulator, _, _ = make(object_position=120)
    client.activate()
    client.close_fingers()
    assert client.wait_for_motion().object_held
    client.close_fingers()  # the same command again changes nothing
    assert client.read_status().object_held
    emulator.set_object(None)  # the person takes the object
    status = client.wait_for_motion()
    assert status.object == ObjectStatus.AT_POSITION
    assert status.position == 255


@given(st.lists(st.integers(0, 2), min_size=1, max_size=8), st.data())
def test_framer_reassembles_any_split(kinds, data):
    frames = []
    for k in kinds:
        if k == 0:
            frames.append(modbus.encode_read_request(9, 0x07D0, 3))
        elif k == 1:
            frames.append(modbus.encode_write_request(9, 0x03E8, [0x0900, 0x00FF, 0xFF64]))
        else:
            frames.append(
                modbus.encode_read_request(9, 0x03E8, 1, modbus.Function.READ_INPUT_REGISTERS)
            )
    stream = b"".join(frames)
    cuts = sorted(data.draw(st.lists(st.integers(0, len(stream)), max_size=10)))
    framer, out, prev = RtuFramer(gap_s=1.0), [], 0
    for cut in [*cuts, len(stream)]:
        out += framer.feed(stream[prev:cut], 0.0)
        prev = cut
    assert out == frames


@given(st.binary(max_size=40))
def test_decoders_only_raise_robotiq_errors(data):
    for decode in (
        lambda f: modbus.decode_read_reply(f, 9, 3),
        lambda f: modbus.decode_write_reply(f, 9, 0x03E8, 3),
        modbus.decode_request,
    ):
        with contextlib.suppress(RobotiqError):
            decode(data)
    emulator = RobotiqEmulator()
    reply = emulator.handle(data)
    assert reply is None or modbus.crc_ok(reply)


def test_emulator_answers_exceptions():
    emulator = RobotiqEmulator()
    reply = emulator.handle(modbus.append_crc(bytes([9, 0x2B, 0, 0, 0, 1])))
    with pytest.raises(RobotiqError, match="ILLEGAL_FUNCTION"):
        modbus.decode_read_reply(reply, 9, 1, 0x2B)
    reply = emulator.handle(modbus.encode_write_request(9, 0x0100, [1]))
    with pytest.raises(RobotiqError, match="ILLEGAL_DATA_ADDRESS"):
        modbus.decode_write_reply(reply, 9, 0x0100, 1)
