"""The one exception type of :mod:`ext_sense_drivers.biotac`."""

from __future__ import annotations


class BioTacError(ValueError):
    """Raised for values that cannot be encoded or records that cannot be read.

    Corrupt bytes on a link never raise: the decoder counts them and moves on.
    """
