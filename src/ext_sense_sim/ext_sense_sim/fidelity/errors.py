"""The one exception type of the fidelity check."""

from __future__ import annotations


class FidelityError(Exception):
    """Real captures that cannot be read or matched with the scene, or a scene with no real kin.

    Messages name the folder, file or scene, what was expected and what arrived.
    """
