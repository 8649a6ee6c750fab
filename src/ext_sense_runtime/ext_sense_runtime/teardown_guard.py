"""Ends a node process whose middleware teardown hangs, even while that hang holds the GIL.

rclpy's ``Node.destroy_node`` can hang for good in a C++ call that keeps the GIL
(docs/runtime.md, "Stopping a graph"), so the guard uses what needs no GIL: ``faulthandler``'s
stack dump after :data:`TEARDOWN_LIMIT_S`, and :class:`NativeExitTimer`, a POSIX timer whose C
thread prints a message and calls ``_exit(0)``. The timer is armed only while rclpy tears down
the last node (its base ``destroy_node``, found with a profile hook) or shuts down: a hang in a
node's own cleanup (a recorder closing its bag) is left to the supervisor.
"""

from __future__ import annotations

import ctypes
import faulthandler
import sys
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from types import FrameType, TracebackType
from typing import Any

from rclpy.node import Node

TEARDOWN_LIMIT_S = 3.0
"""Longest the middleware's part of the cleanup may take (below the supervisors' 5 s)."""

_CLOCK_MONOTONIC = 1
_SIGEV_THREAD = 2
_MESSAGE_TO_EXIT_S = 0.05
"""Between the message and ``_exit``: the message thread writes before the process ends."""
_AFTER_THE_STACKS_S = 0.1
"""The exit comes this long after the stack dump, so the message can point at the stacks."""


class _Timespec(ctypes.Structure):
    _fields_ = [("tv_sec", ctypes.c_long), ("tv_nsec", ctypes.c_long)]


class _Itimerspec(ctypes.Structure):
    _fields_ = [("it_interval", _Timespec), ("it_value", _Timespec)]


class _Sigevent(ctypes.Structure):
    """glibc's ``struct sigevent`` (64 bytes) with the ``SIGEV_THREAD`` members."""

    _fields_ = [
        ("sigev_value", ctypes.c_void_p),
        ("sigev_signo", ctypes.c_int),
        ("sigev_notify", ctypes.c_int),
        ("sigev_notify_function", ctypes.c_void_p),
        ("sigev_notify_attributes", ctypes.c_void_p),
        ("_pad", ctypes.c_byte * 32),
    ]


class NativeExitTimer:
    """``perror(message)`` then ``_exit(0)`` after ``delay_s``, from C library threads.

    Each ``SIGEV_THREAD`` notify function gets ``sigev_value``: the message's address for
    ``perror``, 0 for ``_exit``. Raises ``OSError`` where the C library has no such timers.
    """

    def __init__(self, delay_s: float, message: str) -> None:
        libc = ctypes.CDLL(None, use_errno=True)
        self._create, self._settime, self._delete = (
            libc.timer_create,
            libc.timer_settime,
            libc.timer_delete,
        )
        self._delete.argtypes = [ctypes.c_void_p]
        self._message = ctypes.create_string_buffer(message.encode())  # alive while armed
        self._timers: list[ctypes.c_void_p] = []
        try:
            for function, value, at_s in (
                (libc.perror, ctypes.addressof(self._message), delay_s),
                (libc._exit, 0, delay_s + _MESSAGE_TO_EXIT_S),
            ):
                self._start(ctypes.cast(function, ctypes.c_void_p).value, value, at_s)
        except OSError:
            self.cancel()
            raise

    def _start(self, function: Any, value: int, at_s: float) -> None:
        event = _Sigevent(sigev_value=value, sigev_notify=_SIGEV_THREAD)
        event.sigev_notify_function = function
        timer = ctypes.c_void_p()
        if self._create(_CLOCK_MONOTONIC, ctypes.byref(event), ctypes.byref(timer)) != 0:
            raise OSError(ctypes.get_errno(), "timer_create failed")
        self._timers.append(timer)
        sec = int(at_s)
        spec = _Itimerspec(it_value=_Timespec(sec, int((at_s - sec) * 1e9)))
        if self._settime(timer, 0, ctypes.byref(spec), None) != 0:
            raise OSError(ctypes.get_errno(), "timer_settime failed")

    def cancel(self) -> None:
        """Delete the timers (a deleted timer never fires)."""
        while self._timers:
            self._delete(self._timers.pop())


class TeardownGuard:
    """Bounds the middleware's part of a node process's teardown (see the module docstring).

    ``with TeardownGuard(nodes) as guard:``, :meth:`destroying` before each node's
    ``destroy_node``, :meth:`middleware` around ``rclpy.try_shutdown``. ``enabled=False`` (off
    the main thread) makes it do nothing: the exit and the stack dump are process-wide.
    """

    _RCLPY_DESTROY = Node.destroy_node.__code__

    def __init__(self, nodes: Sequence[Node], enabled: bool = True) -> None:
        self.nodes = list(nodes)
        self.enabled = enabled
        self.current: Node | None = None
        """The node being destroyed; ``None`` before the first and after the last."""
        self.name = "rclpy"
        self._exit: NativeExitTimer | None = None
        self._previous_profile: Any = None
        self.unavailable = False
        """The C library has no POSIX timers: a hang is left to the supervisor."""
        self.armed = 0
        """How many times the exit timer was armed (a test hook)."""

    def __enter__(self) -> TeardownGuard:
        if self.enabled:
            faulthandler.dump_traceback_later(TEARDOWN_LIMIT_S, exit=False)
            self._previous_profile = sys.getprofile()  # put back afterwards (e.g. cProfile's)
            sys.setprofile(self._profile)
        return self

    def __exit__(
        self,
        kind: type[BaseException] | None,
        err: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        if self.enabled:
            sys.setprofile(self._previous_profile)
            faulthandler.cancel_dump_traceback_later()
            self._disarm()

    def destroying(self, node: Node | None) -> None:
        """``node`` is destroyed next (``None``: all are)."""
        self.current = node
        if node is not None:
            try:
                self.name = node.get_name()
            except Exception:  # rclpy's InvalidHandle once its context is shut down
                self.name = "node"

    @contextmanager
    def middleware(self) -> Iterator[None]:
        """Around a step that is the middleware's alone (``rclpy.try_shutdown``)."""
        self._arm()
        try:
            yield
        finally:
            self._disarm()

    def _profile(self, frame: FrameType, event: str, _arg: Any) -> None:
        if frame.f_code is not self._RCLPY_DESTROY or not self.nodes:
            return
        if self.current is not self.nodes[-1]:
            return
        if event == "call":
            self._arm()
        elif event == "return":
            self._disarm()

    def _arm(self) -> None:
        if not self.enabled or self.unavailable or self._exit is not None:
            return
        sys.stdout.flush()  # _exit flushes nothing
        sys.stderr.flush()
        message = (
            f"[{self.name}] rclpy's teardown hung for {TEARDOWN_LIMIT_S:g} s after every "
            "node's own cleanup (stacks above): exiting with 0 without it"
        )
        try:
            self._exit = NativeExitTimer(TEARDOWN_LIMIT_S + _AFTER_THE_STACKS_S, message)
        except (OSError, AttributeError) as err:  # no POSIX timers: left to the supervisor
            print(f"[{self.name}] no teardown guard: {err}", file=sys.stderr, flush=True)
            self.unavailable = True
            return
        self.armed += 1

    def _disarm(self) -> None:
        if self._exit is not None:
            self._exit.cancel()
            self._exit = None
