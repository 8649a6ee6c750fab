"""A Robotiq 2F client speaking Modbus RTU over a serial port, with timeouts and retries.

A missing or corrupt reply is retried ``retries`` times, then raised (NO_ANSWER, BAD_CRC); a
Modbus exception reply is not retried.
"""

from __future__ import annotations

import termios
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

from ext_sense_drivers.robotiq import modbus
from ext_sense_drivers.robotiq.errors import FaultKind, RobotiqError
from ext_sense_drivers.robotiq.registers import (
    COMMAND_REGISTER,
    DEFAULT_BAUDRATE,
    DEFAULT_SLAVE_ID,
    POSITION_CLOSED,
    POSITION_OPEN,
    STATUS_REGISTER,
    STATUS_REGISTER_COUNT,
    ActivationStatus,
    GripperCommand,
    GripperStatus,
    fault_name,
)

_PORT_ERRORS: tuple[type[BaseException], ...] = (OSError, termios.error)
"""What a vanished port raises (termios.error: pyserial's flush on a closed pty)."""


class SerialPort(Protocol):
    """The part of ``serial.Serial`` the client uses (so tests can pass a fake)."""

    timeout: float | None

    def write(self, data: bytes) -> int | None:
        """Write bytes."""

    def read(self, size: int = 1) -> bytes:
        """Read up to ``size`` bytes, waiting at most ``timeout`` seconds."""

    def reset_input_buffer(self) -> None:
        """Drop bytes received but not read."""

    def close(self) -> None:
        """Release the port."""


@dataclass
class ClientCounters:
    """Exchange statistics since the client was created."""

    requests: int = 0
    retries: int = 0
    timeouts: int = 0
    crc_errors: int = 0
    bad_frames: int = 0
    exception_replies: int = 0


def open_serial(port: str, baudrate: int = DEFAULT_BAUDRATE, timeout_s: float = 0.5) -> SerialPort:
    """Open ``port`` with pyserial, 8N1 (RobotiqError, kind SERIAL, if it cannot)."""
    import serial

    try:
        return serial.Serial(port=port, baudrate=baudrate, timeout=timeout_s)
    except (serial.SerialException, OSError, ValueError) as err:
        raise RobotiqError(
            f"Cannot open serial port '{port}' at {baudrate} baud: {err}", FaultKind.SERIAL
        ) from err


