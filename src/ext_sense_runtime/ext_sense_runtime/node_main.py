"""The ``main`` shared by every node executable: init, spin, clean shutdown.

Ctrl-C (SIGINT, to the whole process group from a terminal, often twice: the terminal's and the
one ``ros2 launch`` or ``ext-sense run`` forwards), SIGTERM, and a node finishing its job (it shuts
its context down) all end the process with exit code 0, no abort and no traceback.

rclpy's own signal handlers are not used: ``rclpy.init`` installs SIGINT/SIGTERM handlers that
shut the context down and then chain to Python's default SIGINT handler, which raises
``KeyboardInterrupt`` in the main thread wherever it happens to be: inside a callback the
EventsExecutor's C++ called (``[FATAL] Exception in 'timers' callback``), inside a pybind11 call
that cannot pass it on (``terminate called after throwing an instance of
'pybind11::error_already_set'``, ``Fatal Python error: Aborted``, exit -6), or in
``destroy_node`` when a second SIGINT lands in the cleanup. Here rclpy is initialised with
``SignalHandlerOptions.NO`` and the handlers of :class:`StopRequest` only record that a stop was
asked; the spin loop notices it within its poll period (0.1 s) and then, from the main thread and
outside any callback, the executor is shut down, each node destroyed and rclpy shut down, once
each. Further signals are the same request, and once the cleanup is done they are ignored
(:meth:`StopRequest.ignore_further`): the process is exiting, and a signal during the
interpreter's finalisation would otherwise end it with -2.
"""

from __future__ import annotations

import faulthandler
import gc
import signal
import threading
from collections.abc import Callable, Sequence
from types import FrameType

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions

from ext_sense_runtime.executor import make_executor, spin_until_shutdown
from ext_sense_runtime.teardown_guard import TeardownGuard

STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)
"""The signals that ask a node process to stop."""
STACKS_SIGNAL = signal.SIGUSR1
"""Makes a node process print every thread's stack to stderr and go on (``faulthandler``):
``ext-sense run`` sends it to a node that did not stop in time, before killing it, so the log
says where it hung."""


class StopRequest:
    """SIGINT and SIGTERM recorded as a request to stop; repeated signals are the same request."""

    def __init__(self) -> None:
        self.signum: int | None = None
        """The first stop signal received, ``None`` before."""
        self.count = 0
        """Stop signals received so far."""
        self.installed = False

    def install(self) -> bool:
        """Install the handlers for :data:`STOP_SIGNALS` (once; main thread only).

        Returns:
            Whether the handlers are installed (``False`` off the main thread, where Python
            cannot install signal handlers).
        """
        if not self.installed and threading.current_thread() is threading.main_thread():
            for signum in STOP_SIGNALS:
                signal.signal(signum, self._on_signal)
            faulthandler.register(STACKS_SIGNAL, all_threads=True)
            self.installed = True
            # `ext-sense run` starts its children with these signals blocked, so that one
            # arriving while the interpreter starts and imports is held, not a KeyboardInterrupt:
            # delivered now, to the handler.
            signal.pthread_sigmask(signal.SIG_UNBLOCK, STOP_SIGNALS)
        return self.installed

    def _on_signal(self, signum: int, _frame: FrameType | None) -> None:
        # Runs in the main thread between two bytecodes, possibly inside a callback: it must
        # neither raise nor call into rclpy.
        self.count += 1
        if self.signum is None:
            self.signum = signum

    def requested(self) -> bool:
        """Whether a stop signal has been received."""
        return self.signum is not None

    def ignore_further(self) -> None:
        """Ignore stop signals from now on: call once the process is done and about to exit.

        Python's finalisation resets a signal whose handler is a Python function to the
        default action, so a second Ctrl-C arriving while the interpreter tears down would kill
        the process with -2 after a clean stop; an ignored signal stays ignored.
        """
        if self.installed:
            for signum in STOP_SIGNALS:
                signal.signal(signum, signal.SIG_IGN)


STOP = StopRequest()
"""This process's stop request (signal handlers are per process)."""


def install_stop_handlers() -> StopRequest:
    """Install the stop handlers now (idempotent), e.g. before slow imports.

    Returns:
        :data:`STOP`, this process's stop request.
    """
    STOP.install()
    return STOP


def run_nodes(factories: Sequence[Callable[[], Node]], args: Sequence[str] | None = None) -> int:
    """Create nodes after ``rclpy.init``, spin them on one executor until a stop, clean up once.

    Stops on SIGINT or SIGTERM (see the module docstring) or when the context is shut down (a
    node that finished its job). An exception from a factory or a callback is not a clean
    stop: it propagates after the cleanup.

    Args:
        factories: Each builds one node (usually a Node subclass itself).
        args: Command-line arguments (``--ros-args ...``); ``None`` reads ``sys.argv``.

    Returns:
        Process exit code: 0 on a clean stop.
    """
    stop = install_stop_handlers()
    # Off the main thread (no handlers of ours) rclpy's defaults are kept.
    options = SignalHandlerOptions.NO if stop.installed else None
    rclpy.init(args=args, signal_handler_options=options)
    nodes: list[Node] = []
    executor = None
    try:
        executor = make_executor()
        for factory in factories:
            if stop.requested():  # Ctrl-C while the nodes were being built
                break
            node = factory()
            nodes.append(node)
            executor.add_node(node)
        freeze_startup_objects()
        spin_until_shutdown(executor, stop=stop.requested)
    except (KeyboardInterrupt, ExternalShutdownException):  # rclpy's handlers (not main thread)
        pass
    finally:
        # a hang in rclpy's own teardown ends the process after every node's cleanup (off the
        # main thread, e.g. in a test process, the guard does nothing)
        with TeardownGuard(nodes, enabled=stop.installed) as guard:
            if executor is not None:
                executor.shutdown()  # before the nodes: it lets go of their entities
            for node in nodes:
                guard.destroying(node)
                node.destroy_node()
            guard.destroying(None)
            with guard.middleware():
                rclpy.try_shutdown()
        stop.ignore_further()
    return 0


def freeze_startup_objects() -> None:
    """Move every object alive now into the collector's permanent generation (``gc.freeze``).

    A node's start-up objects (modules, messages, the model) live as long as the process, but
    each full (generation 2) collection scanned them all again: 17.4 ms for the inference node's
    49 000 objects, now and then landing on a window (one tap of 60 at 22.7 ms in three of four
    ``bench_runtime.py --only latency`` runs). Frozen, a full collection scans only what came
    since: 0.4 ms (82 000 and 48 000 objects frozen in the window and inference nodes). Garbage
    is collected first, so none of it is kept.
    """
    gc.collect()
    gc.freeze()


def run_node(factory: Callable[[], Node], args: Sequence[str] | None = None) -> int:
    """Create the node after ``rclpy.init`` and spin it until a stop (:func:`run_nodes`).

    Args:
        factory: Builds the node (usually the Node subclass itself).
        args: Command-line arguments (``--ros-args ...``); ``None`` reads ``sys.argv``.

    Returns:
        Process exit code: 0 on a clean stop.
    """
    return run_nodes([factory], args)
