"""Choosing and spinning the executor.

``EventsExecutor`` where rclpy has it (Kilted), else single-threaded: at 4 kHz the
SingleThreadedExecutor drops messages where the EventsExecutor with a deep history keeps up;
Jazzy's rclpy 7.1 has no EventsExecutor.

Never call ``EventsExecutor.spin()`` directly: in rclpy 9.1 it busy-waits (most of a core with
nothing to do; docs/ros2-from-pypi.md) and does not return on SIGINT or SIGTERM, while a loop of
``spin_once(timeout_sec)`` idles and ends when a stop is requested (the stop handlers of
:mod:`ext_sense_runtime.stop`) or the context is shut down. :func:`spin_until_shutdown` is
that loop.
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
    """Run callbacks until a stop is requested or the context is shut down (a node finishing).

    Args:
        executor: The executor with the nodes added.
        context: The context to watch; the default context when ``None``.
        timeout_s: Longest wait for one callback; bounds how late a stop or shutdown is noticed.
        stop: Polled between callbacks: true ends the loop (e.g. Ctrl-C or SIGTERM received).
    """
    import rclpy

    context = context or rclpy.get_default_context()
    try:
        while context.ok() and not (stop is not None and stop()):
            executor.spin_once(timeout_sec=timeout_s)
    except ExternalShutdownException:
        pass
