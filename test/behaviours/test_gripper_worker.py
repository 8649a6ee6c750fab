"""The gripper worker thread: connects, activates, polls, executes, refuses unsafe moves."""

from __future__ import annotations

import threading
import time

from ext_sense_behaviours.gripper_worker import GripperCommandRequest, GripperWorker
from ext_sense_drivers.robotiq import FaultKind, RobotiqClient
from ext_sense_sim.devices.robotiq_emulator import (
    GripperModel,
    LinkFault,
    PtyGripper,
    RobotiqEmulator,
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
