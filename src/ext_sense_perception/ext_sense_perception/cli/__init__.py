"""The perception commands of ``ext-sense``: :mod:`.learning` and :mod:`.sessions`."""

from __future__ import annotations

import argparse

from ext_sense_perception.cli import learning, sessions


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``features``, ``train``, ``evaluate``, ``report``, ``score`` and ``calibrate``."""
    learning.register(subparsers)
    sessions.register(subparsers)
