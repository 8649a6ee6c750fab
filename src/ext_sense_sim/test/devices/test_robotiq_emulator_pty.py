"""The emulated gripper on a pty, spoken to as raw bytes by a plain Modbus RTU client.

The client below knows nothing of ext_sense: it writes the byte strings of the Robotiq 2F
manual's example sequence (activate, poll status, close, read object status) and compares the
answers byte for byte, exactly as a script written against the real gripper would.
"""

from __future__ import annotations

import os
import select
import subprocess
import sys
import termios
import time
import tty

import pytest

from ext_sense_drivers.robotiq import FaultKind, RobotiqClient, RobotiqError
from ext_sense_sim.devices.robotiq_emulator import (
    GripperModel,
    LinkFault,
    PtyGripper,
    RobotiqEmulator,
)

H = bytes.fromhex
RESET = H("09 10 03 E8 00 03 06 00 00 00 00 00 00 73 30")
ACTIVATE = H("09 10 03 E8 00 03 06 01 00 00 00 00 00 72 E1")
WRITE_ACK = H("09 10 03 E8 00 03 01 30")
READ_STATUS = H("09 03 07 D0 00 01 85 CF")
ACTIVATED = H("09 03 02 31 00 4C 15")  # gACT=1, gSTA=3
CLOSE = H("09 10 03 E8 00 03 06 09 00 00 FF FF FF 42 29")
OBJECT_CLOSING = H("09 03 02 B9 00 2A 15")  # gOBJ=2: stopped on an object while closing
NO_OBJECT = H("09 03 02 F9 00 1B D5")  # gOBJ=3: at position, no object
READ_ALL = H("09 03 07 D0 00 03 04 0E")


class PlainRtu:
    """A bare Modbus RTU exchange on a tty: write bytes, read until the expected length."""

    def __init__(self, path: str) -> None:
        self.fd = os.open(path, os.O_RDWR | os.O_NOCTTY)
        tty.setraw(self.fd)
        termios.tcflush(self.fd, termios.TCIOFLUSH)

    def exchange(self, request: bytes, reply_len: int, timeout_s: float = 0.5) -> bytes:
        os.write(self.fd, request)
        reply, deadline = b"", time.monotonic() + timeout_s
        while len(reply) < reply_len:
            left = deadline - time.monotonic()
            if left <= 0 or not select.select([self.fd], [], [], left)[0]:
                break
            reply += os.read(self.fd, reply_len - len(reply))
        return reply

    def poll_until(self, request: bytes, expected: bytes, timeout_s: float = 3.0) -> bytes:
        deadline, reply = time.monotonic() + timeout_s, b""
        while time.monotonic() < deadline:
            reply = self.exchange(request, len(expected))
            if reply == expected:
                return reply
            time.sleep(0.02)
        return reply

    def close(self) -> None:
        os.close(self.fd)


def manual_sequence(path: str, object_present: bool) -> None:
    rtu = PlainRtu(path)
    try:
        assert rtu.exchange(RESET, 8) == WRITE_ACK
        assert rtu.exchange(ACTIVATE, 8) == WRITE_ACK
        assert rtu.poll_until(READ_STATUS, ACTIVATED) == ACTIVATED
        assert rtu.exchange(CLOSE, 8) == WRITE_ACK
        expected = OBJECT_CLOSING if object_present else NO_OBJECT
        assert rtu.poll_until(READ_STATUS, expected) == expected
        full = rtu.exchange(READ_ALL, 11)
        assert full[:4] == H("09 03 06") + expected[3:4]
        assert full[6] == 0xFF  # gPR echoes the close request
        assert (full[7] < 0xFF) == object_present  # gPO stopped short on the object
    finally:
        rtu.close()


@pytest.mark.parametrize("object_position", [None, 120])
def test_plain_client_follows_the_manual(object_position):
    emulator = RobotiqEmulator(GripperModel(activation_s=0.2, object_position=object_position))
    with PtyGripper(emulator) as pty:
        manual_sequence(pty.path, object_present=object_position is not None)


def test_faults_over_the_pty_give_clear_errors():
    with PtyGripper(RobotiqEmulator(GripperModel(activation_s=0.05))) as pty:
        client = RobotiqClient.open(pty.path, timeout_s=0.5, retries=1)
        try:
            assert client.activate().ready
            pty.emulator.set_fault(LinkFault.NO_ANSWER)
            with pytest.raises(RobotiqError, match="No answer") as info:
                client.read_status()
            assert info.value.kind == FaultKind.NO_ANSWER
            pty.emulator.set_fault(LinkFault.BAD_CRC)
            with pytest.raises(RobotiqError, match="CRC mismatch"):
                client.read_status()
            pty.emulator.set_fault(LinkFault.NONE)
            assert client.read_status().ready  # link back: no stale bytes confuse the client
        finally:
            client.close()


@pytest.mark.timeout(30)
def test_cli_serve_robotiq_prints_pty_path():
    proc = subprocess.Popen(
        [sys.executable, "-m", "ext_sense.cli", "sim", "serve", "robotiq"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        ready, _, _ = select.select([proc.stdout], [], [], 20.0)
        assert ready, "ext-sense sim serve robotiq printed no path"
        path = proc.stdout.readline().strip()
        assert path.startswith("/dev/pts/"), path
        manual_sequence(path, object_present=True)  # the CLI puts an object in the hand
    finally:
        proc.terminate()
        try:
            assert proc.wait(timeout=5) == 0
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
