"""The franka_ros2 arm adapter (needs franka_msgs, which is not on PyPI: not runnable here).

Implements :class:`~ext_sense_behaviours.arm.ArmAdapter` on a node: reads
``FrankaRobotState`` from the state topic, streams ``geometry_msgs/TwistStamped`` Cartesian
velocity commands at ``command_rate_hz`` (a velocity controller needs a steady stream; zero
twist when stopped), sets the robot's collision reflex through ``SetFullCollisionBehavior`` as a
safety net behind the 10 N software stop, and offers error recovery through the
``ErrorRecovery`` action. Names are parameters (:class:`~ext_sense_behaviours.franka.FrankaNames`).
Imported lazily by the ``food_behaviour`` node only when ``arm`` is ``franka``.
"""

from __future__ import annotations

from typing import Any

from geometry_msgs.msg import TwistStamped
from rclpy.action import ActionClient
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy

from ext_sense_behaviours.errors import BehaviourError
from ext_sense_behaviours.franka import (
    FrankaNames,
    arm_state_from_robot_state,
    collision_behavior_values,
    import_franka_msgs,
)
from ext_sense_behaviours.records import ArmState
from ext_sense_runtime.qos import COMMAND_QOS


class FrankaArmAdapter:
    """A Panda under franka_ros2 as an :class:`~ext_sense_behaviours.arm.ArmAdapter`.

    Args:
        node: The node that owns the subscriptions, publisher, clients and timer.
        names: Topic, service and action names.
        command_rate_hz: Rate of the twist stream, Hz.
        collision_force_n, collision_torque_nm, joint_torque_nm: Reflex thresholds.

    Raises:
        BehaviourError: franka_msgs is not installed.
    """

    def __init__(
        self,
        node: Node,
        names: FrankaNames | None = None,
        command_rate_hz: float = 100.0,
        collision_force_n: float = 20.0,
        collision_torque_nm: float = 20.0,
        joint_torque_nm: float = 40.0,
    ) -> None:
        fm = import_franka_msgs()
        import franka_msgs.action  # type: ignore[import-not-found]

        self.node = node
        self.names = names or FrankaNames()
        self._latest: ArmState | None = None
        self._returned_ns: int | None = None
        self._vz = 0.0
        self._target_z: float | None = None
        self.bad_states = 0
        state_qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
        node.create_subscription(
            fm.msg.FrankaRobotState, self.names.state_topic, self._on_state, state_qos
        )
        self._twist_pub = node.create_publisher(TwistStamped, self.names.twist_topic, COMMAND_QOS)
        self._collision = node.create_client(
            fm.srv.SetFullCollisionBehavior, self.names.collision_service
        )
        self._recovery = ActionClient(
            node, franka_msgs.action.ErrorRecovery, self.names.error_recovery_action
        )
        self._srv_types = fm.srv
        self._action_types = franka_msgs.action
        self.set_collision_behavior(collision_force_n, collision_torque_nm, joint_torque_nm)
        node.create_timer(1.0 / command_rate_hz, self._send)

    def set_collision_behavior(self, force_n: float, torque_nm: float, joint_nm: float) -> Any:
        """Ask the robot to set its collision reflex thresholds (asynchronous)."""
        request = self._srv_types.SetFullCollisionBehavior.Request()
        for field, values in collision_behavior_values(force_n, torque_nm, joint_nm).items():
            setattr(request, field, values)
        if not self._collision.wait_for_service(timeout_sec=2.0):
            self.node.get_logger().error(
                f"collision service '{self.names.collision_service}' not available; the robot "
                "keeps its current reflex thresholds"
            )
            return None
        return self._collision.call_async(request)

    def recover(self) -> Any:
        """Send an error-recovery goal (after a reflex stop)."""
        if not self._recovery.wait_for_server(timeout_sec=2.0):
            raise BehaviourError(
                f"error recovery action '{self.names.error_recovery_action}' not available"
            )
        return self._recovery.send_goal_async(self._action_types.ErrorRecovery.Goal())

    def _on_state(self, msg: Any) -> None:
        try:
            self._latest = arm_state_from_robot_state(msg)
        except BehaviourError as err:
            self.bad_states += 1
            self.node.get_logger().error(str(err), throttle_duration_sec=5.0)
            return
        if self._target_z is not None and self._vz > 0 and self._latest.z_m >= self._target_z:
            self._vz, self._target_z = 0.0, None

    def _send(self) -> None:
        msg = TwistStamped()
        msg.header.stamp = self.node.get_clock().now().to_msg()
        msg.header.frame_id = "base"
        msg.twist.linear.z = self._vz
        self._twist_pub.publish(msg)

    def move_down(self, speed_mps: float) -> None:
        """Stream a downward twist of ``speed_mps``."""
        self._vz, self._target_z = -abs(float(speed_mps)), None
        self._send()

    def stop(self) -> None:
        """Stream zero twist."""
        self._vz, self._target_z = 0.0, None
        self._send()

    def retract(self, height_m: float, speed_mps: float) -> None:
        """Stream an upward twist until the state reports ``height_m``."""
        self._vz, self._target_z = abs(float(speed_mps)), float(height_m)
        self._send()

    def read_state(self) -> ArmState | None:
        """The newest state not returned before, else ``None``."""
        state = self._latest
        if state is None or state.stamp_ns == self._returned_ns:
            return None
        self._returned_ns = state.stamp_ns
        return state
