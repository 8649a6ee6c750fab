"""One guard for every node callback: an exception is caught, counted, logged once, diagnosed.

An exception escaping a callback ends the node's spin, and with it the graph: one malformed
message would stop a session. Guarded (``self.guard(self._on_msg)``), it is counted per
callback, logged once per callback and type, and shown on ``/diagnostics`` (ERROR while
recent, then WARN). No rclpy: the node hands in its logger's ``error``.
"""

from __future__ import annotations

import functools
import inspect
import threading
import time
import traceback
from collections import Counter
from collections.abc import Callable
from typing import Any, TypeVar

from ext_sense_runtime.diagnostics import Clock, Level, StatusTask, Updater

F = TypeVar("F", bound=Callable[..., Any])

RECENT_NS = 10_000_000_000
"""An exception younger than this (10 s) keeps the status at ERROR; older ones leave a WARN."""


class CallbackGuard:
    """``log`` gets the first exception of each (callback, type); ``clock``: monotonic ns."""

    def __init__(
        self,
        log: Callable[[str], object],
        clock: Clock = time.monotonic_ns,
        recent_ns: int = RECENT_NS,
    ) -> None:
        self._log = log
        self._clock = clock
        self._recent_ns = int(recent_ns)
        self._lock = threading.Lock()
        self._logged: set[tuple[str, str]] = set()
        self.counts: Counter[str] = Counter()
        """Exceptions caught per callback name."""
        self.last_cause = ""
        """The last exception caught, as ``"<callback>: <Type>: <message> (at file:line)"``."""
        self.last_ns: int | None = None
        """When the last exception was caught (``clock`` time), ``None`` before."""

    @property
    def total(self) -> int:
        """Exceptions caught so far, over all callbacks."""
        return sum(self.counts.values())

    def __call__(self, fn: F) -> F:
        """Same as :meth:`wrap` with the function's own name (usable as a decorator)."""
        return self.wrap(fn)

    def wrap(
        self,
        fn: F,
        name: str | None = None,
        fallback: Callable[[Exception], Any] | None = None,
    ) -> F:
        """Return ``fn`` guarded: its exceptions are caught and reported, it returns ``None``.

        Coroutine functions get an async wrapper; ``KeyboardInterrupt`` and ``SystemExit``
        pass. ``name`` (default ``fn.__name__``) is shown in the log and on ``/diagnostics``;
        ``fallback(err)`` gives the return value after an exception (an on-set callback needs
        one: :func:`~.parameters.refused`).
        """
        label = name or getattr(fn, "__name__", None) or repr(fn)
        if inspect.iscoroutinefunction(fn):

            @functools.wraps(fn)
            async def guarded_async(*args: Any, **kwargs: Any) -> Any:
                try:
                    return await fn(*args, **kwargs)
                except Exception as err:
                    self.caught(label, err)
                    return None if fallback is None else fallback(err)

            return guarded_async  # type: ignore[return-value]

        @functools.wraps(fn)
        def guarded(*args: Any, **kwargs: Any) -> Any:
            try:
                return fn(*args, **kwargs)
            except Exception as err:
                self.caught(label, err)
                return None if fallback is None else fallback(err)

        return guarded  # type: ignore[return-value]

    def caught(self, callback: str, err: BaseException) -> None:
        """Count, and log the first of its kind, an exception caught in ``callback``."""
        cause = f"{callback}: {describe(err)}"
        key = (callback, type(err).__name__)
        with self._lock:
            self.counts[callback] += 1
            self.last_cause = cause
            self.last_ns = self._clock()
            first = key not in self._logged
            self._logged.add(key)
        if first:
            self._log(
                f"exception in callback {cause}; the node goes on, further "
                f"{type(err).__name__}s of {callback} are only counted on /diagnostics"
            )

    def check(self) -> tuple[Level, str, dict[str, object]]:
        """The diagnostics check: ERROR while exceptions are recent, WARN after, OK if none."""
        with self._lock:
            counts = dict(self.counts)
            last_ns, cause = self.last_ns, self.last_cause
        total = sum(counts.values())
        values: dict[str, object] = {"exceptions_total": total, "last_exception": cause}
        values.update({f"exceptions_{name}": n for name, n in sorted(counts.items())})
        if last_ns is None:
            return Level.OK, "no exception in callbacks", values
        age_ns = self._clock() - last_ns
        values["last_exception_age_s"] = f"{age_ns / 1e9:.1f}"
        if age_ns < self._recent_ns:
            return Level.ERROR, f"{total} exception(s) in callbacks, last {cause}", values
        return Level.WARN, f"{total} exception(s) in callbacks, none recently", values

    def attach(self, updater: Updater, name: str = "callbacks") -> StatusTask:
        """Add this guard's status to a node's diagnostics updater and return the task."""
        return updater.add_check(name, self.check)


def describe(err: BaseException) -> str:
    """``"<Type>: <message> (at <file>:<line> in <function>)"``, the innermost frame."""
    text = f"{type(err).__name__}: {err}" if str(err) else type(err).__name__
    frames = traceback.extract_tb(err.__traceback__) if err.__traceback__ else []
    if frames:
        last = frames[-1]
        file = last.filename.rsplit("/", 1)[-1]
        text += f" (at {file}:{last.lineno} in {last.name})"
    return text
