"""The franka_ros2 side of the arm adapter, without rclpy: names, conversions, thresholds.

franka_msgs is not on PyPI (``scripts/setup.sh`` builds it into the venv), so it is imported on
demand (:func:`import_franka_msgs`). The names default to franka_ros2's: the robot state
broadcaster, the collision-behaviour service, the error-recovery action and the
``fr3_arm_controller``'s ``FollowJointTrajectory`` (franka_ros2 has no commandable Cartesian
controller, so straight lines become joint waypoints, :mod:`ext_sense_behaviours.panda_kinematics`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from types import ModuleType
from typing import Any, NamedTuple

import numpy as np

from ext_sense_behaviours.errors import BehaviourError
from ext_sense_behaviours.panda_kinematics import jacobian
from ext_sense_behaviours.records import ArmState
from ext_sense_runtime.stamps import stamp_to_ns


@dataclass(frozen=True)
class FrankaNames:
    """Where the franka_ros2 interfaces live (all overridable by parameters)."""

    state_topic: str = "/franka_robot_state_broadcaster/robot_state"
    trajectory_action: str = "/fr3_arm_controller/follow_joint_trajectory"
    collision_service: str = "/service_server/set_full_collision_behavior"
    error_recovery_action: str = "/action_server/error_recovery"


def import_franka_msgs() -> ModuleType:
    """Import ``franka_msgs`` on demand (BehaviourError when it is not installed)."""
    try:
        import franka_msgs.msg  # type: ignore[import-not-found]
        import franka_msgs.srv  # type: ignore[import-not-found]
    except ImportError as err:
        raise BehaviourError(
            "The franka arm adapter needs the 'franka_msgs' package (FrankaRobotState, "
            "SetFullCollisionBehavior, ErrorRecovery), which is not installed here: it is not on "
            "PyPI. Run `make setup` (it builds them into the venv), or on a ROS install build "
            "franka_ros2's franka_msgs in a colcon workspace and source it; or use arm:=sim."
        ) from err
    import franka_msgs  # type: ignore[import-not-found]

    return franka_msgs


ROBOT_MODE_REFLEX = 4
"""``FrankaRobotState.ROBOT_MODE_REFLEX``: the robot stopped itself (a collision threshold was
exceeded) and takes no motion until error recovery."""


class RobotReading(NamedTuple):
    """What the adapter takes from one ``FrankaRobotState``.

    ``q``: measured joint positions (7,), radians; ``contact`` / ``collision``: a Cartesian
    linear flag over the lower / upper threshold; ``reflex``: stopped by its own reflex.
    """

    state: ArmState
    joint_names: tuple[str, ...]
    q: np.ndarray
    contact: bool
    collision: bool
    reflex: bool


def _raised(v: Any) -> bool:
    return bool(v.x or v.y or v.z)


def reading_from_robot_state(msg: Any) -> RobotReading:
    """Convert a ``FrankaRobotState`` into the adapter's reading (BehaviourError if malformed).

    Force from ``o_f_ext_hat_k`` (base frame), height from ``o_t_ee``. The vertical velocity is
    ``J(q) dq`` from the measured joint velocities (NaN without them): the message carries no
    measured Cartesian velocity, and the trajectory controller sets no commanded twist.
    """
    try:
        stamp_ns = stamp_to_ns(msg.header.stamp)
        f = msg.o_f_ext_hat_k.wrench.force
        z = float(msg.o_t_ee.pose.position.z)
        joints = msg.measured_joint_state
        q = np.asarray(joints.position, dtype=np.float64)
        dq = np.asarray(joints.velocity, dtype=np.float64)
        flags = msg.collision_indicators
        contact = _raised(flags.is_cartesian_linear_contact)
        collision = _raised(flags.is_cartesian_linear_collision)
        reflex = int(msg.robot_mode) == ROBOT_MODE_REFLEX
        names = tuple(joints.name)
    except AttributeError as err:
        raise BehaviourError(
            f"The robot state lacks a field the adapter reads ({err}); expected "
            "franka_msgs/msg/FrankaRobotState with o_f_ext_hat_k, o_t_ee, measured_joint_state "
            "and collision_indicators."
        ) from err
    if q.shape != (7,) or len(names) != 7:
        raise BehaviourError(
            f"The robot state's measured_joint_state must name 7 joints with 7 positions. Got "
            f"{len(names)} names and {q.size} positions instead."
        )
    vz = float(jacobian(q)[2] @ dq) if dq.shape == (7,) else math.nan
    state = ArmState(stamp_ns, z, (float(f.x), float(f.y), float(f.z)), vz)
    return RobotReading(state, names, q, contact, collision, reflex)


def collision_behavior_values(
    force_n: float, torque_nm: float, joint_torque_nm: float
) -> dict[str, list[float]]:
    """Field values of a ``SetFullCollisionBehavior`` request.

    The robot's own reflex is a safety net behind the behaviour's software stop: it stops at
    ``force_n`` (Cartesian x, y, z) and ``torque_nm`` (about x, y, z) and then needs error
    recovery, while the software stop at 10 N does not. Contact ("lower") thresholds are half
    the collision ("upper") ones; acceleration and nominal phases share the values.
    BehaviourError if a threshold is not positive.
    """
    for name, value in (
        ("force_n", force_n),
        ("torque_nm", torque_nm),
        ("joint_torque_nm", joint_torque_nm),
    ):
        if not (value > 0 and math.isfinite(value)):
            raise BehaviourError(f"The '{name}' parameter must be > 0. Got {value!r} instead.")
    cart_upper = [force_n] * 3 + [torque_nm] * 3
    joint_upper = [joint_torque_nm] * 7
    cart_lower = [v / 2 for v in cart_upper]
    joint_lower = [v / 2 for v in joint_upper]
    return {
        "lower_torque_thresholds_acceleration": joint_lower,
        "upper_torque_thresholds_acceleration": joint_upper,
        "lower_torque_thresholds_nominal": joint_lower,
        "upper_torque_thresholds_nominal": joint_upper,
        "lower_force_thresholds_acceleration": cart_lower,
        "upper_force_thresholds_acceleration": cart_upper,
        "lower_force_thresholds_nominal": cart_lower,
        "upper_force_thresholds_nominal": cart_upper,
    }
