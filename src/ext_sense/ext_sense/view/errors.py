"""The one exception type of :mod:`ext_sense.view`."""

from __future__ import annotations


class ViewError(ValueError):
    """Input the view or the plots cannot draw: a wrong shape, an unreadable source."""
