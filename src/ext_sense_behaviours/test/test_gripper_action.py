"""Robotiq counts in control_msgs units, and when a gripper goal is finished."""

from __future__ import annotations

import pytest

from ext_sense_behaviours.errors import BehaviourError
from ext_sense_behaviours.gripper_action import GripperScale, command_problem, goal_outcome
from ext_sense_drivers.robotiq import ActivationStatus, GripperStatus, ObjectStatus

SCALE = GripperScale()


def _status(obj: ObjectStatus, request: int, position: int, fault: int = 0) -> GripperStatus:
    return GripperStatus(
        activated=True,
        go_to=True,
        activation=ActivationStatus.COMPLETED,
        object=obj,
        fault=fault,
        position_request=request,
        position=position,
    )


@pytest.mark.parametrize("counts", [0, 1, 77, 128, 254, 255])
def test_gap_and_counts_round_trip(counts: int) -> None:
    assert SCALE.position_counts(SCALE.gap_m(counts)) == counts


def test_gap_ends_and_clipping() -> None:
    assert SCALE.gap_m(0) == pytest.approx(0.085)
    assert SCALE.gap_m(255) == 0.0
    assert SCALE.position_counts(1.0) == 0  # wider than the stroke: fully open
    assert SCALE.position_counts(-0.01) == 255


def test_effort_and_speed_counts_default_when_not_given() -> None:
    assert SCALE.force_counts(0.0, default=42) == 42
    assert SCALE.force_counts(235.0, default=42) == 255
    assert SCALE.force_counts(1e6, default=42) == 255
    assert SCALE.speed_counts(None, default=7) == 7
    assert SCALE.speed_counts(0.075, default=7) == 128


def test_scale_rejects_a_zero_stroke() -> None:
    with pytest.raises(BehaviourError, match="'stroke_m' parameter must be > 0"):
        GripperScale(stroke_m=0.0)


def test_an_older_status_or_a_moving_gripper_does_not_end_the_goal() -> None:
    assert goal_outcome(_status(ObjectStatus.AT_POSITION, 0, 0), 255, SCALE, 50.0) is None
    assert goal_outcome(_status(ObjectStatus.MOVING, 255, 100), 255, SCALE, 50.0) is None


def test_stopping_on_an_object_is_a_stalled_success_with_the_grip_force() -> None:
    outcome = goal_outcome(_status(ObjectStatus.DETECTED_CLOSING, 255, 120), 255, SCALE, 50.0)
    assert outcome is not None
    assert outcome.succeeded
    assert outcome.stalled
    assert not outcome.reached_goal
    assert outcome.effort_n == 50.0
    assert outcome.position_m == pytest.approx(SCALE.gap_m(120))


def test_reaching_the_gap_is_reached_goal_without_effort() -> None:
    outcome = goal_outcome(_status(ObjectStatus.AT_POSITION, 0, 0), 0, SCALE, 50.0)
    assert outcome is not None
    assert outcome.reached_goal
    assert not outcome.stalled
    assert outcome.effort_n == 0.0


def test_a_fault_fails_the_goal_and_names_it() -> None:
    outcome = goal_outcome(_status(ObjectStatus.MOVING, 255, 10, fault=0x07), 255, SCALE, 50.0)
    assert outcome is not None
    assert not outcome.succeeded
    assert "fault" in outcome.reason


@pytest.mark.parametrize(
    ("gap", "effort", "velocity", "message"),
    [
        (float("nan"), 0.0, None, "command.position must be a finite number. Got nan."),
        (0.02, float("nan"), None, "command.max_effort must be a finite number. Got nan."),
        (0.02, float("inf"), None, "command.max_effort must be a finite number. Got inf."),
        (0.02, 10.0, float("nan"), "speed must be a finite number. Got nan."),
        (1.0, 0.0, None, "command.position must be a finger gap within the stroke, 0..0.085 m"),
        (-0.01, 0.0, None, "Got -0.01 m."),
    ],
)
def test_a_goal_the_gripper_cannot_carry_out_is_named(gap, effort, velocity, message) -> None:
    fields = ("command.position", "command.max_effort", "speed")
    assert message in command_problem(SCALE, gap, effort, velocity, fields)


@pytest.mark.parametrize("gap", [0.0, 0.04, 0.085, 0.085 + 0.0003, -0.0003])
def test_a_gap_within_the_stroke_give_or_take_a_count_is_a_good_goal(gap: float) -> None:
    assert command_problem(SCALE, gap, 0.0) == ""
    assert command_problem(SCALE, gap, -1.0, 0.05) == ""  # no effort given: the default force