class RobotiqClient:
    """Talks to one Robotiq 2F gripper on an open serial port (or anything with its methods).

    Each reply may take ``timeout_s`` and is retried ``retries`` times; a poll reads
    ``read_count`` status registers (3 hold the whole status); ``sleep`` and ``clock`` (monotonic
    seconds) are injectable.
    """

    def __init__(
        self,
        port: SerialPort,
        *,
        slave: int = DEFAULT_SLAVE_ID,
        timeout_s: float = 0.5,
        retries: int = 2,
        read_count: int = STATUS_REGISTER_COUNT,
        sleep: Callable[[float], None] = time.sleep,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        if not timeout_s > 0:
            raise RobotiqError(
                f"The 'timeout_s' parameter must be > 0. Got {timeout_s!r} instead.",
                FaultKind.BAD_ARGUMENT,
            )
        if not (isinstance(retries, int) and retries >= 0):
            raise RobotiqError(
                f"The 'retries' parameter must be an int >= 0. Got {retries!r} instead.",
                FaultKind.BAD_ARGUMENT,
            )
        if not STATUS_REGISTER_COUNT <= read_count <= 8:
            raise RobotiqError(
                f"The 'read_count' parameter must be in [3, 8]. Got {read_count!r} instead.",
                FaultKind.BAD_ARGUMENT,
            )
        self.port = port
        self.slave = slave
        self.timeout_s = float(timeout_s)
        self.retries = retries
        self.read_count = read_count
        self._sleep = sleep
        self._clock = clock
        self.counters = ClientCounters()
        self.last_status: GripperStatus | None = None

    @classmethod
    def open(
        cls, port: str, baudrate: int = DEFAULT_BAUDRATE, timeout_s: float = 0.5, **kwargs: object
    ) -> RobotiqClient:
        """Open ``port`` with pyserial and wrap it (see :func:`open_serial`)."""
        return cls(open_serial(port, baudrate, timeout_s), timeout_s=timeout_s, **kwargs)  # type: ignore[arg-type]

    def close(self) -> None:
        """Close the serial port."""
        self.port.close()

    def _read_exact(self, size: int, deadline: float) -> bytes:
        data = b""
        while len(data) < size:
            remaining = deadline - self._clock()
            if remaining <= 0:
                break
            self.port.timeout = remaining
            try:
                chunk = self.port.read(size - len(data))
            except _PORT_ERRORS as err:
                raise RobotiqError(
                    f"Serial port failed while reading: {err}", FaultKind.SERIAL
                ) from err
            if not chunk:
                break
            data += chunk
        return data

    def _read_reply(self, normal_length: int) -> bytes:
        deadline = self._clock() + self.timeout_s
        head = self._read_exact(2, deadline)
        if len(head) == 2 and head[1] & 0x80:
            return head + self._read_exact(modbus.EXCEPTION_REPLY_LENGTH - 2, deadline)
        return head + self._read_exact(normal_length - len(head), deadline)

    def exchange(self, request: bytes, decode: Callable[[bytes], object], length: int) -> object:
        """Send ``request``, read a ``length``-byte reply and decode it, retrying failures."""
        last: RobotiqError | None = None
        for attempt in range(self.retries + 1):
            if attempt:
                self.counters.retries += 1
            self.counters.requests += 1
            try:
                self.port.reset_input_buffer()
                self.port.write(request)
            except _PORT_ERRORS as err:
                raise RobotiqError(
                    f"Serial port failed while writing: {err}", FaultKind.SERIAL
                ) from err
            reply = self._read_reply(length)
            if not reply:
                self.counters.timeouts += 1
                last = RobotiqError(
                    f"No answer from Robotiq slave {self.slave} within {self.timeout_s:.3f} s "
                    f"(request {request.hex(' ')}, attempt {attempt + 1} of {self.retries + 1}).",
                    FaultKind.NO_ANSWER,
                )
                continue
            is_exception = len(reply) >= 2 and bool(reply[1] & 0x80)
            expected = modbus.EXCEPTION_REPLY_LENGTH if is_exception else length
            if len(reply) < expected:
                self.counters.timeouts += 1
                last = RobotiqError(
                    f"Incomplete answer from Robotiq slave {self.slave} within "
                    f"{self.timeout_s:.3f} s: {len(reply)} of {expected} bytes "
                    f"({reply.hex(' ')}).",
                    FaultKind.NO_ANSWER,
                )
                continue
            try:
                return decode(reply)
            except RobotiqError as err:
                if err.kind == FaultKind.EXCEPTION_REPLY:
                    self.counters.exception_replies += 1
                    raise
                if err.kind == FaultKind.BAD_CRC:
                    self.counters.crc_errors += 1
                else:
                    self.counters.bad_frames += 1
                last = err
        assert last is not None
        raise RobotiqError(
            f"{last} Gave up after {self.retries + 1} attempts.", last.kind
        ) from last

    def read_registers(self, address: int, count: int) -> tuple[int, ...]:
        """Read ``count`` holding registers (function 0x03)."""
        request = modbus.encode_read_request(self.slave, address, count)
        return self.exchange(  # type: ignore[return-value]
            request,
            lambda f: modbus.decode_read_reply(f, self.slave, count),
            modbus.read_reply_length(count),
        )

    def write_registers(self, address: int, values: tuple[int, ...]) -> None:
        """Write registers (function 0x10)."""
        request = modbus.encode_write_request(self.slave, address, values)
        self.exchange(
            request,
            lambda f: modbus.decode_write_reply(f, self.slave, address, len(values)),
            modbus.WRITE_REPLY_LENGTH,
        )

    def read_status(self, raise_on_fault: bool = False) -> GripperStatus:
        """Poll the status (RobotiqError; GRIPPER_FAULT if ``raise_on_fault`` and gFLT != 0)."""
        status = GripperStatus.from_registers(self.read_registers(STATUS_REGISTER, self.read_count))
        self.last_status = status
        if raise_on_fault and status.fault:
            raise RobotiqError(
                f"Gripper reports fault gFLT={fault_name(status.fault)}.", FaultKind.GRIPPER_FAULT
            )
        return status

    def write_command(self, command: GripperCommand) -> None:
        """Write the command registers."""
        self.write_registers(COMMAND_REGISTER, command.to_registers())

    def reset(self) -> None:
        """Clear rACT: the gripper stops and forgets its activation (also clears major faults)."""
        self.write_command(GripperCommand(activate=False, speed=0, force=0))

    def activate(self, timeout_s: float = 5.0, poll_s: float = 0.05) -> GripperStatus:
        """Reset, then set rACT and poll until activation completes (ACTIVATION, GRIPPER_FAULT)."""
        self.reset()
        self.write_command(GripperCommand(activate=True, speed=0, force=0))
        deadline = self._clock() + timeout_s
        while True:
            status = self.read_status(raise_on_fault=True)
            if status.activated and status.activation == ActivationStatus.COMPLETED:
                return status
            if self._clock() >= deadline:
                raise RobotiqError(
                    f"Activation did not complete within {timeout_s} s "
                    f"(gACT={int(status.activated)}, gSTA={status.activation.name}).",
                    FaultKind.ACTIVATION,
                )
            self._sleep(poll_s)

    def move(self, position: int, speed: int = 255, force: int = 255) -> None:
        """Ask the fingers to go to ``position`` (0 open .. 255 closed)."""
        self.write_command(
            GripperCommand(activate=True, go_to=True, position=position, speed=speed, force=force)
        )

    def wait_for_motion(self, timeout_s: float = 5.0, poll_s: float = 0.02) -> GripperStatus:
        """Poll until the last move ended (GRIPPER_FAULT; NO_ANSWER if moving at ``timeout_s``)."""
        deadline = self._clock() + timeout_s
        while True:
            status = self.read_status(raise_on_fault=True)
            if status.motion_done:
                return status
            if self._clock() >= deadline:
                raise RobotiqError(
                    f"Gripper still moving after {timeout_s} s (gPO={status.position}, "
                    f"gPR={status.position_request}).",
                    FaultKind.NO_ANSWER,
                )
            self._sleep(poll_s)

    def open_fingers(self, speed: int = 255, force: int = 255) -> None:
        """Move to fully open."""
        self.move(POSITION_OPEN, speed, force)

    def close_fingers(self, speed: int = 255, force: int = 255) -> None:
        """Move to fully closed (stops on an object, gOBJ = 2)."""
        self.move(POSITION_CLOSED, speed, force)
