"""Stamping receiver words with host time: the words carry none.

The bytes of a read arrived between the previous read's return and its own, so
:class:`ArrivalClock` spreads its words evenly over that interval, the last at the read::

    t_k = t_prev + (k + 1) * (t_read - t_prev) // n        k = 0..n-1

The stamp error is below the read interval. After silence the spread is capped (the link time
of the read's bytes, at least 1 ms). Stamps are integer ns and never decrease.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from ext_sense_drivers.nuskin.errors import NuskinError

BITS_PER_BYTE_ON_WIRE = 10
"""8N1 serial framing: start bit, 8 data bits, stop bit."""


class ArrivalClock:
    """Spreads the words of each read over the interval since the previous read.

    The spread is capped at the link time of the read's bytes (``byte_time_ns`` each), never
    below ``min_spread_ns``.
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
        """Stamps ``(n_words,)`` int64 for the words a read returning at ``read_ns`` completed.

        ``n_bytes`` (default ``4 * n_words``) sets the cap; a read of no words moves the clock.
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
