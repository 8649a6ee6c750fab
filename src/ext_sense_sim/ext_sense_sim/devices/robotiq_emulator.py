"""A Robotiq 2F gripper emulator that answers Modbus RTU on a pty like the real one.

:class:`GripperModel` behind :class:`RobotiqEmulator` (the Modbus server, with injectable link
and gripper faults); :class:`RtuFramer` cuts requests; :class:`PtyGripper` serves on a pty.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import select
import signal
import sys
import threading
import time
import tty
from collections.abc import Callable
from dataclasses import dataclass
from enum import IntEnum

from ext_sense_drivers.robotiq import modbus
from ext_sense_drivers.robotiq.errors import RobotiqError
from ext_sense_drivers.robotiq.registers import (
    COMMAND_REGISTER,
    DEFAULT_SLAVE_ID,
    STATUS_REGISTER,
    ActivationStatus,
    FaultCode,
    GripperCommand,
    GripperStatus,
    ObjectStatus,
)

DEMO_OBJECT_POSITION = 128
"""Where ``ext-sense sim serve robotiq`` puts an object between the fingers by default."""

REGISTER_BLOCK = 8
"""Registers answered from each base address (3 used, the reserved rest read as 0)."""


class LinkFault(IntEnum):
    """Faults the emulator can inject on the link or in the gripper."""

    NONE = 0
    NO_ANSWER = 1
    """Requests are read and ignored, like an unplugged or unpowered gripper."""
    BAD_CRC = 2
    """Replies go out with a corrupted CRC, like line noise."""
    GRIPPER_FAULT = 3
    """The gripper raises gFLT (default 0x0E overcurrent) and stops until reset."""
    BAD_CRC_ON_WRITE = 4
    """Only replies to register writes are corrupted: the command is carried out but its
    acknowledgement is lost, while status reads still answer cleanly."""


@dataclass
class GripperModel:
    """The gripper's behaviour behind its registers.

    ``object_position`` (0..255, ``None``: no object) stops the closing fingers; the finger
    speed runs from ``min_speed_cps`` (rSP 0) to ``max_speed_cps`` (rSP 255) counts per second.
    """

    activation_s: float = 0.3
    object_position: int | None = None
    min_speed_cps: float = 100.0
    max_speed_cps: float = 1500.0

    def __post_init__(self) -> None:
        self.command = GripperCommand(activate=False, speed=0, force=0)
        self.activation = ActivationStatus.RESET
        self.position = 0.0
        self.object = ObjectStatus.MOVING
        self.fault = FaultCode.NONE
        self._activation_end: float | None = None
        self._last_t: float | None = None
        self._moving = False

    def write(self, command: GripperCommand, now: float) -> None:
        """Apply what the robot wrote to the command registers at time ``now`` (seconds)."""
        self.advance(now)
        previous = self.command
        self.command = command
        if not command.activate:
            # Reset: stop, forget activation, clear faults (the manual's way out of a fault).
            self.activation = ActivationStatus.RESET
            self._activation_end = None
            self._moving = False
            self.object = ObjectStatus.MOVING
            self.fault = FaultCode.ACTIVATION_BIT_NOT_SET if command.go_to else FaultCode.NONE
            return
        if not previous.activate and self.fault == FaultCode.NONE:
            self.activation = ActivationStatus.IN_PROGRESS
            self._activation_end = now + self.activation_s
        if command.go_to and self.fault < FaultCode.UNDER_VOLTAGE:
            if self.activation != ActivationStatus.COMPLETED:
                self.fault = FaultCode.ACTION_DELAYED
            elif not previous.go_to or command.position != previous.position:
                self._start_motion()
        if not command.go_to:
            self._moving = False

    def inject_fault(self, code: FaultCode = FaultCode.OVERCURRENT) -> None:
        """Raise a gFLT fault now: the fingers stop where they are until a reset."""
        self.fault = code
        self._moving = False

    def _start_motion(self) -> None:
        if self.fault and self.fault != FaultCode.ACTION_DELAYED:
            return
        self.fault = FaultCode.NONE
        self._moving = True
        self.object = ObjectStatus.MOVING

    def advance(self, now: float) -> None:
        """Move the model forward to time ``now`` (seconds, monotonic)."""
        dt = 0.0 if self._last_t is None else max(0.0, now - self._last_t)
        self._last_t = now
        if (
            self.activation == ActivationStatus.IN_PROGRESS
            and self._activation_end is not None
            and now >= self._activation_end
        ):
            self.activation = ActivationStatus.COMPLETED
            self.position = 0.0
            if self.command.go_to and self.fault == FaultCode.ACTION_DELAYED:
                self._start_motion()
        if (
            self.object == ObjectStatus.DETECTED_CLOSING
            and self.command.go_to
            and self.fault == FaultCode.NONE
            and (self.object_position is None or self.object_position > self.position)
        ):
            # the object was pulled out of the hand: the fingers carry on closing
            self._moving, self.object = True, ObjectStatus.MOVING
        if not self._moving or dt == 0.0:
            return
        speed = self.min_speed_cps + (self.max_speed_cps - self.min_speed_cps) * (
            self.command.speed / 255.0
        )
        target = float(self.command.position)
        step = speed * dt
        if target > self.position:  # closing
            new = min(target, self.position + step)
            obj = self.object_position
            if obj is not None and self.position <= obj <= new and obj < target:
                self.position = float(obj)
                self.object = ObjectStatus.DETECTED_CLOSING
                self._moving = False
                return
            self.position = new
        else:
            self.position = max(target, self.position - step)
        if self.position == target:
            self.object = ObjectStatus.AT_POSITION
            self._moving = False

    def status(self) -> GripperStatus:
        """The status registers as they read now."""
        go_to = self.command.activate and self.command.go_to
        holding = self.object == ObjectStatus.DETECTED_CLOSING
        current = 20 if self._moving else 0
        if holding and not self._moving:
            current = max(1, self.command.force // 4)
        return GripperStatus(
            activated=self.command.activate,
            go_to=go_to,
            activation=self.activation,
            object=self.object if go_to else ObjectStatus.MOVING,
            fault=int(self.fault),
            position_request=self.command.position,
            position=round(self.position),
            current=current,
        )


@dataclass
class EmulatorCounters:
    """What the emulator saw."""

    requests: int = 0
    replies: int = 0
    bad_crc_requests: int = 0
    other_slave: int = 0
    exceptions: int = 0
    ignored_no_answer: int = 0
    corrupted_replies: int = 0


class RobotiqEmulator:
    """The Modbus RTU face of a :class:`GripperModel`, on a monotonic seconds ``clock``."""

    def __init__(
        self,
        model: GripperModel | None = None,
        slave: int = DEFAULT_SLAVE_ID,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.model = model or GripperModel()
        self.slave = slave
        self.clock = clock
        self.link_fault = LinkFault.NONE
        self.counters = EmulatorCounters()
        self._command_regs = list(self.model.command.to_registers()) + [0] * (REGISTER_BLOCK - 3)
        self._lock = threading.Lock()

    def set_fault(self, fault: LinkFault, code: FaultCode = FaultCode.OVERCURRENT) -> None:
        """Inject a fault (``LinkFault.NONE`` clears the link faults; gFLT clears on reset)."""
        with self._lock:
            self.link_fault = fault
            if fault == LinkFault.GRIPPER_FAULT:
                self.model.inject_fault(code)

    def set_object(self, position: int | None) -> None:
        """Put an object between the fingers (stops them at ``position``), or remove it."""
        with self._lock:
            self.model.object_position = position

    def status(self) -> GripperStatus:
        """Current status (advancing the model to now)."""
        with self._lock:
            self.model.advance(self.clock())
            return self.model.status()

    def handle(self, frame: bytes) -> bytes | None:
        """Answer one request frame; ``None`` when a real gripper would stay silent."""
        with self._lock:
            return self._handle(frame)

    def _handle(self, frame: bytes) -> bytes | None:
        self.counters.requests += 1
        if self.link_fault == LinkFault.NO_ANSWER:
            self.counters.ignored_no_answer += 1
            return None
        try:
            request = modbus.decode_request(frame)
        except RobotiqError:
            self.counters.bad_crc_requests += 1
            return None
        if request.slave != self.slave:
            self.counters.other_slave += 1
            return None
        reply = self._answer(request)
        self.counters.replies += 1
        corrupt_write = (
            self.link_fault == LinkFault.BAD_CRC_ON_WRITE
            and request.function == modbus.Function.WRITE_MULTIPLE_REGISTERS
        )
        if self.link_fault == LinkFault.BAD_CRC or corrupt_write:
            self.counters.corrupted_replies += 1
            reply = reply[:-2] + bytes([reply[-2] ^ 0xFF, reply[-1]])
        return reply

    def _answer(self, request: modbus.Request) -> bytes:
        now = self.clock()
        fn, address, count = request.function, request.address, request.count
        command_span = range(COMMAND_REGISTER, COMMAND_REGISTER + REGISTER_BLOCK)
        status_span = range(STATUS_REGISTER, STATUS_REGISTER + REGISTER_BLOCK)
        if fn in (modbus.Function.READ_HOLDING_REGISTERS, modbus.Function.READ_INPUT_REGISTERS):
            last = address + count - 1
            if address in status_span and last in status_span:
                self.model.advance(now)
                block = list(self.model.status().to_registers()) + [0] * (REGISTER_BLOCK - 3)
                values = block[address - STATUS_REGISTER : last - STATUS_REGISTER + 1]
                return modbus.encode_read_reply(self.slave, fn, values)
            if address in command_span and last in command_span:
                values = self._command_regs[
                    address - COMMAND_REGISTER : last - COMMAND_REGISTER + 1
                ]
                return modbus.encode_read_reply(self.slave, fn, values)
            return self._exception(fn, modbus.ExceptionCode.ILLEGAL_DATA_ADDRESS)
        if fn == modbus.Function.WRITE_MULTIPLE_REGISTERS:
            last = address + count - 1
            if not (address in command_span and last in command_span):
                return self._exception(fn, modbus.ExceptionCode.ILLEGAL_DATA_ADDRESS)
            offset = address - COMMAND_REGISTER
            self._command_regs[offset : offset + count] = request.values
            self.model.write(GripperCommand.from_registers(self._command_regs[:3]), now)
            return modbus.encode_write_reply(self.slave, address, count)
        return self._exception(fn, modbus.ExceptionCode.ILLEGAL_FUNCTION)

    def _exception(self, function: int, code: modbus.ExceptionCode) -> bytes:
        self.counters.exceptions += 1
        return modbus.encode_exception(self.slave, function, code)


class RtuFramer:
    """Cuts a byte stream into RTU requests by the length their function code implies.

    A partial request followed by ``gap_s`` of silence (wider than RTU's 3.5 characters, for a
    pty and a Python scheduler) is dropped.
    """

    def __init__(self, gap_s: float = 0.05) -> None:
        self.gap_s = gap_s
        self._buffer = b""
        self._last_t = 0.0
        self.dropped_bytes = 0

    def feed(self, data: bytes, now: float) -> list[bytes]:
        """Add received bytes; return the complete requests they finish."""
        if self._buffer and now - self._last_t > self.gap_s:
            self.dropped_bytes += len(self._buffer)
            self._buffer = b""
        self._last_t = now
        self._buffer += data
        frames = []
        while True:
            length = modbus.request_length(self._buffer)
            if length is None or len(self._buffer) < length:
                break
            frames.append(self._buffer[:length])
            self._buffer = self._buffer[length:]
        return frames


class PtyGripper:
    """Serves a :class:`RobotiqEmulator` on a new pseudo-terminal at :attr:`path` (any baud).

    Use as a context manager (serves in a daemon thread) or call :meth:`serve_forever`.
    """

    def __init__(self, emulator: RobotiqEmulator | None = None, gap_s: float = 0.05) -> None:
        self.emulator = emulator or RobotiqEmulator()
        self.framer = RtuFramer(gap_s)
        self._master, self._slave = os.openpty()
        tty.setraw(self._slave)
        tty.setraw(self._master)
        self.path = os.ttyname(self._slave)
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def serve_forever(self, poll_s: float = 0.01) -> None:
        """Answer requests until :meth:`stop` (or KeyboardInterrupt in the caller)."""
        while not self._stop.is_set():
            ready, _, _ = select.select([self._master], [], [], poll_s)
            if not ready:
                continue
            try:
                data = os.read(self._master, 4096)
            except OSError:  # no client has the port open right now
                time.sleep(poll_s)
                continue
            for frame in self.framer.feed(data, self.emulator.clock()):
                reply = self.emulator.handle(frame)
                if reply is not None:
                    os.write(self._master, reply)

    def stop(self) -> None:
        """Stop serving and close the pty."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
            self._thread = None
        for fd in (self._master, self._slave):
            with contextlib.suppress(OSError):
                os.close(fd)

    def __enter__(self) -> PtyGripper:
        self._thread = threading.Thread(target=self.serve_forever, name="robotiq-pty", daemon=True)
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()


