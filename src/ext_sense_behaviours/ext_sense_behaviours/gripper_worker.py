"""A thread that owns the Robotiq link: connects, polls the status, carries out commands.

Exchanges block for up to ``timeout_s`` x (``retries`` + 1), so never on an executor. After a
lost link or a fault, motion commands are dropped (counted) until the gripper is active again;
it keeps its last command meanwhile, so a held object stays held.
"""

from __future__ import annotations

import queue
import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import NamedTuple

from ext_sense_drivers.robotiq import FaultKind, GripperStatus, RobotiqClient, RobotiqError


class GripperCommandRequest(NamedTuple):
    """One request to the worker: ``kind`` is ``"move"``, ``"activate"`` or ``"reset"``."""

    kind: str
    position: int = 0
    speed: int = 128
    force: int = 128


@dataclass
class WorkerCounters:
    """What the worker did."""

    polls: int = 0
    errors: int = 0
    commands_sent: int = 0
    commands_dropped: int = 0
    reconnects: int = 0


StatusCallback = Callable[[GripperStatus | None, RobotiqError | None], None]


class GripperWorker:
    """Runs a Robotiq client in its own thread.

    ``connect`` opens the port and returns a client (RobotiqError when it cannot);
    ``on_status`` is called from the worker thread with ``(status, None)`` after each poll, or
    ``(last_status, error)`` when an exchange failed.
    """

    def __init__(
        self,
        connect: Callable[[], RobotiqClient],
        on_status: StatusCallback,
        poll_period_s: float = 0.1,
        auto_activate: bool = True,
        reconnect_s: float = 1.0,
    ) -> None:
        self._connect = connect
        self._on_status = on_status
        self.poll_period_s = poll_period_s
        self.auto_activate = auto_activate
        self.reconnect_s = reconnect_s
        self.counters = WorkerCounters()
        self.client: RobotiqClient | None = None
        self.last_status: GripperStatus | None = None
        self.last_error: RobotiqError | None = None
        self._commands: queue.Queue[GripperCommandRequest] = queue.Queue(maxsize=16)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="robotiq-worker", daemon=True)

    def start(self) -> None:
        """Start the thread."""
        self._thread.start()

    def stop(self, timeout_s: float = 3.0) -> None:
        """Stop the thread and close the port."""
        self._stop.set()
        self._thread.join(timeout=timeout_s)
        if self.client is not None:
            self.client.close()
            self.client = None

    def submit(self, request: GripperCommandRequest) -> bool:
        """Queue a request; False (counted as dropped) when the queue is full."""
        try:
            self._commands.put_nowait(request)
            return True
        except queue.Full:
            self.counters.commands_dropped += 1
            return False

    def _report(self, status: GripperStatus | None, error: RobotiqError | None) -> None:
        if error is not None:
            self.counters.errors += 1
        self.last_error = error
        self._on_status(status, error)

    def _ensure_client(self) -> bool:
        if self.client is not None:
            return True
        try:
            self.client = self._connect()
            self.counters.reconnects += 1
            if self.auto_activate and not self.client.read_status().ready:
                self.client.activate()
        except RobotiqError as err:
            if self.client is not None:
                self.client.close()
                self.client = None
            self._report(self.last_status, err)
            return False
        return True

    def _execute(self, request: GripperCommandRequest) -> None:
        assert self.client is not None
        if request.kind == "activate":
            self.client.activate()
        elif request.kind == "reset":
            self.client.reset()
        elif request.kind == "move":
            status = self.last_status
            if self.last_error is not None or status is None or not status.ready:
                self.counters.commands_dropped += 1
                why = "link error" if self.last_error is not None else "gripper not ready"
                raise RobotiqError(
                    f"Move to {request.position} dropped: {why} (activate the gripper first).",
                    FaultKind.GRIPPER_FAULT,
                )
            self.client.move(request.position, request.speed, request.force)
        self.counters.commands_sent += 1

    def _run(self) -> None:
        while not self._stop.is_set():
            if not self._ensure_client():
                self._stop.wait(self.reconnect_s)
                continue
            assert self.client is not None
            try:
                try:
                    request = self._commands.get(timeout=self.poll_period_s)
                except queue.Empty:
                    request = None
                if request is not None:
                    self._execute(request)
                status = self.client.read_status()
                self.counters.polls += 1
                self.last_status = status
                self._report(status, None)
            except RobotiqError as err:
                self._report(self.last_status, err)
                if err.kind == FaultKind.SERIAL:
                    self.client.close()
                    self.client = None
                    self._stop.wait(self.reconnect_s)
