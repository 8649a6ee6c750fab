"""Contact from the arm's external-force estimate: the norm crosses a threshold.

The Panda food-poking protocol stops on a Cartesian collision at 10 N. Here the decision is
taken on each state sample as it arrives, so it fires on the first sample over the threshold
(with ``consecutive`` = 1) and never later than ``consecutive - 1`` samples after it.
"""

from __future__ import annotations

import math

from ext_sense_behaviours.errors import BehaviourError


class ForceContactDetector:
    """Fires when ``|F|`` >= ``threshold_n`` on ``consecutive`` samples in a row.

    More ``consecutive`` samples reject single spikes at the cost of one state period each.
    A sample with a NaN/inf component is counted in ``invalid_samples``, never contact;
    ``fired_at`` is the index of the sample that fired, or ``None``.
    """

    def __init__(self, threshold_n: float = 10.0, consecutive: int = 1) -> None:
        if not (threshold_n > 0 and math.isfinite(threshold_n)):
            raise BehaviourError(
                f"The 'threshold_n' parameter must be a finite value > 0. Got {threshold_n!r} "
                "instead."
            )
        if consecutive < 1:
            raise BehaviourError(
                f"The 'consecutive' parameter must be >= 1. Got {consecutive!r} instead."
            )
        self.threshold_n = float(threshold_n)
        self.consecutive = int(consecutive)
        self.samples = 0
        self.invalid_samples = 0
        self.invalid_run = 0
        self.fired_at: int | None = None
        self.last_norm_n = math.nan
        self._run = 0

    def update(self, force_norm_n: float) -> bool:
        """Feed one force norm; returns True on the sample where contact is declared."""
        index = self.samples
        self.samples += 1
        self.last_norm_n = force_norm_n
        if not math.isfinite(force_norm_n):
            self.invalid_samples += 1
            self.invalid_run += 1
            self._run = 0
            return False
        self.invalid_run = 0
        self._run = self._run + 1 if force_norm_n >= self.threshold_n else 0
        if self.fired_at is None and self._run >= self.consecutive:
            self.fired_at = index
            return True
        return False
