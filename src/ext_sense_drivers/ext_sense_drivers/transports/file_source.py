"""File byte source: a recorded capture replayed at its recorded pace or flat out."""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path

from ext_sense_drivers.transports.base import Chunk
from ext_sense_drivers.transports.errors import TransportError


class FileTransport:
    """Replays a file's bytes at ``bytes_per_s`` since :meth:`open`, or flat out (``None``).

    Reads return at most ``chunk_size`` bytes. At the end :attr:`exhausted` turns True and reads
    wait their timeout and return nothing, unless ``loop`` starts over. ``clock`` (monotonic ns)
    and ``sleep`` are injectable.
    """

    def __init__(
        self,
        path: str | Path,
        bytes_per_s: float | None = None,
        *,
        chunk_size: int = 4096,
        loop: bool = False,
        clock: Callable[[], int] = time.monotonic_ns,
        sleep: Callable[[float], None] = time.sleep,
    ) -> None:
        if bytes_per_s is not None and not bytes_per_s > 0:
            raise TransportError(
                f"The 'bytes_per_s' parameter must be > 0 or None. Got {bytes_per_s} instead."
            )
        if int(chunk_size) <= 0:
            raise TransportError(
                f"The 'chunk_size' parameter must be > 0. Got {chunk_size} instead."
            )
        self.path = Path(path)
        self.bytes_per_s = None if bytes_per_s is None else float(bytes_per_s)
        self.chunk_size = int(chunk_size)
        self.loop = bool(loop)
        self._clock = clock
        self._sleep = sleep
        self._data: bytes | None = None
        self._pos = 0
        self._sent = 0
        self._t0_ns = 0

    @property
    def description(self) -> str:
        """The file path."""
        return str(self.path)

    @property
    def exhausted(self) -> bool:
        """Whether every byte has been read (never with ``loop``)."""
        return self._data is not None and not self.loop and self._pos >= len(self._data)

    def open(self) -> None:
        """Load the file and start the pace clock."""
        try:
            self._data = self.path.read_bytes()
        except OSError as err:
            raise TransportError(f"cannot read capture file {str(self.path)!r}: {err}") from err
        self._pos = 0
        self._sent = 0
        self._t0_ns = self._clock()

    def read(self, timeout_s: float) -> Chunk:
        """The next bytes that are due."""
        if self._data is None:
            raise TransportError(f"capture file {str(self.path)!r} is not open")
        timeout_s = max(0.0, float(timeout_s))
        if self.exhausted or not self._data:
            self._sleep(timeout_s)
            return Chunk(b"", self._clock())
        limit = self.chunk_size
        if self.bytes_per_s is not None:
            due = self._due() - self._sent
            if due <= 0:
                wait = (self._sent + 1 - self._due()) / self.bytes_per_s
                self._sleep(min(timeout_s, max(0.0, wait)))
                due = self._due() - self._sent
                if due <= 0:
                    return Chunk(b"", self._clock())
            limit = min(limit, due)
        out = bytearray()
        while limit > 0 and not self.exhausted:
            if self._pos >= len(self._data):  # loop
                self._pos = 0
            piece = self._data[self._pos : self._pos + limit]
            out += piece
            self._pos += len(piece)
            limit -= len(piece)
        self._sent += len(out)
        return Chunk(bytes(out), self._clock())

    def _due(self) -> int:
        return int((self._clock() - self._t0_ns) * self.bytes_per_s / 1e9)

    def close(self) -> None:
        """Forget the loaded bytes."""
        self._data = None
