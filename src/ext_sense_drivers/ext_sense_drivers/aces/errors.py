"""The one exception type of the ACES line code."""

from __future__ import annotations


class AcesError(Exception):
    """Bad ACES input: unknown bank version, events out of range, samples of the wrong type."""
