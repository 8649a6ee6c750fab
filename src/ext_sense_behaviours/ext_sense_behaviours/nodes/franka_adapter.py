"""The franka_ros2 arm adapter: the food probe's arm on a Panda / FR3 under franka_ros2.

Reads ``FrankaRobotState``, sets the collision reflex (``SetFullCollisionBehavior``) as a
safety net behind the 10 N software stop, moves through ``FollowJointTrajectory`` (vertical
lines as joint waypoints), stops the descent itself on a contact or collision flag or reflex
mode, and offers ``ErrorRecovery``. A goal not accepted within ``accept_timeout_s``, or without
a result within its planned duration plus ``result_margin_s``, is canceled and reported once
(:meth:`FrankaArmAdapter.take_failure`), so the behaviour stops and holds.
``ext_sense_sim.nodes.sim_arm`` speaks the same interfaces.
"""

from __future__ import annotations

import uuid
from collections.abc import Callable
from typing import Any

import numpy as np
from builtin_interfaces.msg import Duration
from control_msgs.action import FollowJointTrajectory
from rclpy.action import ActionClient
from rclpy.action.client import ClientGoalHandle
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from trajectory_msgs.msg import JointTrajectoryPoint
from unique_identifier_msgs.msg import UUID

from ext_sense_behaviours.errors import BehaviourError
from ext_sense_behaviours.franka import (
    FrankaNames,
    RobotReading,
    collision_behavior_values,
    import_franka_msgs,
    reading_from_robot_state,
)
from ext_sense_behaviours.nodes.deadline import Deadline
from ext_sense_behaviours.panda_kinematics import vertical_line
from ext_sense_behaviours.records import ArmState

ACCEPT_TIMEOUT_S = 2.0
"""Longest wait for the controller to accept a trajectory goal (it answers in milliseconds)."""
RESULT_MARGIN_S = 5.0
"""Longest wait for a trajectory's result beyond its planned duration, s."""


