"""The NUSkin driver's settings, checked and turned into a transport and a decoding path."""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum
from pathlib import Path
from typing import ClassVar

from ext_sense_drivers.nuskin.clock import ArrivalClock
from ext_sense_drivers.nuskin.errors import NuskinError
from ext_sense_drivers.nuskin.streams import AcesLineStream, WordStream
from ext_sense_drivers.nuskin.wire import FlagPolarity
from ext_sense_drivers.transports.link_config import LinkConfig, TransportKind

__all__ = ["DriverConfig", "Mode", "TransportKind"]


class Mode(IntEnum):
    """What the bytes are."""

    WORDS = 0
    """The receiver's 4-byte event words."""
    ACES_LINE = 1
    """Raw ACES line samples (int16 little-endian, one per chip)."""


@dataclass(frozen=True)
class DriverConfig(LinkConfig):
    """The NUSkin driver's settings beyond :class:`LinkConfig`'s (errors: :class:`NuskinError`)."""

    error: ClassVar[type[Exception]] = NuskinError

    baud: int = 4_000_000
    can_arbitration_id: int = 0x100
    file_pace: str = "recorded"
    mode: str = "words"
    flag_polarity: str = "ignore"
    aces_threshold: float = 0.5

    @property
    def mode_kind(self) -> Mode:
        """The mode as an enum (raises :class:`NuskinError` if not words or aces_line)."""
        return self.choice("mode", Mode)

    def file_rate(self) -> float | None:
        """Replay rate of a file in bytes/s, or ``None`` for flat out (NuskinError if unknown).

        ``file_bytes_per_s > 0`` wins; else ``file_pace``: ``flat``, ``recorded`` (from the
        lab capture's ``.tact`` markers, which must be there) or ``serial`` (8N1 at ``baud``).
        """
        if self.file_bytes_per_s > 0:
            return float(self.file_bytes_per_s)
        pace = self.file_pace.lower()
        if pace == "flat":
            return None
        if pace == "serial":
            return self.baud / 10.0
        if pace == "recorded":
            from ext_sense_drivers.nuskin.tact import recorded_rate

            return recorded_rate(Path(self.file_path))
        raise NuskinError(
            "The 'file_pace' parameter must be one of ['recorded', 'flat', 'serial']. "
            f"Got {self.file_pace!r} instead."
        )

    def make_stream(self) -> WordStream | AcesLineStream:
        """The configured decoding path (NuskinError for a bad mode or flag polarity)."""
        if self.mode_kind == Mode.WORDS:
            polarity = self.choice("flag_polarity", FlagPolarity)
            return WordStream(polarity, ArrivalClock.for_baud(self.baud))
        try:
            return AcesLineStream(threshold=self.aces_threshold)
        except ImportError as err:
            raise NuskinError(f"The 'mode' parameter 'aces_line' is not available: {err}") from err
