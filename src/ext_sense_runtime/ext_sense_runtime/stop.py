"""Stop signals recorded as one request: node processes, ``ext-sense run`` and the commands.

Every process of a graph stops on the same signals, the ones a terminal, a supervisor or a
session manager sends to end a program: SIGINT (Ctrl-C), SIGTERM (``kill``, ``ros2 launch``'s
escalation, systemd), SIGHUP (the terminal closed, ``kill -HUP``) and SIGQUIT
(Ctrl-backslash). Their default actions kill a process at once (the node's middleware
participant then lingers in the graph until its lease runs out, and a killed ``ext-sense run``
leaves its nodes running); here a handler only records that a stop was asked, and the
process's spin loop notices it and ends cleanly. Repeated signals are the same request.

No rclpy here: the runner, which starts node processes but runs none, uses it too.
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
"""Makes a node process print every thread's stack to stderr and go on (``faulthandler``):
``ext-sense run`` sends it to a node that did not stop in time, before killing it, so the log
says where it hung."""


class StopRequest:
    """The stop signals recorded as a request to stop; repeated signals are the same request.

    With ``interrupt`` the first signal also raises ``KeyboardInterrupt`` in the main thread,
    for a program whose main thread waits in Python code of its own (an operator prompt) while
    its ROS callbacks run in another thread: the signal then ends the wait. Never use it while
    the main thread runs callbacks (an exception raised inside a callback the executor's C++
    called aborts the process).
    """

    def __init__(self) -> None:
        self.signum: int | None = None
        """The first stop signal received, ``None`` before."""
        self.count = 0
        """Stop signals received so far."""
        self.installed = False
        self.interrupt = False

    def install(self, interrupt: bool = False) -> bool:
        """Install the handlers for :data:`STOP_SIGNALS` (once; main thread only).

        Args:
            interrupt: Also raise ``KeyboardInterrupt`` at the first signal (see the class).

        Returns:
            Whether the handlers are installed (``False`` off the main thread, where Python
            cannot install signal handlers).
        """
        self.interrupt = self.interrupt or interrupt
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
        # not call into rclpy, and raises only when asked to (``interrupt``).
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


def install_stop_handlers(interrupt: bool = False) -> StopRequest:
    """Install the stop handlers now (idempotent), e.g. before slow imports.

    Args:
        interrupt: Also raise ``KeyboardInterrupt`` at the first signal (:class:`StopRequest`).

    Returns:
        :data:`STOP`, this process's stop request.
    """
    STOP.install(interrupt)
    return STOP


@contextmanager
def stop_signals_blocked() -> Iterator[None]:
    """Block :data:`STOP_SIGNALS` in this thread while a child process is started.

    The mask survives ``exec``: a stop signal that comes while the child's interpreter starts
    and imports stays pending until it installs its handlers (:meth:`StopRequest.install`
    unblocks them), instead of killing it or raising ``KeyboardInterrupt`` in some import.
    """
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, STOP_SIGNALS)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)
