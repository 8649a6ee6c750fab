"""The Robotiq 2F in the units of ``control_msgs`` gripper actions, and when a goal is done.

:class:`GripperScale` converts the finger gap (m), effort (N) and speed (m/s) of
``GripperCommand`` / ``ParallelGripperCommand`` to register counts (0 open .. 255 closed),
linearly over the stroke. :func:`goal_problem` rejects a goal the gripper cannot carry out as
asked (not finite, or outside the stroke): reporting a clamped goal reached would lie.
:func:`goal_outcome` judges a goal from one status: ``stalled`` (gOBJ 1 or 2) and
``reached_goal`` (gOBJ 3) are both success, as ``GripperActionController`` with ``allow_stalling``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, NamedTuple

from ext_sense_behaviours.errors import BehaviourError
from ext_sense_drivers.robotiq import GripperStatus, ObjectStatus
from ext_sense_drivers.robotiq.registers import fault_name

COUNTS = 255


@dataclass(frozen=True)
class GripperScale:
    """Register counts <-> SI units for one gripper model (defaults: the 2F-85).

    ``stroke_m`` is the gap at gPO 0 (2F-140: 0.140 m; gPO 255 is 0); the maxima at rFR and rSP 255.
    """

    stroke_m: float = 0.085
    max_force_n: float = 235.0
    max_speed_m_s: float = 0.15

    def __post_init__(self) -> None:
        for name in ("stroke_m", "max_force_n", "max_speed_m_s"):
            value = getattr(self, name)
            if not value > 0.0:
                raise BehaviourError(f"The '{name}' parameter must be > 0. Got {value!r} instead.")

    def gap_m(self, counts: int) -> float:
        """Finger gap for a position count (gPO or gPR)."""
        return self.stroke_m * (1.0 - min(max(counts, 0), COUNTS) / COUNTS)

    def position_counts(self, gap_m: float) -> int:
        """The rPR count for a requested gap, clipped to the stroke."""
        fraction = 1.0 - min(max(gap_m, 0.0), self.stroke_m) / self.stroke_m
        return round(fraction * COUNTS)

    def force_counts(self, effort_n: float, default: int) -> int:
        """The rFR count for a maximum effort; ``default`` for 0 or less (not given)."""
        if not effort_n > 0.0:
            return default
        return round(min(effort_n / self.max_force_n, 1.0) * COUNTS)

    @property
    def count_m(self) -> float:
        """The gap of one position count, m: the resolution of a goal."""
        return self.stroke_m / COUNTS

    def speed_counts(self, velocity_m_s: float | None, default: int) -> int:
        """The rSP count for a finger speed; ``default`` when none (or 0 or less) is given."""
        if velocity_m_s is None or not velocity_m_s > 0.0:
            return default
        return round(min(velocity_m_s / self.max_speed_m_s, 1.0) * COUNTS)


class GoalOutcome(NamedTuple):
    """A finished goal, in the fields both gripper actions report.

    ``effort_n`` is the requested force while stopped on an object (the Robotiq holds with it),
    else 0 (the 2F reports no force); ``stalled``: gOBJ 1 or 2, ``reached_goal``: gOBJ 3.
    """

    succeeded: bool
    position_m: float
    effort_n: float
    stalled: bool
    reached_goal: bool
    reason: str


def failed(position_m: float, reason: str) -> GoalOutcome:
    """A goal that failed with the fingers at ``position_m``, for ``reason``."""
    return GoalOutcome(False, position_m, 0.0, False, False, reason)


def command_problem(
    scale: GripperScale,
    gap_m: float,
    effort_n: float,
    velocity_m_s: float | None = None,
    fields: tuple[str, str, str] = ("command.position", "command.max_effort", ""),
) -> str:
    """Why a gripper goal cannot be carried out as asked, in one line; ``""`` when it can.

    ``fields`` names the gap, effort and speed in the goal, for the message; ``velocity_m_s`` is
    ``None`` when the action has none.
    """
    gap_name, effort_name, speed_name = fields
    for name, value in ((gap_name, gap_m), (effort_name, effort_n), (speed_name, velocity_m_s)):
        if value is not None and not math.isfinite(value):
            return f"{name} must be a finite number. Got {value!r}."
    if not -scale.count_m <= gap_m <= scale.stroke_m + scale.count_m:
        return (
            f"{gap_name} must be a finger gap within the stroke, 0..{scale.stroke_m:g} m. "
            f"Got {gap_m:g} m."
        )
    return ""


def goal_problem(scale: GripperScale, goal: Any) -> str:
    """:func:`command_problem` of a ``GripperCommand`` or ``ParallelGripperCommand`` goal."""
    command = goal.command
    if hasattr(command, "max_effort"):  # GripperCommand
        return command_problem(scale, command.position, command.max_effort)
    if not command.position:
        return "command.position[0] (the finger gap, m) is missing"
    return command_problem(
        scale,
        command.position[0],
        command.effort[0] if command.effort else 0.0,
        command.velocity[0] if command.velocity else None,
        ("command.position[0]", "command.effort[0]", "command.velocity[0]"),
    )


def goal_outcome(
    status: GripperStatus, target: int, scale: GripperScale, force_n: float
) -> GoalOutcome | None:
    """The outcome of the goal to position count ``target`` judged from one status, or ``None``.

    ``None`` while the fingers move or gPR differs (a status read before the command was written).
    """
    position_m = scale.gap_m(status.position)
    if status.fault:
        return failed(position_m, f"gripper fault {fault_name(status.fault)}")
    if not status.ready:
        return failed(position_m, "gripper not activated")
    if status.position_request != target or not status.go_to:
        return None
    if status.object == ObjectStatus.MOVING:
        return None
    stalled = status.object in (ObjectStatus.DETECTED_OPENING, ObjectStatus.DETECTED_CLOSING)
    reason = "stopped on an object" if stalled else "at the requested position"
    return GoalOutcome(True, position_m, force_n if stalled else 0.0, stalled, not stalled, reason)
