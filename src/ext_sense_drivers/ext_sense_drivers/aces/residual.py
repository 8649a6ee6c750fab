"""Residual tests of the ACES line decoder after cancellation.

Both compare the energy of each signature-long stretch of the decided residual with the
quietest tenth of them (the noise floor).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

REFRESH_RATIO = 0.25
"""A decided stretch one signature long whose residual energy exceeds the noise floor by this
fraction of one signature's energy sends the window through the matched filter."""

REFRESH_LIMIT = 8.0
"""Above this many signatures' energy in one decided stretch the matched filter is not run
(a burst it cannot resolve either)."""

MAX_NOISE = 0.6
"""Noise floor (RMS, chip amplitudes) above which a window is beyond specification and all its
detections are withheld."""

REJECT_RATIO = 0.25
"""A decided stretch whose residual exceeds the floor by this fraction of a signature's energy
was not explained; detections overlapping it are withheld."""


def stretch_energy(r: npt.NDArray[np.float64], span: int) -> npt.NDArray[np.float64]:
    """Energy of every stretch of ``span`` samples in ``r``."""
    cum = np.concatenate(([0.0], np.cumsum(r * r)))
    return cum[span:] - cum[:-span]


def missed_energy(decided: npt.NDArray[np.float64], amplitude: float, length: int) -> bool:
    """Whether a decided stretch holds a missed signature (see :data:`REFRESH_LIMIT`)."""
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
    """The decided samples the decoding left unexplained (``blanked`` ones included).

    Returns:
        Whether the noise floor is above :data:`MAX_NOISE` (then all are), and the running
        count of unexplained samples (``(decided.size + 1,)``), or None when there are none.
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
