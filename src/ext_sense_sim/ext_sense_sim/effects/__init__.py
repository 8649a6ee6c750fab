"""The effects a scene can list, by name. Only the listed ones are ever built or run."""

from __future__ import annotations

from ext_sense_sim.effects.base import Effect
from ext_sense_sim.effects.beam import BeamModes
from ext_sense_sim.effects.biotac import BiotacTransduction
from ext_sense_sim.effects.fork import ArmVibration, ForkPenetration
from ext_sense_sim.effects.grasp import GraspTransfer
from ext_sense_sim.effects.handover import HumanGrasp
from ext_sense_sim.effects.noise import SensorNoise, SpuriousEvents
from ext_sense_sim.effects.nuskin import NuskinTransduction
from ext_sense_sim.effects.receiver import ReceiverLink
from ext_sense_sim.effects.tap import ContactImpulse
from ext_sense_sim.effects.wire import AcesLine, BiotacWire, NuskinWire, WireFaults

_ALL: tuple[type[Effect], ...] = (
    ContactImpulse,
    HumanGrasp,
    ForkPenetration,
    ArmVibration,
    BeamModes,
    GraspTransfer,
    SensorNoise,
    NuskinTransduction,
    SpuriousEvents,
    ReceiverLink,
    AcesLine,
    BiotacTransduction,
    NuskinWire,
    BiotacWire,
    WireFaults,
)

REGISTRY: dict[str, type[Effect]] = {cls.name: cls for cls in _ALL}
"""Effect name to class."""
