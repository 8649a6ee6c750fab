"""The record both ACES detectors return."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import numpy.typing as npt


class Detections(NamedTuple):
    """Signatures found in one window.

    Attributes:
        code: Bank row (taxel - 1) of each detection, ``(n,)`` int64.
        start: Start sample within the window, ``(n,)`` int64.
        sign: Polarity, +1 or -1, ``(n,)`` int64.
        tested: Correlations examined (candidates or onset tests) to find them.
        cancellations: Cancellation steps taken, including look-ahead ones not returned.
        strength: Sum over the returned detections of ``|correlation| / chips`` at acceptance,
            line units: divided by their number, an estimate of the chip amplitude on the line.
    """

    code: npt.NDArray[np.int64]
    start: npt.NDArray[np.int64]
    sign: npt.NDArray[np.int64]
    tested: int = 0
    cancellations: int = 0
    strength: float = 0.0

    @classmethod
    def none(cls, tested: int = 0, cancellations: int = 0) -> Detections:
        """No detections."""
        empty = np.empty(0, np.int64)
        return cls(empty, empty, empty, tested, cancellations)
