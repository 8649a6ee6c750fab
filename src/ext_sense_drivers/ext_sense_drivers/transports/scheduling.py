"""The best scheduling the machine allows for one thread: SCHED_FIFO, else a raised nice.

The reader stamps each read when it returns, so its wait for a core is stamp error
(docs/benchmarks.md, "Reader priority and the arrival clock"). SCHED_FIFO needs
``CAP_SYS_NICE`` or ``RLIMIT_RTPRIO``, a lower nice ``CAP_SYS_NICE`` or ``RLIMIT_NICE``;
:func:`raise_thread_priority` tries them in turn and never raises. Linux semantics.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable
from typing import NamedTuple

FALLBACK_NICE = -10
"""Nice asked for when SCHED_FIFO is refused (clamped to what ``RLIMIT_NICE`` allows)."""

MAX_FIFO_PRIORITY = 99
"""Linux's highest SCHED_FIFO priority."""


class Scheduling(NamedTuple):
    """What a thread got: ``policy`` fifo, nice or default, and why it is not what was asked.

    ``value``: the FIFO priority (1-99), the nice value, or 0; ``requested``: 0 when none was.
    """

    policy: str
    value: int
    requested: int
    reason: str = ""

    @property
    def granted(self) -> bool:
        """Whether the thread got the SCHED_FIFO priority asked for."""
        return self.policy == "fifo" and self.value == self.requested

    def describe(self) -> str:
        """One line for a log or a diagnostics value."""
        if self.policy == "fifo":
            got = f"SCHED_FIFO {self.value}"
        elif self.policy == "nice":
            got = f"SCHED_OTHER nice {self.value}"
        else:
            got = "default scheduling"
        if self.requested <= 0:
            return f"{got} (reader_priority 0: left as is)"
        if self.granted:
            return got
        return f"{got} (asked SCHED_FIFO {self.requested}: {self.reason})"


def _rlimit(name: str) -> int | None:
    """The soft limit ``RLIMIT_<name>``, or None where the platform has none."""
    try:
        import resource

        soft, _ = resource.getrlimit(getattr(resource, f"RLIMIT_{name}"))
    except (ImportError, AttributeError, OSError, ValueError):
        return None
    return None if soft == getattr(resource, "RLIM_INFINITY", -1) else int(soft)


def _set_fifo(tid: int, priority: int) -> None:
    # reset on fork: a process started from this thread (e.g. the simulator's trials-ahead
    # child) runs at normal priority instead of inheriting real time
    policy = os.SCHED_FIFO | getattr(os, "SCHED_RESET_ON_FORK", 0)
    os.sched_setscheduler(tid, policy, os.sched_param(priority))


def _set_nice(tid: int, nice: int) -> None:
    os.setpriority(os.PRIO_PROCESS, tid, nice)


def _get_nice(tid: int) -> int:
    return os.getpriority(os.PRIO_PROCESS, tid)


def raise_thread_priority(
    priority: int,
    *,
    tid: int | None = None,
    fallback_nice: int = FALLBACK_NICE,
    set_fifo: Callable[[int, int], None] = _set_fifo,
    set_nice: Callable[[int, int], None] = _set_nice,
    get_nice: Callable[[int], int] = _get_nice,
) -> Scheduling:
    """Give thread ``tid`` SCHED_FIFO at ``priority``, else the best nice allowed, else nothing.

    A priority above a non-zero ``RLIMIT_RTPRIO`` is tried at the limit too; 0 or less leaves the
    thread as it is; ``fallback_nice`` is asked for when SCHED_FIFO is refused. ``tid`` defaults
    to the calling thread; ``set_fifo``, ``set_nice`` and ``get_nice`` are injectable. Never raises.
    """
    requested = min(int(priority), MAX_FIFO_PRIORITY)
    if requested <= 0:
        return Scheduling("default", 0, 0)
    tid = threading.get_native_id() if tid is None else int(tid)
    rtprio = _rlimit("RTPRIO")
    tries = [requested]
    if rtprio is not None and 0 < rtprio < requested:
        tries.append(rtprio)  # without CAP_SYS_NICE the limit is the ceiling
    reason = ""
    for prio in tries:
        try:
            set_fifo(tid, prio)
        except (OSError, AttributeError, ValueError) as err:
            reason = f"SCHED_FIFO refused ({type(err).__name__}: {err}; RLIMIT_RTPRIO {rtprio})"
            continue
        if prio == requested:
            return Scheduling("fifo", prio, requested)
        return Scheduling("fifo", prio, requested, f"RLIMIT_RTPRIO is {rtprio}")
    return _fallback(tid, requested, reason, fallback_nice, set_nice, get_nice)


def _fallback(
    tid: int,
    requested: int,
    reason: str,
    fallback_nice: int,
    set_nice: Callable[[int, int], None],
    get_nice: Callable[[int], int],
) -> Scheduling:
    """The nice step of :func:`raise_thread_priority`: the lowest nice allowed, if below now."""
    try:
        current = int(get_nice(tid))
    except (OSError, AttributeError) as err:
        return Scheduling("default", 0, requested, f"{reason}; nice unreadable: {err}")
    nice_limit = _rlimit("NICE")  # RLIMIT_NICE n allows nice down to 20 - n
    tries = [int(fallback_nice)]
    if nice_limit is not None and 20 - nice_limit > int(fallback_nice):
        tries.append(20 - nice_limit)
    for nice in tries:
        if nice >= current:
            continue
        try:
            set_nice(tid, nice)
        except (OSError, AttributeError) as err:
            reason = f"{reason}; nice {nice} refused ({type(err).__name__})"
            continue
        return Scheduling("nice", nice, requested, reason)
    return Scheduling("default", 0, requested, f"{reason}; nice left at {current}")
