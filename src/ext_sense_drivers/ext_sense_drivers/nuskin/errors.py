"""The one exception type of the NUSkin package."""

from __future__ import annotations


class NuskinError(Exception):
    """Bad arguments to the NUSkin codec, clock or file readers (bad bytes never raise)."""
