"""The one exception type of :mod:`ext_sense_drivers.biotac`."""

from __future__ import annotations


class BioTacError(ValueError):
    """Values that cannot be encoded or records that cannot be read (bad bytes never raise)."""
