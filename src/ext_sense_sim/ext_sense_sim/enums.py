"""Tasks and sensors a scene can ask for."""

from __future__ import annotations

from enum import IntEnum


class Task(IntEnum):
    """The three tasks of the paper; ``name.lower()`` is the string used in files and messages."""

    TAP_LOCALIZATION = 0
    HANDOVER_STABILITY = 1
    FOOD_IDENTIFICATION = 2

    @property
    def label(self) -> str:
        """The task's name in files and messages, e.g. ``"tap_localization"``."""
        return self.name.lower()


class Sensor(IntEnum):
    """The two tactile sensors."""

    NUSKIN = 0
    BIOTAC = 1

    @property
    def label(self) -> str:
        """``"nuskin"`` or ``"biotac"``."""
        return self.name.lower()
