"""A reader thread that owns one transport, reconnects with backoff and queues what arrives.

Reads never block the executor; the state and counters are plain attributes written by the
thread alone.
"""

from __future__ import annotations

import logging
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass

from ext_sense_drivers.transports.base import Chunk, LinkState, Transport
from ext_sense_drivers.transports.errors import TransportError
from ext_sense_drivers.transports.scheduling import Scheduling, raise_thread_priority

_log = logging.getLogger(__name__)

DRAINER_STEP = 10
"""The thread that starts (and drains) a reader runs this many FIFO steps below the reader."""


@dataclass(frozen=True)
class Backoff:
    """Exponential reconnect delays: ``initial_s``, then times ``factor`` up to ``max_s``."""

    initial_s: float = 0.1
    max_s: float = 5.0
    factor: float = 2.0

    def __post_init__(self) -> None:
        if not self.initial_s > 0:
            raise TransportError(
                f"The 'initial_s' parameter must be > 0. Got {self.initial_s} instead."
            )
        if not self.max_s >= self.initial_s:
            raise TransportError(
                f"The 'max_s' parameter must be >= initial_s ({self.initial_s}). "
                f"Got {self.max_s} instead."
            )
        if not self.factor >= 1:
            raise TransportError(f"The 'factor' parameter must be >= 1. Got {self.factor} instead.")

    def delay(self, failures: int) -> float:
        """Seconds to wait after ``failures`` consecutive failures (1 = the first)."""
        return min(self.max_s, self.initial_s * self.factor ** max(0, failures - 1))


class StreamReader:
    """Runs ``transport`` in a daemon thread; :meth:`drain` hands over what arrived.

    On a :class:`TransportError` the thread closes the transport, waits the backoff delay and
    retries until :meth:`stop`; an exhausted file ends it in :attr:`LinkState.EXHAUSTED`. Past
    ``max_pending_bytes`` queued the oldest chunks are dropped (:attr:`dropped_bytes`).

    ``read_timeout_s`` bounds how late :meth:`stop` acts; ``on_data`` is called from the thread
    after each queued chunk (quick, never raising). ``priority``: SCHED_FIFO asked for (0: leave
    as is; refused, a raised nice or nothing, see :attr:`scheduling`), as how soon the thread
    runs after a read is the stamp's error; the thread calling :meth:`start` is raised
    :data:`DRAINER_STEP` lower, since a preempted drainer holding the GIL would stall the reader.
    """

    def __init__(
        self,
        transport: Transport,
        *,
        backoff: Backoff | None = None,
        read_timeout_s: float = 0.2,
        max_pending_bytes: int = 16 << 20,
        on_data: Callable[[], None] | None = None,
        priority: int = 0,
    ) -> None:
        self.transport = transport
        self.backoff = backoff or Backoff()
        self.read_timeout_s = float(read_timeout_s)
        self.max_pending_bytes = int(max_pending_bytes)
        self.on_data = on_data
        self.priority = int(priority)
        self.scheduling: Scheduling | None = None
        """What the reader thread got (None until it started)."""
        self.drainer_scheduling: Scheduling | None = None
        """What the thread that called :meth:`start` got (None: not asked, priority 0)."""
        self._queue: deque[tuple[int, Chunk]] = deque()
        self._pending = 0
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self.state = LinkState.STOPPED
        self.bytes_total = 0
        self.chunks_total = 0
        self.connects = 0
        """Successful opens."""
        self.connected_ns: int | None = None
        """When the last open succeeded, ``time.monotonic_ns`` (None before the first)."""
        self.disconnects = 0
        """Open links lost to a TransportError."""
        self.open_failures = 0
        self.dropped_bytes = 0
        self.last_error = ""
        self.failures_in_row = 0

    @property
    def description(self) -> str:
        """The transport's description (the diagnostics hardware_id)."""
        return self.transport.description

    def start(self) -> None:
        """Start the thread (once); with a priority, raise the calling thread too (see above)."""
        if self._thread is not None:
            return
        if self.priority > 0:
            self.drainer_scheduling = raise_thread_priority(max(1, self.priority - DRAINER_STEP))
            self._report("draining thread", self.drainer_scheduling)
        self._stop.clear()
        self._thread = threading.Thread(
            target=self._run, name=f"reader {self.description}", daemon=True
        )
        self._thread.start()

    def stop(self, timeout_s: float = 2.0) -> None:
        """Ask the thread to end, wait for it, and close the transport."""
        self._stop.set()
        thread, self._thread = self._thread, None
        if thread is not None:
            thread.join(timeout_s)
        self.transport.close()
        self.state = LinkState.STOPPED

    def drain(self) -> list[Chunk]:
        """Every chunk queued since the last call, oldest first."""
        return [chunk for _, chunk in self.drain_tagged()]

    def drain_tagged(self) -> list[tuple[int, Chunk]]:
        """Like :meth:`drain`, each chunk with the connection it came on (1 = the first open)."""
        with self._lock:
            tagged = list(self._queue)
            self._queue.clear()
            self._pending = 0
        return tagged

    @property
    def queued_chunks(self) -> int:
        """Chunks waiting for :meth:`drain`."""
        return len(self._queue)

    @property
    def alive(self) -> bool:
        """Whether the reader thread runs."""
        return self._thread is not None and self._thread.is_alive()

    def _run(self) -> None:
        self.scheduling = raise_thread_priority(self.priority)  # in the thread itself
        self._report("reader thread", self.scheduling)
        while not self._stop.is_set():
            self.state = LinkState.CONNECTING
            try:
                self.transport.open()
            except TransportError as err:
                self.open_failures += 1
                self._fail(err)
                continue
            self.connected_ns = time.monotonic_ns()
            self.connects += 1
            self.failures_in_row = 0
            self.state = LinkState.CONNECTED
            try:
                self._pump()
            except TransportError as err:
                self.disconnects += 1
                self._fail(err)
                continue
            if self.transport.exhausted:
                self.state = LinkState.EXHAUSTED
                return
        self.transport.close()

    def _report(self, which: str, got: Scheduling) -> None:
        if got.requested and not got.granted:
            _log.warning("%s of %s: %s", which, self.description, got.describe())
        elif got.requested:
            _log.info("%s of %s: %s", which, self.description, got.describe())

    def _pump(self) -> None:
        while not self._stop.is_set():
            chunk = self.transport.read(self.read_timeout_s)
            if chunk.data:
                self._push(chunk)
            elif self.transport.exhausted:
                return

    def _push(self, chunk: Chunk) -> None:
        with self._lock:
            self._queue.append((self.connects, chunk))
            self._pending += len(chunk.data)
            while self._pending > self.max_pending_bytes and len(self._queue) > 1:
                _, old = self._queue.popleft()
                self._pending -= len(old.data)
                self.dropped_bytes += len(old.data)
        self.bytes_total += len(chunk.data)
        self.chunks_total += 1
        on_data = self.on_data
        if on_data is not None:
            on_data()

    def _fail(self, err: TransportError) -> None:
        self.transport.close()
        self.last_error = str(err)
        self.failures_in_row += 1
        self.state = LinkState.BACKOFF
        self._stop.wait(self.backoff.delay(self.failures_in_row))
