"""Tasks, sensors and label kinds as closed sets of names."""

from __future__ import annotations

from enum import IntEnum

from ext_sense_perception.errors import PerceptionError


class Task(IntEnum):
    """The three tasks of the paper; ``name.lower()`` is the string used in messages."""

    TAP_LOCALIZATION = 0
    HANDOVER_STABILITY = 1
    FOOD_IDENTIFICATION = 2

    @property
    def label(self) -> str:
        """The task name as used in messages and model cards, e.g. ``"tap_localization"``."""
        return self.name.lower()

    @property
    def is_regression(self) -> bool:
        """Whether the task's label is a number (tap position in metres)."""
        return self is Task.TAP_LOCALIZATION

    @classmethod
    def parse(cls, value: str | int | Task) -> Task:
        """Task from its message string, enum name or value.

        Raises:
            PerceptionError: when the value names no task.
        """
        if isinstance(value, Task):
            return value
        if isinstance(value, int):
            return cls(value)
        key = str(value).strip().upper().replace("-", "_")
        aliases = {
            "TAP": "TAP_LOCALIZATION",
            "HANDOVER": "HANDOVER_STABILITY",
            "FOOD": "FOOD_IDENTIFICATION",
        }
        key = aliases.get(key, key)
        try:
            return cls[key]
        except KeyError as err:
            names = ", ".join(t.label for t in cls)
            raise PerceptionError(
                f"The 'task' parameter must be one of {names}. Got {value!r} instead."
            ) from err


class Sensor(IntEnum):
    """The two tactile sensors; ``name.lower()`` is the string used in messages."""

    NUSKIN = 0
    BIOTAC = 1

    @property
    def label(self) -> str:
        """The sensor name as used in messages and model cards, e.g. ``"nuskin"``."""
        return self.name.lower()

    @classmethod
    def parse(cls, value: str | int | Sensor) -> Sensor:
        """Sensor from its message string, enum name or value.

        Raises:
            PerceptionError: when the value names no sensor.
        """
        if isinstance(value, Sensor):
            return value
        if isinstance(value, int):
            return cls(value)
        try:
            return cls[str(value).strip().upper()]
        except KeyError as err:
            raise PerceptionError(
                f"The 'sensor' parameter must be 'nuskin' or 'biotac'. Got {value!r} instead."
            ) from err
