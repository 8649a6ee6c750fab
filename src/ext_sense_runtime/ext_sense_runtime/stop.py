"""Stop signals recorded as one request: node processes, ``ext-sense run`` and the commands.

SIGINT, SIGTERM, SIGHUP and SIGQUIT would kill a process at once (its participant lingering in
the graph, a killed runner's nodes left running); here a handler only records the stop, and the
spin loop ends cleanly. Repeated signals are the same request. No rclpy: the runner uses it too.
"""

from __future__ import annotations

import faulthandler
import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from types import FrameType

STOP_SIGNALS: tuple[signal.Signals, ...] = (
    signal.SIGINT,
    signal.SIGTERM,
    signal.SIGHUP,
    signal.SIGQUIT,
)
"""The signals that ask a process to stop."""
STACKS_SIGNAL = signal.SIGUSR1
"""Prints every thread's stack (``faulthandler``): sent to a node that did not stop in time."""


class StopRequest:
    """The stop signals recorded as a request to stop; repeated signals are the same request.

    With ``interrupt`` the first signal also raises ``KeyboardInterrupt`` in the main thread,
    to end an operator prompt while callbacks run in another thread; never while the main
    thread runs callbacks (an exception inside one the executor's C++ called aborts).
    """

    def __init__(self) -> None:
        self.signum: int | None = None
        """The first stop signal received, ``None`` before."""
        self.count = 0
        """Stop signals received so far."""
        self.installed = False
        self.interrupt = False

    def install(self, interrupt: bool = False) -> bool:
        """Install the handlers for :data:`STOP_SIGNALS` once; whether they are (main thread)."""
        self.interrupt = self.interrupt or interrupt
        if not self.installed and threading.current_thread() is threading.main_thread():
            for signum in STOP_SIGNALS:
                signal.signal(signum, self._on_signal)
            faulthandler.register(STACKS_SIGNAL, all_threads=True)
            self.installed = True
            # children start with them blocked (stop_signals_blocked): delivered now
            signal.pthread_sigmask(signal.SIG_UNBLOCK, STOP_SIGNALS)
        return self.installed

    def _on_signal(self, signum: int, _frame: FrameType | None) -> None:
        # possibly inside a callback: no rclpy here, and raise only when asked to
        self.count += 1
        if self.signum is None:
            self.signum = signum
            if self.interrupt:
                raise KeyboardInterrupt

    def requested(self) -> bool:
        """Whether a stop signal has been received."""
        return self.signum is not None

    def exit_code(self) -> int:
        """The shell's exit status for a stop by the first signal: ``128 + N``."""
        return 128 + int(self.signum or signal.SIGINT)

    def ignore_further(self) -> None:
        """Ignore stop signals from now on, once the process is done and about to exit.

        Finalisation resets Python handlers to the default action: a late Ctrl-C would end a
        clean stop with -2. An ignored signal stays ignored.
        """
        if self.installed:
            for signum in STOP_SIGNALS:
                signal.signal(signum, signal.SIG_IGN)


STOP = StopRequest()
"""This process's stop request (signal handlers are per process)."""


def install_stop_handlers(interrupt: bool = False) -> StopRequest:
    """Install the stop handlers now (idempotent) and return :data:`STOP`."""
    STOP.install(interrupt)
    return STOP


@contextmanager
def stop_signals_blocked() -> Iterator[None]:
    """Block :data:`STOP_SIGNALS` in this thread while a child process is started.

    The mask survives ``exec``: a signal during the child's imports stays pending until
    :meth:`StopRequest.install` unblocks it, instead of a ``KeyboardInterrupt`` in some import.
    """
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, STOP_SIGNALS)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)
