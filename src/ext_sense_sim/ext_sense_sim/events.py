"""NUSkin events as parallel arrays, one row per event."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np


class EventBatch(NamedTuple):
    """Events of a batch of trials, sorted by ``(trial, t_ns)``.

    Attributes:
        trial: Trial index (within the batch or the run, as stated), ``int32``.
        t_ns: Time from the trial origin, integer nanoseconds, ``int64``.
        taxel: Taxel id 1..80, ``uint16``.
        polarity: +1 rising pressure, -1 falling, ``int8``.
        value: The receiver's 10-bit value field, 0..1023, ``uint16``.
    """

    trial: np.ndarray
    t_ns: np.ndarray
    taxel: np.ndarray
    polarity: np.ndarray
    value: np.ndarray

    @classmethod
    def empty(cls) -> EventBatch:
        """No events."""
        return cls(
            np.zeros(0, np.int32),
            np.zeros(0, np.int64),
            np.zeros(0, np.uint16),
            np.zeros(0, np.int8),
            np.zeros(0, np.uint16),
        )

    def sorted(self) -> EventBatch:
        """The same events ordered by trial, then time (stable)."""
        order = np.lexsort((self.t_ns, self.trial))
        return EventBatch(*(a[order] for a in self))

    def merged(self, other: EventBatch) -> EventBatch:
        """Both sets of events, sorted."""
        return EventBatch(
            *(np.concatenate([a, b]) for a, b in zip(self, other, strict=True))
        ).sorted()

    def select(self, mask: np.ndarray) -> EventBatch:
        """The events where ``mask`` is true."""
        return EventBatch(*(a[mask] for a in self))

    def offset_trials(self, first: int) -> EventBatch:
        """Trial indices shifted by ``first`` (batch-local to run-wide)."""
        return self._replace(trial=(self.trial + first).astype(np.int32))

    def last_values(self, n_trials: int) -> np.ndarray:
        """Value of each taxel's last event per trial (0 when none), ``(n_trials, 80)``."""
        out = np.zeros((n_trials, 80), dtype=np.uint16)
        out[self.trial, self.taxel.astype(np.intp) - 1] = self.value  # later rows win
        return out
