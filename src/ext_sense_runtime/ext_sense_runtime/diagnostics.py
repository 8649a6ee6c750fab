"""A small diagnostics updater in the spirit of ros/diagnostics (not on PyPI), no rclpy.

One task per concern, each returning a level, a message and key-values whose keys carry their
units; the clock is injected, so tests never sleep. :mod:`.diagnostics_ros` publishes reports.
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from enum import IntEnum


class Level(IntEnum):
    """Levels of ``diagnostic_msgs/DiagnosticStatus``."""

    OK = 0
    WARN = 1
    ERROR = 2
    STALE = 3


@dataclass(frozen=True)
class StatusReport:
    """What one task says at one update (maps 1:1 to ``DiagnosticStatus``)."""

    name: str
    level: Level
    message: str
    hardware_id: str = ""
    values: tuple[tuple[str, str], ...] = ()


Clock = Callable[[], int]
"""Returns monotonic integer nanoseconds."""


@dataclass
class StatusTask:
    """A task built from a function returning ``(level, message, values)``."""

    name: str
    check: Callable[[], tuple[Level, str, dict[str, object]]]

    def report(self, hardware_id: str) -> StatusReport:
        """Run the check and wrap its answer."""
        level, message, values = self.check()
        return StatusReport(self.name, level, message, hardware_id, _pairs(values))


@dataclass
class RateTask:
    """Event-rate check against ``[min_hz, max_hz]`` with a tolerance, over a sliding window.

    Call :meth:`tick` for every event (or :meth:`add` for ``n`` at once); the rate is counted
    over the last ``window`` updates, like ``diagnostic_updater.FrequencyStatus``.
    """

    name: str
    min_hz: float
    max_hz: float
    tolerance: float = 0.1
    window: int = 5
    clock: Clock = time.monotonic_ns
    unit: str = "per_s"
    _count: int = 0
    _history: deque[tuple[int, int]] = field(default_factory=deque)

    def tick(self) -> None:
        """Count one event."""
        self._count += 1

    def add(self, n: int) -> None:
        """Count ``n`` events."""
        self._count += int(n)

    def rate(self) -> float:
        """Events per second over the current window (0 before two updates)."""
        if len(self._history) < 2:
            return 0.0
        (t0, c0), (t1, c1) = self._history[0], self._history[-1]
        return (c1 - c0) * 1e9 / (t1 - t0) if t1 > t0 else 0.0

    def report(self, hardware_id: str) -> StatusReport:
        """Level OK inside the tolerated band, WARN outside, ERROR when nothing arrives."""
        self._history.append((self.clock(), self._count))
        while len(self._history) > self.window + 1:
            self._history.popleft()
        rate = self.rate()
        lo, hi = self.min_hz * (1 - self.tolerance), self.max_hz * (1 + self.tolerance)
        if len(self._history) < 2:
            level, message = Level.OK, "warming up"
        elif rate == 0.0 and self.min_hz > 0:
            level, message = Level.ERROR, "no events"
        elif rate < lo:
            level, message = Level.WARN, "rate too low"
        elif rate > hi:
            level, message = Level.WARN, "rate too high"
        else:
            level, message = Level.OK, "rate ok"
        values = {
            f"rate_{self.unit}": f"{rate:.1f}",
            f"min_{self.unit}": self.min_hz,
            f"max_{self.unit}": self.max_hz,
            "events_total": self._count,
        }
        return StatusReport(self.name, level, message, hardware_id, _pairs(values))


class Updater:
    """Collects tasks and produces their reports at most every ``period_ns`` (1 s).

    ``hardware_id`` (the sensor's serial or port) is shown on every status.
    """

    def __init__(
        self, hardware_id: str, period_ns: int = 1_000_000_000, clock: Clock = time.monotonic_ns
    ) -> None:
        self.hardware_id = hardware_id
        self.period_ns = int(period_ns)
        self.clock = clock
        self.tasks: list[StatusTask | RateTask] = []
        self._last_ns: int | None = None

    def add(self, task: StatusTask | RateTask) -> StatusTask | RateTask:
        """Register a task and return it."""
        self.tasks.append(task)
        return task

    def add_check(
        self, name: str, check: Callable[[], tuple[Level, str, dict[str, object]]]
    ) -> StatusTask:
        """Register a function as a task."""
        return self.add(StatusTask(name, check))  # type: ignore[return-value]

    def due(self) -> bool:
        """Whether ``period_ns`` has passed since the last update."""
        return self._last_ns is None or self.clock() - self._last_ns >= self.period_ns

    def update(self, force: bool = False) -> list[StatusReport]:
        """Run every task when due (or forced); return their reports, else an empty list.

        A task that raises is reported as ERROR instead of killing the node.
        """
        if not (force or self.due()):
            return []
        self._last_ns = self.clock()
        reports = []
        for task in self.tasks:
            try:
                reports.append(task.report(self.hardware_id))
            except Exception as err:
                reports.append(
                    StatusReport(task.name, Level.ERROR, f"check failed: {err!r}", self.hardware_id)
                )
        return reports


def _pairs(values: dict[str, object]) -> tuple[tuple[str, str], ...]:
    return tuple((str(k), str(v)) for k, v in values.items())
