"""The BioTac driver's settings, checked and turned into a transport and a clock model."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

from ext_sense_drivers.biotac.clock import FRAME_PERIOD_NS, transmission_ns
from ext_sense_drivers.biotac.errors import BioTacError
from ext_sense_drivers.biotac.frame_layout import MAX_SENSORS, STANDARD_FRAME_SIZE
from ext_sense_drivers.transports.link_config import LinkConfig, TransportKind

__all__ = ["BioTacDriverConfig", "TransportKind"]


@dataclass(frozen=True)
class BioTacDriverConfig(LinkConfig):
    """The BioTac driver's settings beyond :class:`LinkConfig`'s (checked on construction)."""

    error: ClassVar[type[Exception]] = BioTacError

    baud: int = 1_000_000
    can_arbitration_id: int = 0x200
    frame_id_prefix: str = "biotac_"
    expected_sensors: tuple[int, ...] = field(default=(0,))
    latency_ns: int = 0
    clock_window_frames: int = 200

    def __post_init__(self) -> None:
        self.check_link()
        bad = [s for s in self.expected_sensors if not 0 <= int(s) < MAX_SENSORS]
        if bad:
            raise BioTacError(
                f"The 'expected_sensors' parameter must hold slots 0..{MAX_SENSORS - 1}. "
                f"Got {list(self.expected_sensors)} instead."
            )

    @property
    def lead_ns(self) -> int:
        """First sample to least-delayed arrival: frame span + serial transmission + latency."""
        lead = FRAME_PERIOD_NS + int(self.latency_ns)
        if self.transport_kind == TransportKind.SERIAL:
            lead += transmission_ns(STANDARD_FRAME_SIZE, self.baud)
        return lead
