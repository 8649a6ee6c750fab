"""A stream's stalls: silence past a WARN threshold, then past an ERROR one, ended by data.

Shared by the drivers' and the window node's liveness, so stall levels and counts mean the
same on every ``/diagnostics`` status. Times are monotonic integer ns given by the caller.
"""

from __future__ import annotations

from dataclasses import dataclass

from ext_sense_runtime.diagnostics import Level


@dataclass
class StallTracker:
    """The stall in progress, if any, and the stalls so far.

    Args:
        warn_ns: Silence that is a stall (WARN); the caller decides when it has passed.
        error_ns: Silence that makes the stall an ERROR.
    """

    warn_ns: int
    error_ns: int
    stalls: int = 0
    longest_stall_ns: int = 0
    stalled_since_ns: int | None = None
    """When the silence of the stall in progress began, ``None`` when not stalled."""

    @property
    def stalled(self) -> bool:
        """Whether a stall is in progress."""
        return self.stalled_since_ns is not None

    def begin(self, silent_since_ns: int) -> bool:
        """A stall began (its silence since ``silent_since_ns``); False if one is in progress."""
        if self.stalled_since_ns is not None:
            return False
        self.stalls += 1
        self.stalled_since_ns = int(silent_since_ns)
        return True

    def end(self, now_ns: int) -> int | None:
        """Data returned at ``now_ns``: the stall's length (kept if the longest), or ``None``."""
        if self.stalled_since_ns is None:
            return None
        silent = int(now_ns) - self.stalled_since_ns
        self.longest_stall_ns = max(self.longest_stall_ns, silent)
        self.stalled_since_ns = None
        return silent

    def drop(self) -> None:
        """Forget the stall in progress without measuring it (the stream is no longer due)."""
        self.stalled_since_ns = None

    def level(self, now_ns: int) -> Level:
        """OK when not stalled, ERROR once silent past ``error_ns``, else WARN."""
        if self.stalled_since_ns is None:
            return Level.OK
        return Level.ERROR if int(now_ns) - self.stalled_since_ns > self.error_ns else Level.WARN


class StallCounts:
    """The stall counters of a liveness that keeps its stalls in ``stall``, for its readers."""

    stall: StallTracker

    @property
    def stalls(self) -> int:
        """Stalls so far."""
        return self.stall.stalls

    @property
    def longest_stall_ns(self) -> int:
        """The longest stall that has ended, ns."""
        return self.stall.longest_stall_ns
