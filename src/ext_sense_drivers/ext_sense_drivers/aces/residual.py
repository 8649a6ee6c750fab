"""Residual tests of the ACES line decoder: what the residual says after cancellation.

Both compare the energy of every stretch of one signature length in a window's decided
residual with the quietest tenth of those stretches (the noise floor):

- :func:`missed_energy` (after the onset decoder): a signature's worth left somewhere sends
  the window through the matched filter;
- :func:`unexplained` (after decoding): stretches the detections did not explain, whose
  detections the decoder withholds.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

REFRESH_RATIO = 0.25
"""A decided stretch one signature long whose residual energy exceeds the noise floor by this
fraction of one signature's energy sends the window through the matched filter."""

REFRESH_LIMIT = 8.0
"""Above this many signatures' energy in one decided stretch the matched filter is not run."""

MAX_NOISE = 0.6
"""Residual test, absolute part: when even the quietest tenth of a window's decided stretches
keeps more residual than noise of this RMS (chip amplitudes) would leave, the window is noise
or interference beyond what the line is specified for (exact decoding was measured up to 0.4
chip RMS), its correlations are not evidence, and all its detections are withheld."""

REJECT_RATIO = 0.25
"""Residual test after decoding: a decided stretch one signature long whose residual energy
still exceeds the noise floor by this fraction of one signature's energy was not explained by
the detections around it (a burst too dense to separate: the cancellations left residue that
made more false detections). Committed detections overlapping it are withheld and counted."""


def stretch_energy(r: npt.NDArray[np.float64], span: int) -> npt.NDArray[np.float64]:
    """Energy of every stretch of ``span`` samples in ``r``."""
    cum = np.concatenate(([0.0], np.cumsum(r * r)))
    return cum[span:] - cum[:-span]


def missed_energy(decided: npt.NDArray[np.float64], amplitude: float, length: int) -> bool:
    """Whether the decided residual still holds a signature's worth of energy somewhere.

    Not when it holds more than :data:`REFRESH_LIMIT` signatures' worth in one stretch:
    that is a burst the matched filter does not resolve either (the residual test
    withholds it), and running it there cost most of the time on bursty lines.

    Compares the most energetic stretch of one signature length with the quietest tenth
    of the stretches (the noise floor: missed signatures raise it far less than the mean,
    so even a window full of weak missed signatures stands out).

    Args:
        decided: The decided residual samples.
        amplitude: Chip amplitude the energies are measured in (the nominal one).
        length: Chips per signature.
    """
    if decided.size < length:
        return False
    if float(np.dot(decided, decided)) <= REFRESH_RATIO * amplitude**2 * length:
        return False  # no stretch can hold more than the whole residual
    energy = stretch_energy(decided, length)
    top = float(energy.max()) / (amplitude**2 * length)
    if top <= REFRESH_RATIO:
        return False
    floor = float(np.partition(energy, energy.size // 10)[energy.size // 10])
    excess = top - floor / (amplitude**2 * length)
    return REFRESH_RATIO < excess <= REFRESH_LIMIT


def unexplained(
    decided: npt.NDArray[np.float64],
    amplitude: float,
    length: int,
    blanked: npt.NDArray[np.int64] | None,
) -> tuple[bool, npt.NDArray[np.int64] | None]:
    """The decided samples the decoding left unexplained.

    A stretch is unexplained when its residual energy exceeds the noise floor by
    :data:`REJECT_RATIO` of a signature's energy, and every stretch is when the floor
    itself is above :data:`MAX_NOISE`. Samples the overload gate blanked count as
    unexplained too: a correlation over them was measured on part of a signature, or on the
    residue of erased ones.

    Args:
        decided: The decided residual samples.
        amplitude: Chip amplitude in use.
        length: Chips per signature.
        blanked: Samples the overload gate blanked, or None.

    Returns:
        Whether the noise floor is above :data:`MAX_NOISE`, and the running count of
        unexplained samples (``(decided.size + 1,)``, ``cum[i]`` the number before sample
        ``i``), or None when there are none.
    """
    unit = amplitude**2 * length
    if decided.size < length or (
        blanked is None and float(np.dot(decided, decided)) <= REJECT_RATIO * unit
    ):
        return False, None
    energy = stretch_energy(decided, length)
    if blanked is None and float(energy.max()) <= REJECT_RATIO * unit:
        return False, None  # nothing above the level, whatever the floor (floor <= max)
    floor = float(np.partition(energy, energy.size // 10)[energy.size // 10])
    noisy = floor > MAX_NOISE**2 * unit
    if noisy:
        bad = np.ones(energy.size, dtype=bool)
    else:
        bad = energy - floor > REJECT_RATIO * amplitude**2 * length
    if not bad.any() and blanked is None:
        return noisy, None
    mark = np.zeros(decided.size + 1, np.int64)
    starts = np.flatnonzero(bad)
    np.add.at(mark, starts, 1)
    np.add.at(mark, starts + length, -1)
    covered = np.cumsum(mark)[: decided.size] > 0
    if blanked is not None:
        covered[blanked[blanked < decided.size]] = True
    return noisy, np.concatenate(([0], np.cumsum(covered)))
