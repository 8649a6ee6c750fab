"""Overload gate of the ACES line decoder: blank what the line cannot separate before decoding.

A window's decided samples that sit in a stretch carrying more signatures per sample than the
line can separate (a burst beyond separation, a saturated line, garbage input) are set to 0,
so that neither detector works on them; the decoder counts them and their energy.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import numpy.typing as npt

MAX_DEPTH = 16.0
"""Overload gate: a stretch of one signature length whose energy says it carries more than this
many signatures per sample on average (energy per sample / amplitude squared; signatures add
incoherently) is beyond what the line can separate. Its samples are not decoded (set to 0) and
counted. Bursts of 12 signatures started within 0.1 ms (about 9.6 per sample over the stretch,
more where they happen to add up) still decode; 16 did not. Also stops a constant or random
full-scale input (64 and 21)."""

SUSTAINED_SPAN = 4
"""Signature lengths of the overload gate's second, longer stretch."""

MAX_SUSTAINED_DEPTH = 7.0
"""Overload gate on stretches of :data:`SUSTAINED_SPAN` signature lengths: a line that carries
more than this many signatures per sample on average for that long is saturated (a random line
at 95 % busy carries 3, and reaching 7 over four signature lengths is a 1e-4 event there;
a burst of 12 signatures is 3 over such a stretch). Decoding a saturated line only costs time
(the onset decoder's test budget and a matched filter per pass) and produces residue."""


class Blanked(NamedTuple):
    """What the overload gate took out of a window.

    Attributes:
        samples: Indices of the blanked samples, ``(n,)`` int64, ascending.
        signatures: Their energy before blanking in units of one signature's energy.
    """

    samples: npt.NDArray[np.int64]
    signatures: float


def blank_overload(
    buf: npt.NDArray[np.float64], commit: int, amplitude: float, length: int
) -> Blanked | None:
    """Blank the samples before ``commit`` the line cannot separate (in place).

    Every stretch of one signature length that starts before ``commit`` and carries more
    than :data:`MAX_DEPTH` signatures' energy per sample, and every stretch of
    :data:`SUSTAINED_SPAN` lengths above :data:`MAX_SUSTAINED_DEPTH`, marks its samples
    before ``commit``; those are set to 0 so that neither detector works on them. Later samples
    are judged again by the next pass.

    Args:
        buf: The window's residual samples (changed in place).
        commit: Samples of the window decided in this pass.
        amplitude: Chip amplitude in use.
        length: Chips per signature.

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
