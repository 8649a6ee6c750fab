"""The line's sample clock: sample index <-> integer ns, computed from the index (no drift)."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from ext_sense_runtime.stamps import S


def sample_to_ns(index: npt.ArrayLike, rate_hz: int) -> npt.NDArray[np.int64]:
    """Start times ``floor(index * 1e9 / rate_hz)``, int64 ns, of sample indices (>= 0)."""
    n = np.asarray(index, dtype=np.int64)
    whole, part = np.divmod(n, rate_hz)
    return whole * S + (part * S) // rate_hz


def ns_to_sample(t_ns: npt.ArrayLike, rate_hz: int) -> npt.NDArray[np.int64]:
    """Nearest sample indices ``round(t_ns * rate_hz / 1e9)`` (int64, no overflow).

    ``ns_to_sample(sample_to_ns(n)) == n`` for every ``n >= 0``.
    """
    t = np.asarray(t_ns, dtype=np.int64)
    whole, part = np.divmod(t, S)
    return whole * rate_hz + (part * rate_hz + S // 2) // S
