"""Helpers for tests that run nodes in this process: a context, an executor thread, waiting."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any


@contextmanager
def spinning(*node_factories: Callable[..., Any]) -> Iterator[list[Any]]:
    """Create nodes on a fresh context, spin them on one executor thread, clean up after."""
    import rclpy
    from rclpy.context import Context

    from ext_sense_runtime.executor import make_executor
    from ext_sense_runtime.node_main import destroy_node

    context = Context()
    rclpy.init(context=context, args=[])
    executor = make_executor(context=context)
    nodes = []
    stop = threading.Event()

    def spin() -> None:
        while not stop.is_set() and context.ok():
            try:
                executor.spin_once(timeout_sec=0.02)
            except Exception:  # shutdown races end the loop
                if stop.is_set() or not context.ok():
                    return
                raise

    try:
        for factory in node_factories:
            node = factory(context=context)
            nodes.append(node)
            executor.add_node(node)
        thread = threading.Thread(target=spin, daemon=True)
        thread.start()
        try:
            yield nodes
        finally:
            stop.set()
            thread.join(timeout=5)
    finally:  # the order of a node process's own teardown (node_main.RosSession.close)
        executor.shutdown()  # before the nodes: it lets go of their entities
        for node in nodes:
            destroy_node(node)
        rclpy.try_shutdown(context=context)
        context.destroy()


def wait_for(predicate: Callable[[], bool], timeout: float = 10.0, step: float = 0.02) -> bool:
    """Poll ``predicate`` until it holds or ``timeout`` seconds pass; returns its last value."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if predicate():
            return True
        time.sleep(step)
    return bool(predicate())


def spin_until(executor: Any, predicate: Callable[[], bool], timeout_s: float = 10.0) -> bool:
    """Spin ``executor`` in this thread until ``predicate()`` holds; False after ``timeout_s``.

    For tests that own their executor (lifecycle transitions, action round trips) rather than
    spinning it in a thread as :func:`spinning` does. ``executor`` may be a list of executors,
    spun in turn: a test then leaves one out to make its node stop answering.
    """
    executors = executor if isinstance(executor, list) else [executor]
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        for one in executors:
            one.spin_once(timeout_sec=0.01)
        if predicate():
            return True
    return False
