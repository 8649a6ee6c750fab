"""Choosing and spinning the executor.

``EventsExecutor`` where rclpy has it (Kilted; it keeps up at 4 kHz where the single-threaded
one drops), else single-threaded (Jazzy). Never call ``EventsExecutor.spin()``: in rclpy 9.1 it
busy-waits and ignores stop signals (docs/ros2-from-pypi.md); :func:`spin_until_shutdown` loops
on ``spin_once`` instead.
"""

from __future__ import annotations

from collections.abc import Callable

from rclpy.context import Context
from rclpy.executors import Executor, ExternalShutdownException, SingleThreadedExecutor

try:  # Kilted and later
    from rclpy.experimental import EventsExecutor
except ImportError:  # Jazzy
    EventsExecutor = None  # type: ignore[assignment,misc]


def make_executor(context: Context | None = None) -> Executor:
    """The fastest executor this rclpy offers."""
    if EventsExecutor is not None:
        return EventsExecutor(context=context)
    return SingleThreadedExecutor(context=context)


def spin_until_shutdown(
    executor: Executor,
    context: Context | None = None,
    timeout_s: float = 0.1,
    stop: Callable[[], bool] | None = None,
) -> None:
    """Run callbacks until ``stop()`` or the context (default: rclpy's) is shut down.

    ``timeout_s`` is the longest wait for one callback: how late the end may be noticed.
    """
    import rclpy

    context = context or rclpy.get_default_context()
    try:
        while context.ok() and not (stop is not None and stop()):
            executor.spin_once(timeout_sec=timeout_s)
    except ExternalShutdownException:
        pass
