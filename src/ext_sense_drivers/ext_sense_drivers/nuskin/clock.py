"""Stamping receiver words with host time: the words carry none.

The reader takes a host timestamp right after every read returns (:class:`Chunk.t_ns`). All
bytes of one read arrived at the host after the previous read returned and before this one did,
so :class:`ArrivalClock` spreads the words a read completed evenly over that interval, the last
word at the read's own time::

    t_k = t_prev + (k + 1) * (t_read - t_prev) // n        k = 0..n-1

Error bound: with a receiver that sends each word as it happens, a word's stamp and its true
arrival at the host lie in the same interval ``(t_prev, t_read]``, so the stamp error is less
than the read interval ``t_read - t_prev``. While events flow, a read returns as soon as a byte is
waiting, so the interval is the reader loop's period (tens of microseconds to about a
millisecond; docs/nuskin.md); after an idle line the interval can be
as long as the read timeout, so the spread is capped at ``max_spread_ns`` (default: the time the
serial link needs to carry the read's bytes, but at least 1 ms): bursts after silence are then
stamped within the cap before the read. The constant latency from the taxel to the host (receiver
buffering, USB) is not modelled; it is an offset, not a spread.

Stamps are integer nanoseconds, never decrease, and a read stamped earlier than the previous one
(a clock that stepped back) is clamped to the previous read.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from ext_sense_drivers.nuskin.errors import NuskinError

BITS_PER_BYTE_ON_WIRE = 10
"""8N1 serial framing: start bit, 8 data bits, stop bit."""


class ArrivalClock:
    """Spreads the words of each read over the interval since the previous read.

    Args:
        byte_time_ns: Time one byte takes on the link, ns (``1e10 / baud`` for 8N1), > 0; sets
            the cap on the spread (see the module docstring).
        min_spread_ns: The cap is never below this, ns.
    """

    def __init__(self, byte_time_ns: int = 10_000, min_spread_ns: int = 1_000_000) -> None:
        if int(byte_time_ns) <= 0:
            raise NuskinError(
                f"The 'byte_time_ns' parameter must be > 0. Got {byte_time_ns} instead."
            )
        if int(min_spread_ns) < 0:
            raise NuskinError(
                f"The 'min_spread_ns' parameter must be >= 0. Got {min_spread_ns} instead."
            )
        self.byte_time_ns = int(byte_time_ns)
        self.min_spread_ns = int(min_spread_ns)
        self._last_read_ns: int | None = None
        self._last_stamp_ns: int | None = None

    @classmethod
    def for_baud(cls, baud: int, min_spread_ns: int = 1_000_000) -> ArrivalClock:
        """A clock for an 8N1 serial link at ``baud`` bit/s."""
        if int(baud) <= 0:
            raise NuskinError(f"The 'baud' parameter must be > 0. Got {baud} instead.")
        return cls(max(1, BITS_PER_BYTE_ON_WIRE * 1_000_000_000 // int(baud)), min_spread_ns)

    def stamp(
        self, n_words: int, read_ns: int, n_bytes: int | None = None
    ) -> npt.NDArray[np.int64]:
        """Stamps for the ``n_words`` words completed by a read that returned at ``read_ns``.

        Args:
            n_words: Words the read completed (may be 0: the read still moves the clock).
            read_ns: Host time the read returned, integer ns.
            n_bytes: Bytes the read carried (sets the cap); ``4 * n_words`` when omitted.

        Returns:
            ``(n_words,)`` int64 stamps, non-decreasing, the last one at the read time.
        """
        read_ns = int(read_ns)
        n = int(n_words)
        for floor in (self._last_read_ns, self._last_stamp_ns):
            if floor is not None and read_ns < floor:
                read_ns = floor  # the host clock stepped back: never go back with it
        cap = max(
            self.min_spread_ns, (4 * n if n_bytes is None else int(n_bytes)) * self.byte_time_ns
        )
        start = (
            read_ns - cap if self._last_read_ns is None else max(self._last_read_ns, read_ns - cap)
        )
        if self._last_stamp_ns is not None:
            start = max(start, self._last_stamp_ns)
        self._last_read_ns = read_ns
        if n <= 0:
            return np.empty(0, np.int64)
        span = read_ns - start
        stamps = start + (np.arange(1, n + 1, dtype=np.int64) * span) // n
        self._last_stamp_ns = int(stamps[-1])
        return stamps
