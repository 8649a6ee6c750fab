"""The gripper as the handover sees it, and the Robotiq status as ROS key-values.

:func:`is_open`, :func:`settled` and :func:`describe_position` read a Robotiq 2F status as the
handover needs it. The ``robotiq_gripper`` node publishes the status as a
``diagnostic_msgs/DiagnosticStatus`` whose key-values are the register fields
(:func:`status_to_values`); :func:`status_from_values` reads them back in other nodes.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from ext_sense_behaviours.errors import BehaviourError
from ext_sense_drivers.robotiq import ActivationStatus, GripperStatus, ObjectStatus
from ext_sense_drivers.robotiq.registers import fault_name
from ext_sense_runtime.diagnostics import Level

OPEN_TOLERANCE = 10
"""gPO at or below which the fingers count as open (position counts, 0..255)."""

STATUS_KEYS = ("gACT", "gGTO", "gSTA", "gOBJ", "gFLT", "gPR", "gPO", "gCU")


def is_open(status: GripperStatus) -> bool:
    """The last go-to ended (gOBJ != 0) at an open position."""
    return (
        status.motion_done
        and status.position <= OPEN_TOLERANCE
        and status.position_request <= OPEN_TOLERANCE
    )


def settled(status: GripperStatus) -> bool:
    """The fingers are not moving: the last go-to ended, or a fault stopped them."""
    return bool(status.fault) or status.motion_done or not status.go_to


def describe_position(status: GripperStatus) -> str:
    """:func:`describe` with the finger position, for decisions about where the fingers are."""
    return f"{describe(status)}, gPO={status.position}"


def describe(status: GripperStatus) -> str:
    """One line a person understands, for the status message."""
    if status.fault:
        return f"fault gFLT={fault_name(status.fault)}"
    if not status.activated:
        return "reset (not activated)"
    if status.activation != ActivationStatus.COMPLETED:
        return "activating"
    if not status.go_to:
        return "activated, idle"
    return {
        ObjectStatus.MOVING: "moving",
        ObjectStatus.DETECTED_OPENING: "stopped on an object while opening",
        ObjectStatus.DETECTED_CLOSING: "holding an object",
        ObjectStatus.AT_POSITION: "at requested position, no object",
    }[status.object]


def status_level(status: GripperStatus | None, error: str) -> tuple[Level, str]:
    """The gripper's diagnostic level and message (ERROR: link error or fault; WARN: not ready)."""
    if error:
        return Level.ERROR, error
    if status is None:
        return Level.WARN, "no status yet"
    if status.fault:
        return Level.ERROR, describe(status)
    return (Level.OK if status.ready else Level.WARN), describe(status)


def status_to_values(status: GripperStatus) -> list[tuple[str, str]]:
    """Register fields as key-value strings, in :data:`STATUS_KEYS` order."""
    fields = (
        int(status.activated),
        int(status.go_to),
        int(status.activation),
        int(status.object),
        status.fault,
        status.position_request,
        status.position,
        status.current,
    )
    return [(k, str(v)) for k, v in zip(STATUS_KEYS, fields, strict=True)]


def status_from_values(values: Mapping[str, str] | Sequence[tuple[str, str]]) -> GripperStatus:
    """Rebuild a status from :func:`status_to_values` pairs (BehaviourError: a bad key)."""
    pairs = dict(values)
    try:
        v = {k: int(pairs[k]) for k in STATUS_KEYS}
    except (KeyError, ValueError) as err:
        raise BehaviourError(
            f"The gripper status must carry integer values for {list(STATUS_KEYS)}. "
            f"Got {sorted(pairs)} instead."
        ) from err
    return GripperStatus(
        activated=bool(v["gACT"]),
        go_to=bool(v["gGTO"]),
        activation=ActivationStatus(v["gSTA"] & 3),
        object=ObjectStatus(v["gOBJ"] & 3),
        fault=v["gFLT"],
        position_request=v["gPR"],
        position=v["gPO"],
        current=v["gCU"],
    )
