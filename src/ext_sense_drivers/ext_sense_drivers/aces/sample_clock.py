"""The line's own sample clock: sample index <-> integer nanoseconds, exactly, with no drift.

At 508 kHz a sample lasts 250000/127 ns, not an integer, so times are computed from the index
with integer arithmetic every time instead of accumulating a rounded period.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from ext_sense_runtime.stamps import S


def sample_to_ns(index: npt.ArrayLike, rate_hz: int) -> npt.NDArray[np.int64]:
    """Start time of samples, ``floor(index * 1e9 / rate)`` in integer ns.

    Args:
        index: Sample indices since stream start (>= 0), any integer shape.
        rate_hz: Line sample rate, integer Hz.

    Returns:
        int64 ns, same shape as ``index``.
    """
    n = np.asarray(index, dtype=np.int64)
    whole, part = np.divmod(n, rate_hz)
    return whole * S + (part * S) // rate_hz


def ns_to_sample(t_ns: npt.ArrayLike, rate_hz: int) -> npt.NDArray[np.int64]:
    """Nearest sample index of times, ``round(t_ns * rate / 1e9)`` without int64 overflow.

    ``ns_to_sample(sample_to_ns(n)) == n`` for every ``n >= 0``.

    Args:
        t_ns: Times in integer ns since stream start, any integer shape.
        rate_hz: Line sample rate, integer Hz.

    Returns:
        int64 sample indices, same shape as ``t_ns``.
    """
    t = np.asarray(t_ns, dtype=np.int64)
    whole, part = np.divmod(t, S)
    return whole * rate_hz + (part * rate_hz + S // 2) // S
