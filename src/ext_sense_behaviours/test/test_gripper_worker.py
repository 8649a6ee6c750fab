"""The gripper worker thread: connects, activates, polls, executes, refuses unsafe moves."""

from __future__ import annotations

import contextlib
import threading
import time

import pytest
from hypothesis import given
from hypothesis import strategies as st

from ext_sense_behaviours.gripper_worker import GripperCommandRequest, GripperWorker
from ext_sense_drivers.robotiq import FaultKind, RobotiqClient, RobotiqError, modbus
from ext_sense_sim.devices.robotiq_emulator import (
    GripperModel,
    LinkFault,
    PtyGripper,
    RobotiqEmulator,
    RtuFramer,
)


class Recorder:
    def __init__(self) -> None:
        self.events: list = []
        self.lock = threading.Lock()

    def __call__(self, status, error) -> None:
        with self.lock:
            self.events.append((status, error))

    def wait(self, cond, timeout_s: float = 5.0) -> bool:
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            with self.lock:
                if self.events and cond(*self.events[-1]):
                    return True
            time.sleep(0.01)
        return False


def test_worker_activates_moves_and_survives_faults():
    emulator = RobotiqEmulator(GripperModel(activation_s=0.05, object_position=100))
    with PtyGripper(emulator) as pty:
        rec = Recorder()
        worker = GripperWorker(
            lambda: RobotiqClient.open(pty.path, timeout_s=0.3, retries=1), rec, poll_period_s=0.02
        )
        worker.start()
        try:
            assert rec.wait(lambda s, e: s is not None and s.ready)
            worker.submit(GripperCommandRequest("move", 255, 255, 100))
            assert rec.wait(lambda s, e: s is not None and s.object_held)
            emulator.set_fault(LinkFault.NO_ANSWER)
            assert rec.wait(lambda s, e: e is not None and e.kind == FaultKind.NO_ANSWER)
            worker.submit(GripperCommandRequest("move", 0))  # refused while the link is down
            time.sleep(0.2)
            emulator.set_fault(LinkFault.NONE)
            assert rec.wait(lambda s, e: e is None and s.object_held)
            assert worker.counters.commands_dropped >= 1
            assert emulator.status().position == 100  # the object stayed held
            emulator.set_fault(LinkFault.GRIPPER_FAULT)
            assert rec.wait(lambda s, e: s is not None and s.fault == 0x0E)
            worker.submit(GripperCommandRequest("activate"))
            assert rec.wait(lambda s, e: s is not None and s.ready)
        finally:
            worker.stop()


def test_worker_reports_a_missing_port_and_keeps_trying(tmp_path):
    rec = Recorder()
    worker = GripperWorker(
        lambda: RobotiqClient.open(str(tmp_path / "absent")), rec, reconnect_s=0.05
    )
    worker.start()
    try:
        assert rec.wait(lambda s, e: e is not None and e.kind == FaultKind.SERIAL)
        time.sleep(0.2)
        assert worker.counters.errors >= 2
    finally:
        worker.stop()


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
