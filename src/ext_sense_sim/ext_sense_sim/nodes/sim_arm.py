"""``sim_arm``: a simulated Panda / FR3 behind franka_ros2's interfaces, for the food probe.

Offers what a franka_ros2 robot offers the food behaviour's adapter, under franka_ros2's default
names: the robot state at ``rate_hz`` (joints, ``o_t_ee``, ``o_f_ext_hat_k``, collision
indicators, robot mode, ``cartesian_reflex``), ``SetFullCollisionBehavior``, the
``FollowJointTrajectory`` action of ``joint_trajectory_controller`` (a new goal preempts, a
cancel holds, a reflex aborts) and ``ErrorRecovery``. The physics is
:class:`~ext_sense_sim.devices.franka_arm.SimFrankaArm`.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Any

import numpy as np
from control_msgs.action import FollowJointTrajectory
from franka_msgs.action import ErrorRecovery
from franka_msgs.msg import FrankaRobotState
from franka_msgs.srv import SetFullCollisionBehavior
from rclpy.action import ActionServer, CancelResponse, GoalResponse
from rclpy.action.server import ServerGoalHandle
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.task import Future
from scipy.spatial.transform import Rotation

from ext_sense_behaviours.franka import FrankaNames
from ext_sense_behaviours.panda_kinematics import Q_MAX, Q_MIN
from ext_sense_runtime.callback_guard import CallbackGuard
from ext_sense_runtime.diagnostics import Level, Updater
from ext_sense_runtime.diagnostics_ros import DiagnosticsPublisher
from ext_sense_runtime.node_main import run_node
from ext_sense_runtime.parameters import declare_all, param
from ext_sense_runtime.stamps import fill_stamp, stamp_to_ns
from ext_sense_sim.devices.franka_arm import (
    DEFAULT_THRESHOLDS,
    SimFrankaArm,
    SurfaceModel,
    TrajectoryState,
    start_pose,
)

_MODE_IDLE, _MODE_MOVE, _MODE_REFLEX = 1, 2, 4
_ERROR_CODE = {TrajectoryState.ABORTED: -4}  # PATH_TOLERANCE_VIOLATED, as the controller reports
_ro = functools.partial(param, read_only=True)


@dataclass(frozen=True)
class SimArmParameters:
    """``sim_arm``'s parameters, all read-only; the interface names are franka_ros2's."""

    surface_z_m: float = _ro(0.152, "Food surface height, m (< 0: none).", low=-1.0, high=2.0)
    stiffness_n_per_m: float = _ro(1000.0, "Surface stiffness, N/m.", low=1.0, high=1e6)
    force_noise_n: float = _ro(0.05, "Force estimate noise (1 sd per axis), N.", low=0.0, high=10.0)
    start_x_m: float = _ro(0.45, "End-effector start x, m (base frame).", low=0.2, high=0.7)
    start_z_m: float = _ro(0.16, "End-effector start height, m (base frame).", low=0.02, high=0.8)
    rate_hz: float = _ro(100.0, "State rate and physics step, Hz.", low=1.0, high=1000.0)
    joint_prefix: str = _ro("fr3", "Joint names are <prefix>_joint1..7.")
    seed: int = _ro(0, "Noise seed.", low=0, high=2**31 - 1)
    state_topic: str = _ro(FrankaNames.state_topic, "State topic.")
    collision_service: str = _ro(FrankaNames.collision_service, "SetFullCollisionBehavior service.")
    trajectory_action: str = _ro(
        FrankaNames.trajectory_action,
        "FollowJointTrajectory action of the simulated joint_trajectory_controller.",
    )
    error_recovery_action: str = _ro(FrankaNames.error_recovery_action, "ErrorRecovery action.")


class SimArmNode(Node):
    """The simulated robot (see module docstring)."""

    PARAMETERS = SimArmParameters

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(kwargs.pop("node_name", "sim_arm"), **kwargs)
        self.guard = CallbackGuard(self.get_logger().error)
        p = declare_all(self, SimArmParameters)
        surface = SurfaceModel(
            surface_z_m=p.surface_z_m if p.surface_z_m >= 0 else None,
            stiffness_n_per_m=p.stiffness_n_per_m,
            noise_n=p.force_noise_n,
        )
        q0 = start_pose(p.start_x_m, p.start_z_m)
        self.joint_names = [f"{p.joint_prefix}_joint{i}" for i in range(1, 8)]
        self.arm = SimFrankaArm(q0, surface, self._now_ns(), seed=p.seed)
        self._goal: tuple[ServerGoalHandle, Future] | None = None
        self.goals = {"accepted": 0, "rejected": 0, "succeeded": 0, "canceled": 0, "aborted": 0}
        self.threshold_requests = 0
        qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
        self.state_pub = self.create_publisher(FrankaRobotState, p.state_topic, qos)
        self.create_service(
            SetFullCollisionBehavior, p.collision_service, self.guard(self._on_thresholds)
        )
        self.trajectory_server = ActionServer(
            self,
            FollowJointTrajectory,
            p.trajectory_action,
            self._execute_trajectory,
            goal_callback=self._on_goal,
            cancel_callback=self._on_cancel,
        )
        self.recovery_server = ActionServer(
            self, ErrorRecovery, p.error_recovery_action, self._execute_recovery
        )
        self.create_timer(1.0 / p.rate_hz, self.guard(self._tick))
        self.updater = Updater(hardware_id="sim_arm")
        self.updater.add_check("arm", self._check)
        self.guard.attach(self.updater)
        self.diagnostics = DiagnosticsPublisher(self, self.updater)

    def destroy_node(self) -> None:
        """Destroy the action servers, then the node.

        rclpy's ``destroy_node`` leaves action servers alive until garbage collection, where a
        node made next in the same process would find them ready and send them its goals.
        """
        self.trajectory_server.destroy()
        self.recovery_server.destroy()
        super().destroy_node()

    def _now_ns(self) -> int:
        return self.get_clock().now().nanoseconds

    def _on_thresholds(self, request: Any, response: Any) -> Any:
        self.threshold_requests += 1
        values = {name: list(getattr(request, name)) for name in DEFAULT_THRESHOLDS}
        response.error = self.arm.set_thresholds(values)
        response.success = not response.error
        if response.error:
            self.get_logger().error(f"collision thresholds refused: {response.error}")
        return response

    def _on_goal(self, request: Any) -> GoalResponse:
        """Refuse what the controller refuses: unknown joints, positions beyond the limits."""
        trajectory = request.trajectory
        if sorted(trajectory.joint_names) != sorted(self.joint_names) or not trajectory.points:
            self.goals["rejected"] += 1
            self.get_logger().error(f"trajectory refused: joints {list(trajectory.joint_names)}")
            return GoalResponse.REJECT
        return GoalResponse.ACCEPT

    def _on_cancel(self, handle: ServerGoalHandle) -> CancelResponse:
        """Stop at once (as the controller does on its next cycle), not at the next state tick."""
        goal = self._goal
        if goal is not None and goal[0] is handle:
            self.arm.cancel(self._now_ns())
        return CancelResponse.ACCEPT

    async def _execute_trajectory(self, handle: ServerGoalHandle) -> Any:
        trajectory = handle.request.trajectory
        order = [list(trajectory.joint_names).index(n) for n in self.joint_names]
        points = np.array([[p.positions[i] for i in order] for p in trajectory.points])
        times = np.array([stamp_to_ns(p.time_from_start) / 1e9 for p in trajectory.points])
        result = FollowJointTrajectory.Result()
        if np.any(points < Q_MIN - 1e-9) or np.any(points > Q_MAX + 1e-9):
            why = "positions beyond the joint limits"
        else:
            why = self.arm.follow(times, points, self._now_ns())
        if why:
            self.goals["aborted"] += 1
            handle.abort()
            result.error_code, result.error_string = -1, why  # INVALID_GOAL
            return result
        self.goals["accepted"] += 1
        previous, done = self._goal, Future()
        self._goal = (handle, done)
        if previous is not None:
            previous[1].set_result("preempted by a new goal")
        reason = await done
        state = self.arm.trajectory_state if reason is None else TrajectoryState.ABORTED
        if handle.is_cancel_requested and state != TrajectoryState.SUCCEEDED:
            state = TrajectoryState.CANCELED
        self.goals[state] = self.goals.get(state, 0) + 1
        if state == TrajectoryState.SUCCEEDED:
            handle.succeed()
        elif state == TrajectoryState.CANCELED:
            handle.canceled()
        else:
            handle.abort()
            result.error_code = _ERROR_CODE[TrajectoryState.ABORTED]
            result.error_string = reason or self.arm.abort_reason
        return result

    async def _execute_recovery(self, handle: ServerGoalHandle) -> Any:
        self.arm.recover()
        self.get_logger().info("error recovery: reflex cleared")
        handle.succeed()
        return ErrorRecovery.Result()

    def _tick(self) -> None:
        now = self._now_ns()
        goal = self._goal
        if goal is not None and goal[0].is_cancel_requested:
            self.arm.cancel(now)
        else:
            self.arm.step(now)
        if goal is not None and self.arm.trajectory_state != TrajectoryState.RUNNING:
            self._goal = None
            if not goal[1].done():
                goal[1].set_result(None)
        self.state_pub.publish(self._state_msg(now))

    def _state_msg(self, now_ns: int) -> FrankaRobotState:
        arm = self.arm
        msg = FrankaRobotState()
        fill_stamp(msg.header.stamp, now_ns)
        msg.header.frame_id = "base"
        joints = msg.measured_joint_state
        joints.header = msg.header
        joints.name = self.joint_names
        joints.position, joints.velocity = arm.q.tolist(), arm.dq.tolist()
        joints.effort = [0.0] * 7
        pose = arm.pose
        ee = msg.o_t_ee
        ee.header = msg.header
        ee.pose.position.x, ee.pose.position.y, ee.pose.position.z = pose[:3, 3].tolist()
        w, x, y, z = Rotation.from_matrix(pose[:3, :3]).as_quat(scalar_first=True).tolist()
        ee.pose.orientation.w, ee.pose.orientation.x = w, x
        ee.pose.orientation.y, ee.pose.orientation.z = y, z
        wrench = msg.o_f_ext_hat_k
        wrench.header = msg.header
        f = wrench.wrench.force
        f.x, f.y, f.z = arm.force_n.tolist()
        flags = msg.collision_indicators
        c, k = flags.is_cartesian_linear_contact, flags.is_cartesian_linear_collision
        c.x, c.y, c.z = (float(v) for v in arm.contact)
        k.x, k.y, k.z = (float(v) for v in arm.collision)
        moving = arm.trajectory_state == TrajectoryState.RUNNING
        msg.robot_mode = _MODE_REFLEX if arm.reflex else _MODE_MOVE if moving else _MODE_IDLE
        msg.current_errors.cartesian_reflex = arm.reflex
        return msg

    def _check(self) -> tuple[Level, str, dict[str, object]]:
        arm = self.arm
        level = Level.WARN if arm.reflex else Level.OK
        text = "reflex: waiting for error recovery" if arm.reflex else arm.trajectory_state
        return (
            level,
            text,
            {
                "z_m": f"{arm.pose[2, 3]:.4f}",
                "force_z_n": f"{arm.force_n[2]:.2f}",
                "threshold_requests": self.threshold_requests,
                **{f"goals_{k}": v for k, v in self.goals.items()},
            },
        )


def main(args: list[str] | None = None) -> int:
    """Run the node."""
    return run_node(SimArmNode, args)
