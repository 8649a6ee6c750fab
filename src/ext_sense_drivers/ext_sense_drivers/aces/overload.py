"""Overload gate of the ACES line decoder: blank what the line cannot separate before decoding."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import numpy.typing as npt

MAX_DEPTH = 16.0
"""Signatures per sample (energy per sample / amplitude squared) over one signature length
beyond which the line cannot separate them: a burst of 12 decodes, 16 does not."""

SUSTAINED_SPAN = 4
"""Signature lengths of the overload gate's second, longer stretch."""

MAX_SUSTAINED_DEPTH = 7.0
"""Signatures per sample over :data:`SUSTAINED_SPAN` lengths beyond which the line is saturated
(a 95 % busy line carries 3); decoding it would only cost time and make residue."""


class Blanked(NamedTuple):
    """The blanked samples of a window (ascending), and their energy in signatures' energies."""

    samples: npt.NDArray[np.int64]
    signatures: float


def blank_overload(
    buf: npt.NDArray[np.float64], commit: int, amplitude: float, length: int
) -> Blanked | None:
    """Set to 0 the samples before ``commit`` in stretches above either depth limit.

    Returns:
        The blanked samples and their energy, or None.
    """
    if commit <= 0:
        return None
    hit = False
    seg = buf[: min(commit + SUSTAINED_SPAN * length - 1, buf.size)]
    if float(np.dot(seg, seg)) <= MAX_DEPTH * amplitude**2 * length:
        return None  # no stretch can hold more than the whole segment
    mark = np.zeros(seg.size + 1, np.int64)
    cum = np.concatenate(([0.0], np.cumsum(seg * seg)))
    for span, depth in ((length, MAX_DEPTH), (SUSTAINED_SPAN * length, MAX_SUSTAINED_DEPTH)):
        if seg.size < span:
            continue
        energy = (cum[span:] - cum[:-span])[:commit]
        starts = np.flatnonzero(energy > depth * amplitude**2 * span)
        if starts.size:
            hit = True
            np.add.at(mark, starts, 1)
            np.add.at(mark, starts + span, -1)
    if not hit:
        return None
    blank = np.flatnonzero(np.cumsum(mark)[:commit] > 0)
    lost = buf[blank]
    signatures = float(np.dot(lost, lost)) / (amplitude**2 * length)
    buf[blank] = 0.0
    return Blanked(blank, signatures)
