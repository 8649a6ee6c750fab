"""The spin-and-signal helper of every rclpy entry point: init, spin, one clean teardown.

A stop signal or a node shutting its context down ends the process with 0 after its nodes are
destroyed and its context shut down and destroyed (its participant leaves the graph at once).
rclpy's own handlers are not used: their ``KeyboardInterrupt`` aborts the process inside a
callback the executor's C++ called; here the handlers only record the stop (:mod:`.stop`).
"""

from __future__ import annotations

import contextlib
import gc
import sys
import threading
from collections.abc import Callable, Sequence
from types import TracebackType
from typing import TypeVar

import rclpy
from rclpy.context import Context
from rclpy.executors import Executor, ExternalShutdownException
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions

from ext_sense_runtime.executor import make_executor, spin_until_shutdown
from ext_sense_runtime.stop import install_stop_handlers
from ext_sense_runtime.teardown_guard import TeardownGuard

N = TypeVar("N", bound=Node)

BACKGROUND_JOIN_S = 5.0
"""Longest wait for :meth:`RosSession.spin_in_background`'s thread to end at the teardown."""


class RosSession:
    """``rclpy.init`` with the stop handlers, one executor, one teardown (:meth:`close`) on exit.

    Off the main thread (a test process) rclpy's own handlers are kept. ``args`` go to
    ``rclpy.init`` (``None``: ``sys.argv``); with ``interrupt`` the first stop signal also
    raises ``KeyboardInterrupt`` in a main thread waiting on an operator.
    """

    def __init__(self, args: Sequence[str] | None = None, *, interrupt: bool = False) -> None:
        self.stop = install_stop_handlers(interrupt)
        options = SignalHandlerOptions.NO if self.stop.installed else None
        rclpy.init(args=args, signal_handler_options=options)
        self.context: Context = rclpy.get_default_context()
        self.nodes: list[Node] = []
        self.executor: Executor = make_executor()
        self._background: threading.Thread | None = None
        self._background_done = threading.Event()
        self.closed = False

    def __enter__(self) -> RosSession:
        return self

    def __exit__(
        self,
        kind: type[BaseException] | None,
        err: BaseException | None,
        tb: TracebackType | None,
    ) -> bool:
        self.close()
        # rclpy's own handlers (off the main thread) end a spin this way: a clean stop
        return kind is not None and issubclass(kind, ExternalShutdownException)

    def add(self, node: N) -> N:
        """Spin ``node`` on the session's executor and destroy it at the teardown."""
        self.nodes.append(node)
        self.executor.add_node(node)
        return node

    def running(self) -> bool:
        """Neither a stop was asked nor the context shut down (a node that finished its job)."""
        return self.context.ok() and not self.stop.requested()

    def spin(self, until: Callable[[], bool] | None = None, timeout_s: float = 0.1) -> None:
        """Run callbacks in this thread until a stop, a shutdown, or ``until()`` holds.

        ``timeout_s``, the longest wait for one callback, bounds how late the end is noticed.
        """
        stop = self.stop.requested

        def done() -> bool:
            return stop() or (until is not None and until())

        with contextlib.suppress(KeyboardInterrupt):  # rclpy's handlers (off the main thread)
            spin_until_shutdown(self.executor, self.context, timeout_s, stop=done)

    def spin_in_background(self, timeout_s: float = 0.05) -> None:
        """Run callbacks in a thread of their own until the teardown (:meth:`close`)."""
        self._background = threading.Thread(
            target=spin_until_shutdown,
            args=(self.executor, self.context, timeout_s, self._background_done.is_set),
            name="ros_spin",
            daemon=True,
        )
        self._background.start()

    def close(self) -> None:
        """The teardown (once): executor, nodes, rclpy and its context; then signals ignored."""
        if self.closed:
            return
        self.closed = True
        self._background_done.set()
        if self._background is not None:
            self._background.join(timeout=BACKGROUND_JOIN_S)
        with TeardownGuard(self.nodes, enabled=self.stop.installed) as guard:
            self.executor.shutdown()  # before the nodes: it lets go of their entities
            for node in self.nodes:
                guard.destroying(node)
                destroy_node(node)
            guard.destroying(None)
            with guard.middleware():
                rclpy.try_shutdown(context=self.context)
                # the participant is deleted when the context is finalised: now, not at some
                # garbage collection that may never come (the start-up objects are frozen)
                self.context.destroy()
        self.stop.ignore_further()


def destroy_node(node: Node) -> None:
    """``node.destroy_node()``; for a lifecycle node also its state machine.

    rclpy's ``LifecycleNode`` never destroys its state machine, which holds the context: the
    node would stay in ``ros2 node list`` until its participant's lease ran out.
    """
    node.destroy_node()
    # a lifecycle node's class imported rclpy.lifecycle; the other nodes never need it
    lifecycle = sys.modules.get("rclpy.lifecycle")
    if lifecycle is not None and isinstance(node, lifecycle.LifecycleNode):
        node._state_machine.destroy_when_not_in_use()


def run_nodes(factories: Sequence[Callable[[], Node]], args: Sequence[str] | None = None) -> int:
    """Create nodes after ``rclpy.init``, spin them on one executor until a stop, clean up once.

    Returns the exit code, 0 on a clean stop; an exception from a factory or a callback
    propagates after the cleanup. ``args`` as for :class:`RosSession`.
    """
    with RosSession(args) as ros:
        for factory in factories:
            if not ros.running():  # Ctrl-C while the nodes were being built
                break
            ros.add(factory())
        gc.collect()  # then frozen: full collections skip the start-up objects (ms on the hot path)
        gc.freeze()
        ros.spin()
    return 0


def run_node(factory: Callable[[], Node], args: Sequence[str] | None = None) -> int:
    """:func:`run_nodes` with one node factory (usually the Node subclass itself)."""
    return run_nodes([factory], args)