def _interrupt(signum: int, frame: object) -> None:
    raise KeyboardInterrupt  # SIGTERM ends the server as cleanly as Ctrl-C


def serve(args: argparse.Namespace) -> int:
    """Open the emulated gripper on a pty, print its path, serve until Ctrl-C or SIGTERM.

    ``args`` may set ``object_position`` (-1: none), ``activation_s``, ``fault`` (a
    :class:`LinkFault` name), ``slave`` and ``link`` (a symlink to the pty, removed at exit).
    """
    object_position = int(getattr(args, "object_position", DEMO_OBJECT_POSITION))
    model = GripperModel(
        activation_s=float(getattr(args, "activation_s", 0.3)),
        object_position=object_position if 0 <= object_position <= 255 else None,
    )
    emulator = RobotiqEmulator(model, slave=int(getattr(args, "slave", DEFAULT_SLAVE_ID)))
    emulator.set_fault(LinkFault[str(getattr(args, "fault", "none")).upper()])
    pty = PtyGripper(emulator)
    link = getattr(args, "link", None)
    if link:
        with contextlib.suppress(FileNotFoundError):
            if os.path.islink(link):
                os.unlink(link)
        os.symlink(pty.path, link)
    print(pty.path, flush=True)
    print(
        f"Robotiq 2F emulator: slave {emulator.slave}, any baud, object at "
        f"{model.object_position}; Ctrl-C to stop.",
        file=sys.stderr,
        flush=True,
    )
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, _interrupt)
    try:
        pty.serve_forever()
    except KeyboardInterrupt:
        pass
    finally:
        pty.stop()
        if link and os.path.islink(link):
            os.unlink(link)
    return 0
