"""Device-side links of the emulated devices: a pseudo-terminal with a FIFO, or a CAN sink."""

from __future__ import annotations

import contextlib
import os
import select
import threading
import time
from collections import deque
from pathlib import Path

from ext_sense_drivers.transports.scheduling import raise_thread_priority
from ext_sense_sim.errors import SceneError


class PtyLink:
    """A pseudo-terminal in raw mode: the emulator writes the master, a driver opens the slave.

    A pty buffers only about 4 KiB, less than a tap's burst, so bytes go through a device-side
    FIFO (like a receiver's UART buffer) that a writer thread, at SCHED_FIFO ``priority`` (0: as
    it is), drains as fast as the reader takes them. Bytes older than ``max_backlog_s`` (nobody
    reading) are dropped and counted in ``dropped_bytes``. ``link``: a symlink to the slave.
    """

    def __init__(
        self, link: str | Path | None = None, max_backlog_s: float = 0.1, priority: int = 0
    ) -> None:
        import tty

        if not max_backlog_s > 0:
            raise SceneError(
                f"The 'max_backlog_s' parameter must be > 0. Got {max_backlog_s!r} instead."
            )
        self.master, self._slave = os.openpty()
        tty.setraw(self._slave)
        os.set_blocking(self.master, False)
        self.dropped_bytes = 0
        self.max_backlog_ns = round(max_backlog_s * 1e9)
        self.priority = priority
        self.path = os.ttyname(self._slave)
        self.link = Path(link) if link else None
        if self.link is not None:
            if self.link.is_symlink() or self.link.exists():
                self.link.unlink()
            self.link.symlink_to(self.path)
        self._fifo: deque[tuple[int, bytes]] = deque()
        self._backlog = 0
        self._cond = threading.Condition()
        self._closed = False
        self._writer = threading.Thread(target=self._drain, name="pty_writer", daemon=True)
        self._writer.start()

    @property
    def backlog_bytes(self) -> int:
        """Bytes waiting in the FIFO."""
        return self._backlog

    def write(self, data: bytes) -> int:
        """Queue ``data`` for the pty without blocking.

        Returns:
            Bytes accepted (all of them; stale ones are dropped later and counted).
        """
        if data:
            with self._cond:
                self._fifo.append((time.monotonic_ns(), bytes(data)))
                self._backlog += len(data)
                self._cond.notify()
        return len(data)

    def _drop_stale(self, now_ns: int) -> None:
        while self._fifo and now_ns - self._fifo[0][0] > self.max_backlog_ns:
            _, old = self._fifo.popleft()
            self._backlog -= len(old)
            self.dropped_bytes += len(old)

    def _drain(self) -> None:
        raise_thread_priority(self.priority)
        while True:
            with self._cond:
                while not self._fifo and not self._closed:
                    self._cond.wait()
                if self._closed:
                    return
                self._drop_stale(time.monotonic_ns())
                if not self._fifo:
                    continue
                stamp, data = self._fifo[0]
            try:
                select.select([], [self.master], [], 0.002)
                n = os.write(self.master, data)
            except BlockingIOError:
                n = 0
            except OSError:  # closed underneath us
                return
            with self._cond:
                if n:
                    self._fifo.popleft()
                    self._backlog -= n
                    if n < len(data):
                        self._fifo.appendleft((stamp, data[n:]))
            if not n:
                time.sleep(0.0002)

    def close(self) -> None:
        """Stop the writer, close both ends and remove the symlink."""
        with self._cond:
            self._closed = True
            self._cond.notify()
        self._writer.join(timeout=1.0)
        for fd in (self.master, self._slave):
            with contextlib.suppress(OSError):
                os.close(fd)
        if self.link is not None and self.link.is_symlink():
            self.link.unlink()


def open_link(
    kind: str, *, link_path: str = "", can_channel: str = "", can_id: int = 0x100, priority: int = 0
):
    """A pty (writer at ``priority``) or a python-can virtual channel sink: ``write``, ``close``."""
    if kind == "pty":
        return PtyLink(link_path or None, priority=priority)
    if kind == "can":
        from ext_sense_drivers.transports.can_bus import CanSink

        return CanSink("virtual", can_channel or "ext_sense", can_id)
    raise SceneError(f"The 'link' parameter must be 'pty' or 'can'. Got {kind!r} instead.")
