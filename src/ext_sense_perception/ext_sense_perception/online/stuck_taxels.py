"""Stuck or saturated NUSkin taxels: per-taxel event rates on stream time (no ROS).

A taxel firing near its ceiling (a shorted pad) passes any event-count onset test every few
milliseconds; a real contact is short and wide. A taxel at ``rate_hz`` or more for longer than
``after_ns`` is *stuck*, ignored by onset detection until a whole bucket falls below half the
rate. Rates are counted in fixed buckets of stream time, one ``bincount`` per block.
"""

from __future__ import annotations

import numpy as np

from ext_sense_perception.errors import PerceptionError
from ext_sense_runtime.stamps import MS

BUCKET_NS = 100 * MS
"""Stream time over which each taxel's rate is counted."""


class StuckTaxels:
    """Which taxels (ids ``1..n_taxels``) are stuck, rates counted over ``bucket_ns`` (see module).

    PerceptionError: a non-positive rate, time or bucket.
    """

    def __init__(
        self, n_taxels: int, rate_hz: float, after_ns: int, bucket_ns: int = BUCKET_NS
    ) -> None:
        for name, value in (("rate_hz", rate_hz), ("after_ns", after_ns), ("bucket_ns", bucket_ns)):
            if not value > 0:
                raise PerceptionError(f"The {name!r} parameter must be > 0. Got {value!r} instead.")
        self.rate_hz = float(rate_hz)
        self.after_ns = int(after_ns)
        self.bucket_ns = int(bucket_ns)
        self._busy_min = self.rate_hz * self.bucket_ns / 1e9
        size = int(n_taxels) + 1  # index: taxel id (0 unused)
        self._counts = np.zeros(size, np.int64)
        self._busy_ns = np.zeros(size, np.int64)
        self.stuck = np.zeros(size, bool)
        """Per taxel id: whether it is stuck now (index 0 unused)."""
        self.last_rate_hz = np.zeros(size)
        """Per taxel id: its rate over the last full bucket, events/s."""
        self._bucket_end: int | None = None
        self.masked_events = 0
        """Events of stuck taxels kept from onset detection so far."""

    @property
    def ids(self) -> tuple[int, ...]:
        """Ids of the taxels stuck now."""
        return tuple(int(i) for i in np.flatnonzero(self.stuck))

    def stuck_for_ns(self, taxel: int) -> int:
        """How long a taxel has fired at its ceiling without a pause, ns (whole buckets)."""
        return int(self._busy_ns[taxel])

    def feed(self, t_ns: np.ndarray, taxel: np.ndarray) -> bool:
        """Count a block of events sorted by time; whether the set of stuck taxels changed."""
        if not t_ns.size:
            return False
        if self._bucket_end is None:
            self._bucket_end = int(t_ns[0]) + self.bucket_ns
        changed = False
        lo = 0
        while lo < t_ns.size:
            hi = int(np.searchsorted(t_ns, self._bucket_end, side="left"))
            if hi > lo:
                self._counts += np.bincount(taxel[lo:hi], minlength=self._counts.size)
                lo = hi
            if lo < t_ns.size:  # the block runs past this bucket: close it (and any empty ones)
                changed |= self.advance(int(t_ns[lo]))
        return changed

    def advance(self, now_ns: int) -> bool:
        """Close the buckets that ended by ``now_ns`` (stream time); whether the set changed."""
        if self._bucket_end is None or now_ns < self._bucket_end:
            return False
        changed = self._close()
        self._bucket_end += self.bucket_ns
        if now_ns >= self._bucket_end:  # whole buckets with no events: every taxel quiet
            changed |= self._close()
            self._bucket_end += ((now_ns - self._bucket_end) // self.bucket_ns + 1) * self.bucket_ns
        return changed

    def _close(self) -> bool:
        counts = self._counts
        self.last_rate_hz = counts * (1e9 / self.bucket_ns)
        busy = counts >= self._busy_min
        self._busy_ns = np.where(busy, self._busy_ns + self.bucket_ns, 0)
        now_stuck = (self.stuck | (self._busy_ns >= self.after_ns)) & ~(counts < self._busy_min / 2)
        changed = bool((now_stuck != self.stuck).any())
        self.stuck = now_stuck
        self._counts = np.zeros_like(counts)
        return changed

    def unmasked(self, taxel: np.ndarray) -> np.ndarray | None:
        """The mask of a block's events that onset detection may see (None: all of them)."""
        if not self.stuck.any():
            return None
        keep = ~self.stuck[taxel]
        self.masked_events += int(keep.size - np.count_nonzero(keep))
        return keep