def _duration(seconds: float) -> Duration:
    ns = round(seconds * 1e9)
    return Duration(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


class FrankaArmAdapter:
    """A Panda / FR3 under franka_ros2 as an :class:`~ext_sense_behaviours.arm.ArmAdapter`.

    ``node`` owns the subscription, clients and timer; ``guard`` wraps each callback. The
    reflex thresholds are the collision ones (contact flags at half these); ``max_descent_m``
    is the planned descent, m (the behaviour stops it earlier). BehaviourError when franka_msgs
    is not installed or a threshold is not positive.
    """

    def __init__(
        self,
        node: Node,
        names: FrankaNames | None = None,
        collision_force_n: float = 20.0,
        collision_torque_nm: float = 20.0,
        joint_torque_nm: float = 40.0,
        max_descent_m: float = 0.15,
        guard: Callable[[Callable[..., Any]], Callable[..., Any]] | None = None,
        accept_timeout_s: float = ACCEPT_TIMEOUT_S,
        result_margin_s: float = RESULT_MARGIN_S,
    ) -> None:
        fm = import_franka_msgs()
        import franka_msgs.action  # type: ignore[import-not-found]

        wrap = guard or (lambda f: f)
        self.node = node
        self.names = names or FrankaNames()
        self.max_descent_m = float(max_descent_m)
        self.accept_timeout_s = float(accept_timeout_s)
        self.result_margin_s = float(result_margin_s)
        self.thresholds = collision_behavior_values(
            collision_force_n, collision_torque_nm, joint_torque_nm
        )
        self.reading: RobotReading | None = None
        self._returned_ns: int | None = None
        self._goal: Any = None  # the accepted goal handle of the motion under way
        self._motion_id = 0  # bumps at every command: answers for older goals are stale
        self.descending = False
        self.counters = {
            "bad_states": 0,
            "contact_stops": 0,
            "goals_sent": 0,
            "goals_rejected": 0,
            "goals_unanswered": 0,
            "goals_timed_out": 0,
            "goals_failed": 0,
        }
        self._failure: str | None = None  # the newest motion's failure, not yet taken
        self._deadline = Deadline(node, wrap)
        self.thresholds_set: bool | None = None  # None: not yet answered
        self.last_error = ""
        state_qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
        node.create_subscription(
            fm.msg.FrankaRobotState, self.names.state_topic, wrap(self._on_state), state_qos
        )
        self._trajectory = ActionClient(node, FollowJointTrajectory, self.names.trajectory_action)
        self._collision = node.create_client(
            fm.srv.SetFullCollisionBehavior, self.names.collision_service
        )
        self._recovery = ActionClient(
            node, franka_msgs.action.ErrorRecovery, self.names.error_recovery_action
        )
        self._srv_types = fm.srv
        self._action_types = franka_msgs.action
        self._threshold_request: Any = None
        self._configure_timer = node.create_timer(0.2, wrap(self._send_thresholds))

    # -- the collision reflex ------------------------------------------------------------------

    def _send_thresholds(self) -> None:
        """Send the thresholds once the robot's service is there (a timer, never blocking)."""
        if self._threshold_request is not None or not self._collision.service_is_ready():
            return
        request = self._srv_types.SetFullCollisionBehavior.Request()
        for field, values in self.thresholds.items():
            setattr(request, field, values)
        self._threshold_request = self._collision.call_async(request)
        self._threshold_request.add_done_callback(self._on_thresholds)
        self.node.destroy_timer(self._configure_timer)

    def _on_thresholds(self, future: Any) -> None:
        response = future.result()
        self.thresholds_set = bool(response is not None and response.success)
        if self.thresholds_set:
            self.node.get_logger().info(
                f"robot collision reflex set: {self.thresholds['upper_force_thresholds_nominal']}"
            )
        else:
            self.last_error = f"collision thresholds refused: {getattr(response, 'error', '')}"
            self.node.get_logger().error(self.last_error)

    def recover(self) -> Any:
        """Send an error-recovery goal (after a reflex); returns the goal future.

        Raises:
            BehaviourError: The robot's error recovery action is not available.
        """
        if not self._recovery.server_is_ready():
            raise BehaviourError(
                f"error recovery action '{self.names.error_recovery_action}' not available"
            )
        return self._recovery.send_goal_async(self._action_types.ErrorRecovery.Goal())

    # -- state ---------------------------------------------------------------------------------

    def _on_state(self, msg: Any) -> None:
        try:
            reading = reading_from_robot_state(msg)
        except BehaviourError as err:
            self.counters["bad_states"] += 1
            self.node.get_logger().error(str(err), throttle_duration_sec=5.0)
            return
        self.reading = reading
        if self.descending and (reading.contact or reading.collision or reading.reflex):
            what = "reflex" if reading.reflex else "collision" if reading.collision else "contact"
            self.counters["contact_stops"] += 1
            self.node.get_logger().warning(
                f"robot {what} flag at |F|={reading.state.force_norm_n:.1f} N: descent stopped"
            )
            self.stop()

    def destroy(self) -> None:
        """Destroy the action clients (the owning node's ``destroy_node`` leaves them alive)."""
        self._deadline.disarm()
        self._trajectory.destroy()
        self._recovery.destroy()

    @property
    def trajectory_ready(self) -> bool:
        """Whether the trajectory controller's action server is discovered (motions can start)."""
        return bool(self._trajectory.server_is_ready())

    def read_state(self) -> ArmState | None:
        """The newest state not returned before, else ``None``."""
        reading = self.reading
        if reading is None or reading.state.stamp_ns == self._returned_ns:
            return None
        self._returned_ns = reading.state.stamp_ns
        return reading.state

    # -- motion --------------------------------------------------------------------------------

    def move_down(self, speed_mps: float) -> None:
        """Plan ``max_descent_m`` straight down at ``speed_mps`` and send it to the controller."""
        self._line(-self.max_descent_m, speed_mps)
        self.descending = True

    def retract(self, height_m: float, speed_mps: float) -> None:
        """Plan straight up to ``height_m`` at ``speed_mps`` (nothing when already there)."""
        dz = float(height_m) - self._reading().state.z_m
        if dz > 1e-5:
            self._line(dz, speed_mps)

    def _reading(self) -> RobotReading:
        if self.reading is None:
            raise BehaviourError("no robot state yet: cannot plan a motion")
        return self.reading

    def take_failure(self) -> str | None:
        """Why the newest motion failed, once (``None``: it did not, or it was taken).

        Rejected, unanswered, timed out, aborted or canceled by someone else; a new motion
        clears a failure nobody took.
        """
        failure, self._failure = self._failure, None
        return failure

    def stop(self) -> None:
        """Cancel the motion under way; the controller holds where the arm is."""
        self.descending = False
        self._motion_id += 1
        self._deadline.disarm()
        goal, self._goal = self._goal, None
        if goal is not None:
            goal.cancel_goal_async()

    def _line(self, dz_m: float, speed_mps: float) -> None:
        """Send a vertical line of ``dz_m`` from the measured joints as a trajectory goal."""
        self.stop()
        reading = self._reading()
        times, positions = vertical_line(reading.q, dz_m, abs(float(speed_mps)))
        velocities = np.gradient(positions, times, axis=0) if len(times) > 1 else None
        goal = FollowJointTrajectory.Goal()
        goal.trajectory.joint_names = list(reading.joint_names)
        for i, t in enumerate(times):
            point = JointTrajectoryPoint(
                positions=positions[i].tolist(), time_from_start=_duration(float(t))
            )
            if velocities is not None:  # at rest at the end
                point.velocities = velocities[i].tolist() if i < len(times) - 1 else [0.0] * 7
            goal.trajectory.points.append(point)
        if not self._trajectory.server_is_ready():
            self.counters["goals_failed"] += 1
            raise BehaviourError(
                f"trajectory action '{self.names.trajectory_action}' not available: is the "
                "joint_trajectory_controller loaded and active?"
            )
        motion, planned_s = self._motion_id, float(times[-1])
        goal_id = UUID(uuid=list(uuid.uuid4().bytes))  # ours: a goal never answered can be canceled
        self._failure = None  # a failure of an earlier motion is no longer news
        self.counters["goals_sent"] += 1
        self._deadline.arm(self.accept_timeout_s, lambda: self._unanswered(motion, goal_id))
        future = self._trajectory.send_goal_async(goal, goal_uuid=goal_id)
        future.add_done_callback(lambda f: self._on_goal_response(f, motion, planned_s))

    def _fail(self, counter: str, text: str) -> None:
        """Count and log the current motion's failure; the behaviour takes it next."""
        self.counters[counter] += 1
        self.descending = False
        self.last_error = self._failure = text
        self.node.get_logger().error(text)

    def _unanswered(self, motion: int, goal_id: UUID) -> None:
        if motion != self._motion_id:
            return
        self._motion_id += 1  # an acceptance after this is stale: it gets canceled
        # The controller may have accepted the goal and be moving, its answer lost on the way:
        # cancel it by its id (a controller that never got it answers "unknown goal").
        lost = ClientGoalHandle(
            self._trajectory, goal_id, FollowJointTrajectory.Impl.SendGoalService.Response()
        )
        lost.cancel_goal_async()
        self._fail(
            "goals_unanswered",
            f"trajectory goal not answered within {self.accept_timeout_s:.1f} s: canceled",
        )

    def _on_goal_response(self, future: Any, motion: int, planned_s: float) -> None:
        handle = future.result()
        if motion != self._motion_id:  # stopped, replaced or abandoned before the answer
            if handle is not None and handle.accepted:
                handle.cancel_goal_async()
            return
        self._deadline.disarm()
        if handle is None or not handle.accepted:
            self._fail("goals_rejected", "trajectory goal rejected by the controller")
            return
        self._goal = handle
        self._deadline.arm(planned_s + self.result_margin_s, lambda: self._no_result(handle))
        handle.get_result_async().add_done_callback(lambda f: self._on_result(f, handle))

    def _no_result(self, handle: Any) -> None:
        if self._goal is not handle:
            return
        self._goal = None
        self._motion_id += 1
        handle.cancel_goal_async()
        self._fail(
            "goals_timed_out",
            f"trajectory goal had no result {self.result_margin_s:.1f} s after its planned end: "
            "canceled",
        )

    def _on_result(self, future: Any, handle: Any) -> None:
        from action_msgs.msg import GoalStatus

        if self._goal is not handle:  # stopped, replaced or timed out: nobody waits for it
            return
        self._goal = None
        self._deadline.disarm()
        outcome = future.result()
        if outcome is None or outcome.status == GoalStatus.STATUS_SUCCEEDED:
            return
        if outcome.status == GoalStatus.STATUS_CANCELED:  # ours clear ``_goal`` first: not ours
            why = "canceled by the controller"
        else:
            why = f"ended with status {outcome.status}: "
            why += str(outcome.result.error_string or outcome.result.error_code)
        self._fail("goals_failed", f"trajectory goal {why}")

    def status(self) -> dict[str, object]:
        """Key-values for ``/diagnostics``."""
        reading = self.reading
        return {
            **self.counters,
            "thresholds_set": {None: "pending", True: "yes", False: "refused"}[self.thresholds_set],
            "robot_reflex": bool(reading is not None and reading.reflex),
            "robot_contact": bool(reading is not None and reading.contact),
            "last_error": self.last_error or "none",
        }
