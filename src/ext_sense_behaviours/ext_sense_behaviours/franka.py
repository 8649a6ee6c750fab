"""The franka_ros2 side of the arm adapter, without rclpy: names, conversions, thresholds.

franka_msgs is not on PyPI, so nothing here imports it at module load: :func:`import_franka_msgs`
does it on demand and says what is missing. Names of the topic, service and action come from
parameters (:class:`FrankaNames`), defaulting to franka_ros2's:

- state: ``/franka_robot_state_broadcaster/robot_state`` (``franka_msgs/msg/FrankaRobotState``;
  external wrench ``o_f_ext_hat_k`` (WrenchStamped, base frame), pose ``o_t_ee`` (PoseStamped));
- collision thresholds: ``/service_server/set_full_collision_behavior``
  (``franka_msgs/srv/SetFullCollisionBehavior``);
- error recovery: ``/action_server/error_recovery`` (``franka_msgs/action/ErrorRecovery``);
- Cartesian velocity command: franka_ros2 ships no topic for this, so the adapter publishes
  ``geometry_msgs/TwistStamped`` on ``twist_topic`` for a Cartesian velocity controller of the
  user's (an assumption to adapt on the real robot).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from types import ModuleType
from typing import Any

from ext_sense_behaviours.errors import BehaviourError
from ext_sense_behaviours.records import ArmState
from ext_sense_runtime.stamps import stamp_to_ns


@dataclass(frozen=True)
class FrankaNames:
    """Where the franka_ros2 interfaces live (all overridable by parameters)."""

    state_topic: str = "/franka_robot_state_broadcaster/robot_state"
    twist_topic: str = "/cartesian_velocity_controller/command"
    collision_service: str = "/service_server/set_full_collision_behavior"
    error_recovery_action: str = "/action_server/error_recovery"


def import_franka_msgs() -> ModuleType:
    """Import ``franka_msgs`` on demand.

    Raises:
        BehaviourError: franka_msgs is not installed (it is not on PyPI: build franka_ros2 in
            a colcon workspace and source it).
    """
    try:
        import franka_msgs.msg  # type: ignore[import-not-found]
        import franka_msgs.srv  # type: ignore[import-not-found]
    except ImportError as err:
        raise BehaviourError(
            "The franka arm adapter needs the 'franka_msgs' package (FrankaRobotState, "
            "SetFullCollisionBehavior, ErrorRecovery), which is not installed here: it is not on "
            "PyPI. Build frankaemika/franka_ros2 in a colcon workspace and source it, or use "
            "arm:=sim."
        ) from err
    import franka_msgs  # type: ignore[import-not-found]

    return franka_msgs


def arm_state_from_robot_state(msg: Any) -> ArmState:
    """Convert a ``FrankaRobotState`` (or anything with the same fields) into an ArmState.

    Uses ``header.stamp``, ``o_f_ext_hat_k.wrench.force`` and ``o_t_ee.pose.position.z``; the
    vertical velocity is the last commanded twist ``o_dp_ee_c.twist.linear.z`` (the message
    carries no measured Cartesian velocity).

    Raises:
        BehaviourError: A field is missing (another franka_msgs version).
    """
    try:
        stamp_ns = stamp_to_ns(msg.header.stamp)
        f = msg.o_f_ext_hat_k.wrench.force
        z = float(msg.o_t_ee.pose.position.z)
        twist = getattr(msg, "o_dp_ee_c", None)
        vz = float(twist.twist.linear.z) if twist is not None else math.nan
    except AttributeError as err:
        raise BehaviourError(
            f"The robot state lacks a field the adapter reads ({err}); expected "
            "franka_msgs/msg/FrankaRobotState with o_f_ext_hat_k and o_t_ee."
        ) from err
    return ArmState(stamp_ns, z, (float(f.x), float(f.y), float(f.z)), vz)


def collision_behavior_values(
    force_n: float, torque_nm: float, joint_torque_nm: float
) -> dict[str, list[float]]:
    """Field values of a ``SetFullCollisionBehavior`` request.

    The robot's own reflex is a safety net behind the behaviour's software stop: it stops at
    ``force_n`` (Cartesian x, y, z) and ``torque_nm`` (about x, y, z) and then needs error
    recovery, while the software stop at 10 N does not. Contact ("lower") thresholds are half
    the collision ("upper") ones; acceleration and nominal phases share the values.

    Raises:
        BehaviourError: A threshold is not positive.
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
