"""The one exception type of the simulator."""

from __future__ import annotations


class SceneError(Exception):
    """A scene file, an effect's parameters or a simulated run is wrong or cannot go on.

    Messages name the scene or effect, the parameter, what was expected and what arrived.
    """
