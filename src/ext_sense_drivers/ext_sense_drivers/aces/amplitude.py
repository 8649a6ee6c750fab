"""Chip amplitude tracking of the ACES line decoder.

The amplitude follows the detections' mean correlation per chip, pass by pass, within
:data:`AMPLITUDE_RANGE` of the nominal one.
"""

from __future__ import annotations

AMPLITUDE_MEMORY = 16
"""Past detections' weight: a pass moves the estimate ``n / (n + min(seen, this))`` of the way
to its ``n`` detections' mean (a running mean, then an exponential one)."""

AMPLITUDE_RANGE = (0.25, 4.0)
"""The tracked amplitude stays within these multiples of the nominal one."""

AMPLITUDE_STEP = 0.002
"""Smaller relative changes of the amplitude estimate are not applied (saves work per pass)."""

REDO_GAIN = 0.1
"""Relative amplitude error above which a pass with rejected detections is decoded again."""

REDO_SETTLED = 64
"""Passes are decoded again only until this many detections measured the amplitude: later,
residue is a burst far more often than a gain change."""


def clamp_amplitude(amplitude: float, nominal: float) -> float:
    """``amplitude`` held within :data:`AMPLITUDE_RANGE` of the ``nominal`` one."""
    lo, hi = AMPLITUDE_RANGE
    return min(max(amplitude, lo * nominal), hi * nominal)


def tracked_amplitude(
    in_use: float, nominal: float, strength: float, n: int, seen: int
) -> float | None:
    """The amplitude to cancel with after a pass's ``n`` (> 0) detections, or None to keep it.

    ``strength`` is their summed correlation per chip, ``seen`` the detections measured before.
    """
    memory = min(seen, AMPLITUDE_MEMORY)
    step = n / (n + memory)
    new = clamp_amplitude(in_use + step * (strength / n - in_use), nominal)
    if abs(new - in_use) > AMPLITUDE_STEP * in_use:
        return new
    return None
