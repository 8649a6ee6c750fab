"""Tasks and sensors: the closed sets of names every ext_sense package speaks (no rclpy).

``label`` is the string used in files, parameters and messages, one definition for all.
"""

from __future__ import annotations

from enum import IntEnum
from typing import Self


class _Named(IntEnum):
    """An IntEnum named in files and messages by ``label``, its lower-case member name."""

    @property
    def label(self) -> str:
        """The member's name in files, messages and model cards, e.g. ``"tap_localization"``."""
        return self.name.lower()

    @classmethod
    def _aliases(cls) -> dict[str, str]:
        return {}

    @classmethod
    def parse(cls, value: str | int | Self, error: type[Exception] = ValueError) -> Self:
        """Member from its label, enum name, alias or value (case and ``-``/``_`` ignored).

        Raises:
            error: The value names no member (each package passes its own exception type).
        """
        if isinstance(value, cls):
            return value
        try:
            if isinstance(value, int):
                return cls(value)
            key = str(value).strip().upper().replace("-", "_")
            return cls[cls._aliases().get(key, key)]
        except (KeyError, ValueError) as err:
            names = ", ".join(repr(m.label) for m in cls)
            param = cls.__name__.lower()
            raise error(
                f"The {param!r} parameter must be one of {names}. Got {value!r} instead."
            ) from err


class Task(_Named):
    """The three tasks of the paper; aliases ``tap``, ``handover``, ``food``."""

    TAP_LOCALIZATION = 0
    HANDOVER_STABILITY = 1
    FOOD_IDENTIFICATION = 2

    @property
    def is_regression(self) -> bool:
        """Whether the task's label is a number (tap position in metres)."""
        return self is Task.TAP_LOCALIZATION

    @classmethod
    def _aliases(cls) -> dict[str, str]:
        return {
            "TAP": "TAP_LOCALIZATION",
            "HANDOVER": "HANDOVER_STABILITY",
            "FOOD": "FOOD_IDENTIFICATION",
        }


class Sensor(_Named):
    """The two tactile sensors: NUSkin (event taxels) and BioTac (PAC)."""

    NUSKIN = 0
    BIOTAC = 1
