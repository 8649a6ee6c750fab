"""The one exception type of ext_sense_behaviours."""

from __future__ import annotations


class BehaviourError(Exception):
    """A behaviour, adapter or replay got input or configuration it cannot act on safely."""
