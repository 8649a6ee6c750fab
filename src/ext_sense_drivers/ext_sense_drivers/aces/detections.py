"""The record both ACES detectors return, and how the line decoder combines two of them."""

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
        strength: Sum of ``|correlation| / chips`` at acceptance, line units (per detection,
            an estimate of the chip amplitude).
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

    def select(self, keep: npt.NDArray[np.bool_]) -> Detections:
        """The detections where ``keep`` is True (without the work counts and strength)."""
        return Detections(self.code[keep], self.start[keep], self.sign[keep])


def merge(first: Detections, extra: Detections) -> tuple[Detections, int]:
    """Add the matched filter's detections; one that negates an onset decision undoes it.

    Returns:
        The merged detections and the number of onset decisions undone.
    """
    keys = {
        (k, t): i
        for i, (k, t) in enumerate(zip(first.code.tolist(), first.start.tolist(), strict=True))
    }
    drop = np.zeros(first.code.size, dtype=bool)
    add = np.ones(extra.code.size, dtype=bool)
    for j, (k, t, s) in enumerate(
        zip(extra.code.tolist(), extra.start.tolist(), extra.sign.tolist(), strict=True)
    ):
        i = keys.get((k, t))
        if i is not None and not drop[i] and first.sign[i] == -s:
            drop[i] = True
            add[j] = False
    keep = ~drop
    merged = Detections(
        np.concatenate((first.code[keep], extra.code[add])),
        np.concatenate((first.start[keep], extra.start[add])),
        np.concatenate((first.sign[keep], extra.sign[add])),
    )
    return merged, int(drop.sum())


def annihilate(found: Detections) -> tuple[Detections, int]:
    """Collapse detections of one taxel at one start into one (or none, if signs cancel).

    Returns:
        ``found`` itself when nothing collapses, else the collapsed detections; and the number
        of detections undone.
    """
    if found.code.size < 2:
        return found, 0
    key = found.code * (1 << 40) + found.start
    ordered = np.sort(key)
    if not (ordered[1:] == ordered[:-1]).any():
        return found, 0
    uniq, first, inverse = np.unique(key, return_index=True, return_inverse=True)
    total = np.zeros(uniq.size, np.int64)
    np.add.at(total, inverse, found.sign)
    keep = total != 0
    collapsed = Detections(
        found.code[first][keep], found.start[first][keep], np.sign(total[keep]).astype(np.int64)
    )
    return collapsed, int(key.size - np.count_nonzero(total))
