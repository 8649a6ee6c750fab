"""``robotiq_gripper`` node: a Robotiq 2F over Modbus RTU behind the standard gripper actions.

Serves ``/<controller_name>/gripper_cmd`` (``GripperCommand``: gap in m, ``max_effort`` in N)
and ``/<parallel_controller_name>/gripper_cmd`` (``ParallelGripperCommand``), as MoveIt and
``ros2_control`` controllers do (code for PickNik's ``ros2_robotiq_gripper`` works unchanged).
``stalled`` (gOBJ 1 or 2) and ``reached_goal`` (gOBJ 3) are both a success. A goal outside the
stroke or not finite is rejected before anything moves; a newer goal preempts the running one;
a cancel stops the fingers. Every poll publishes ``joint_states`` (the gap) and
``gripper/status`` (register fields, ``link`` ok / error); ``gripper/activate`` (Bool) resets
and activates (true) or resets (false). A lifecycle node like the drivers; the serial link
lives in a :class:`~ext_sense_behaviours.gripper_worker.GripperWorker` thread.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass, field
from typing import Any

from control_msgs.action import GripperCommand, ParallelGripperCommand
from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
from rclpy.action import ActionServer, CancelResponse, GoalResponse
from rclpy.action.server import ServerGoalHandle
from rclpy.lifecycle import LifecycleNode, State, TransitionCallbackReturn
from rclpy.task import Future
from sensor_msgs.msg import JointState
from std_msgs.msg import Bool

from ext_sense_behaviours.gripper import describe, status_level, status_to_values
from ext_sense_behaviours.gripper_action import (
    GoalOutcome,
    GripperScale,
    failed,
    goal_outcome,
    goal_problem,
)
from ext_sense_behaviours.gripper_worker import GripperCommandRequest, GripperWorker
from ext_sense_drivers.robotiq import GripperStatus, RobotiqClient, RobotiqError
from ext_sense_runtime.diagnostics import Level, Updater
from ext_sense_runtime.diagnostics_ros import DiagnosticsPublisher
from ext_sense_runtime.node_main import run_node
from ext_sense_runtime.parameters import declare_all, param
from ext_sense_runtime.qos import COMMAND_QOS


def _fraction_to_byte(value: float) -> int:
    return round(min(max(value, 0.0), 1.0) * 255)


@dataclass
class _Goal:
    """The goal being carried out; ``pending`` while its move waits for a ready gripper."""

    handle: ServerGoalHandle
    move: GripperCommandRequest
    force_n: float
    deadline: float
    pending: bool
    future: Future = field(default_factory=Future)

    def finish(self, outcome: GoalOutcome) -> None:
        if not self.future.done():
            self.future.set_result(outcome)


@dataclass(frozen=True)
class RobotiqParameters:
    """``robotiq_gripper``'s parameters; speed, force and goal_timeout_s change live."""

    port: str = param("", "Serial device of the gripper.", read_only=True)
    baud: int = param(115200, "Baud rate, bit/s.", low=9600, high=921600, read_only=True)
    slave_id: int = param(9, "Modbus slave id.", low=1, high=247, read_only=True)
    timeout_s: float = param(
        0.5, "Reply timeout per exchange, seconds.", low=0.01, high=5.0, read_only=True
    )
    retries: int = param(
        2, "Retries after a missing or corrupt reply.", low=0, high=10, read_only=True
    )
    poll_rate_hz: float = param(10.0, "Status poll rate, Hz.", low=0.5, high=100.0, read_only=True)
    auto_activate: bool = param(True, "Activate the gripper on connect.")
    speed: float = param(
        0.5, "Finger speed of GripperCommand goals, 0..1 of maximum.", low=0.0, high=1.0
    )
    force: float = param(
        0.5, "Grip force of goals with no max_effort, 0..1 of maximum.", low=0.0, high=1.0
    )
    joint_name: str = param("robotiq_finger_gap", "Joint name in joint_states.", read_only=True)
    stroke_m: float = param(
        0.085,
        "Finger gap fully open, m (2F-85: 0.085, 2F-140: 0.14).",
        low=0.01,
        high=0.5,
        read_only=True,
    )
    max_force_n: float = param(
        235.0, "Grip force at full force setting, N.", low=1.0, high=1000.0, read_only=True
    )
    max_speed_m_s: float = param(
        0.15, "Finger speed at full speed setting, m/s.", low=0.001, high=1.0, read_only=True
    )
    goal_timeout_s: float = param(
        5.0, "Longest time a goal may take before it is aborted, s.", low=0.1, high=60.0
    )
    controller_name: str = param(
        "/robotiq_gripper_controller",
        "Namespace of the GripperCommand action (<name>/gripper_cmd).",
        read_only=True,
    )
    parallel_controller_name: str = param(
        "/robotiq_parallel_gripper_controller",
        "Namespace of the ParallelGripperCommand action (<name>/gripper_cmd).",
        read_only=True,
    )
    autostart: bool = param(
        True,
        "Configure and activate this lifecycle node at start-up (ros2 run, tests); the graphs "
        "set it false and drive the transitions themselves (launch events, ext-sense run), or "
        "leave them to an external manager (manage_drivers:=false).",
        read_only=True,
    )


class RobotiqGripperNode(LifecycleNode):
    """Drives one Robotiq 2F gripper (a lifecycle node: see the module docstring)."""

    PARAMETERS = RobotiqParameters

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(kwargs.pop("node_name", "robotiq_gripper"), **kwargs)
        self.p = p = declare_all(self, RobotiqParameters, self._on_change)
        self.port = p.port
        self.scale = GripperScale(p.stroke_m, p.max_force_n, p.max_speed_m_s)
        controller, parallel = p.controller_name, p.parallel_controller_name

        self._lock = threading.Lock()
        self.status: GripperStatus | None = None
        self.error: str = ""
        self._goal: _Goal | None = None
        self.goals = {"succeeded": 0, "aborted": 0, "canceled": 0, "rejected": 0}
        self.status_pub = self.create_publisher(DiagnosticStatus, "gripper/status", COMMAND_QOS)
        self.joint_pub = self.create_publisher(JointState, "joint_states", COMMAND_QOS)
        self.create_subscription(Bool, "gripper/activate", self._on_activate, COMMAND_QOS)
        self.active = False
        self.gripper_server = ActionServer(
            self,
            GripperCommand,
            f"{controller.rstrip('/')}/gripper_cmd",
            self._execute_gripper_command,
            goal_callback=self._on_goal_request,
            cancel_callback=lambda _: CancelResponse.ACCEPT,
        )
        self.parallel_server = ActionServer(
            self,
            ParallelGripperCommand,
            f"{parallel.rstrip('/')}/gripper_cmd",
            self._execute_parallel_command,
            goal_callback=self._on_goal_request,
            cancel_callback=lambda _: CancelResponse.ACCEPT,
        )

        self.worker: GripperWorker | None = None
        self._open_worker = lambda: GripperWorker(
            lambda: RobotiqClient.open(
                p.port, p.baud, p.timeout_s, slave=p.slave_id, retries=p.retries
            ),
            self._on_worker_status,
            poll_period_s=1.0 / p.poll_rate_hz,
            auto_activate=self.p.auto_activate,
        )
        if not self.port:
            self.error = (
                "parameter 'port' is empty: set it to the gripper's serial device (e.g. the pty "
                "path printed by `ext-sense sim serve robotiq`)"
            )
            self.get_logger().error(self.error)
            self.create_timer(1.0, lambda: self._publish_status(None, None))
        self.updater = Updater(hardware_id=self.port or "no port")
        self.updater.add_check("link", self._check_link)
        self.diagnostics = DiagnosticsPublisher(self, self.updater)
        if p.autostart:
            self.trigger_configure()
            self.trigger_activate()
        else:
            self.get_logger().info("unconfigured: waiting for a lifecycle manager to configure")

    def on_configure(self, state: State) -> TransitionCallbackReturn:
        """Open the Modbus link: the worker thread connects (retrying) and polls."""
        if not self.port:
            self.get_logger().error(f"cannot configure: {self.error}")
            return TransitionCallbackReturn.FAILURE
        self.worker = self._open_worker()
        self.worker.start()
        self.get_logger().info(f"configured: opening the gripper on {self.port}")
        return TransitionCallbackReturn.SUCCESS

    def on_activate(self, state: State) -> TransitionCallbackReturn:
        """Serve: gripper goals are accepted from now on."""
        self.active = True
        self.get_logger().info("active: serving the gripper actions")
        return TransitionCallbackReturn.SUCCESS

    def on_deactivate(self, state: State) -> TransitionCallbackReturn:
        """Stop serving; a goal under way is aborted; the link stays open."""
        self.active = False
        with self._lock:
            goal = self._goal
        if goal is not None:
            goal.finish(failed(self._current_gap(), "gripper deactivated"))
        return TransitionCallbackReturn.SUCCESS

    def on_cleanup(self, state: State) -> TransitionCallbackReturn:
        """Close the link (the worker thread stops and closes the port)."""
        worker, self.worker = self.worker, None
        if worker is not None:
            worker.stop()
        with self._lock:
            self.status = None
        return TransitionCallbackReturn.SUCCESS

    def on_shutdown(self, state: State) -> TransitionCallbackReturn:
        """Close the link on the way out from any state."""
        self.on_deactivate(state)
        return self.on_cleanup(state)

    def _on_goal_request(self, request: Any) -> GoalResponse:
        why = goal_problem(self.scale, request) if self.active else "the node is not active"
        if why:
            self.get_logger().error(f"gripper goal refused: {why}")
            self.goals["rejected"] += 1
            return GoalResponse.REJECT
        return GoalResponse.ACCEPT

    def _on_change(self, new: RobotiqParameters) -> None:
        self.p = new

    async def _execute_gripper_command(self, goal_handle: ServerGoalHandle) -> Any:
        command = goal_handle.request.command
        outcome = await self._carry_out(goal_handle, command.position, None, command.max_effort)
        return GripperCommand.Result(
            position=outcome.position_m,
            effort=outcome.effort_n,
            stalled=outcome.stalled,
            reached_goal=outcome.reached_goal,
        )

    async def _execute_parallel_command(self, goal_handle: ServerGoalHandle) -> Any:
        command = goal_handle.request.command  # checked by _on_goal_request
        velocity = command.velocity[0] if command.velocity else None
        effort = command.effort[0] if command.effort else 0.0
        outcome = await self._carry_out(goal_handle, command.position[0], velocity, effort)
        state = JointState(name=[self.p.joint_name], position=[outcome.position_m])
        state.effort = [outcome.effort_n]
        state.header.stamp = self.get_clock().now().to_msg()
        return ParallelGripperCommand.Result(
            state=state, stalled=outcome.stalled, reached_goal=outcome.reached_goal
        )

    def _current_gap(self) -> float:
        status = self.status
        return self.scale.gap_m(status.position) if status is not None else float("nan")

    def _refuse(self, goal_handle: ServerGoalHandle, why: str) -> GoalOutcome:
        self.get_logger().error(f"gripper goal aborted: {why}")
        goal_handle.abort()
        self.goals["aborted"] += 1
        return failed(self._current_gap(), why)

    async def _carry_out(
        self,
        goal_handle: ServerGoalHandle,
        gap_m: float,
        velocity_m_s: float | None,
        effort_n: float,
    ) -> GoalOutcome:
        """Send one move to the worker and wait for the status that ends it."""
        with self._lock:
            status, error = self.status, self.error
        if self.worker is None or error or (status is not None and status.fault):
            why = error or ("not configured" if status is None else describe(status))
            return self._refuse(goal_handle, f"gripper not ready ({why})")
        target = self.scale.position_counts(gap_m)
        force = self.scale.force_counts(effort_n, _fraction_to_byte(self.p.force))
        speed = self.scale.speed_counts(velocity_m_s, _fraction_to_byte(self.p.speed))
        goal = _Goal(
            goal_handle,
            GripperCommandRequest("move", target, speed, force),
            force / 255 * self.scale.max_force_n,
            time.monotonic() + self.p.goal_timeout_s,
            pending=status is None or not status.ready,  # just started: not yet read or active
        )
        with self._lock:
            previous, self._goal = self._goal, goal
        if previous is not None:
            previous.finish(failed(self._current_gap(), "preempted by a newer goal"))
        if not goal.pending:
            self._submit(goal)
        outcome: GoalOutcome = await goal.future
        with self._lock:
            if self._goal is goal:
                self._goal = None
        if goal_handle.is_cancel_requested and not outcome.succeeded:
            goal_handle.canceled()
            self.goals["canceled"] += 1
        elif outcome.succeeded:
            goal_handle.succeed()
            self.goals["succeeded"] += 1
        else:
            self.get_logger().error(f"gripper goal aborted: {outcome.reason}")
            goal_handle.abort()
            self.goals["aborted"] += 1
        return outcome

    def _on_activate(self, msg: Bool) -> None:
        if self.worker is not None:
            self.worker.submit(GripperCommandRequest("activate" if msg.data else "reset"))

    def _on_worker_status(self, status: GripperStatus | None, error: RobotiqError | None) -> None:
        with self._lock:
            self.status = status
            previous, self.error = self.error, "" if error is None else str(error)
            goal = self._goal
        if error is not None and str(error) != previous:
            self.get_logger().error(f"gripper: {error}")
        if goal is not None:
            self._advance(goal, status, error)
        self._publish_status(status, error)

    def _submit(self, goal: _Goal) -> None:
        if self.worker is None or not self.worker.submit(goal.move):
            goal.finish(failed(self._current_gap(), "command queue full"))

    def _advance(
        self, goal: _Goal, status: GripperStatus | None, error: RobotiqError | None
    ) -> None:
        """Finish the running goal when this status (or error) decides it (worker thread)."""
        gap = self.scale.gap_m(status.position) if status is not None else float("nan")
        if goal.pending and error is None and status is not None and not status.fault:
            if status.ready:  # ready now: the move goes out
                goal.pending = False
                self._submit(goal)
            elif time.monotonic() > goal.deadline or goal.handle.is_cancel_requested:
                goal.finish(failed(gap, describe(status)))
        elif error is not None:
            goal.finish(failed(gap, str(error)))
        elif status is not None:
            outcome = goal_outcome(status, goal.move.position, self.scale, goal.force_n)
            if outcome is not None:
                goal.finish(outcome)
            elif time.monotonic() > goal.deadline:
                goal.finish(failed(gap, "goal timed out"))
            elif goal.handle.is_cancel_requested and self.worker is not None:
                # stop where the fingers are: a go-to the current position ends the motion
                self.worker.submit(GripperCommandRequest("move", status.position, 255, 0))
                goal.finish(failed(gap, "canceled"))

    def _publish_status(self, status: GripperStatus | None, error: RobotiqError | None) -> None:
        msg = DiagnosticStatus(name="robotiq_2f", hardware_id=self.port or "no port")
        level, text = status_level(status, str(error or self.error))
        msg.level, msg.message = bytes([int(level)]), text
        if status is not None:
            # ``link``: "ok" when these values were read just now, "error" when they are the
            # last ones read before a link error (so a reader knows whether they are current)
            fresh = error is None and not self.error
            msg.values = [KeyValue(key=k, value=v) for k, v in status_to_values(status)]
            msg.values.append(KeyValue(key="link", value="ok" if fresh else "error"))
            joints = JointState(
                name=[self.p.joint_name], position=[self.scale.gap_m(status.position)]
            )
            joints.header.stamp = self.get_clock().now().to_msg()
            self.joint_pub.publish(joints)
        self.status_pub.publish(msg)

    def _check_link(self) -> tuple[Level, str, dict[str, object]]:
        with self._lock:
            status, error = self.status, self.error
        values: dict[str, object] = {}
        if self.worker is not None:
            c = self.worker.counters
            values = {
                "polls": c.polls,
                "errors": c.errors,
                "commands_sent": c.commands_sent,
                "commands_dropped": c.commands_dropped,
                "connects": c.reconnects,
            }
            if self.worker.client is not None:
                cc = self.worker.client.counters
                values |= {
                    "retries": cc.retries,
                    "timeouts": cc.timeouts,
                    "crc_errors": cc.crc_errors,
                }
        return (*status_level(status, error), values)

    def destroy_node(self) -> None:
        """Stop the worker, close the port, destroy the action servers (rclpy's leaves them)."""
        self.on_cleanup(None)
        self.gripper_server.destroy()
        self.parallel_server.destroy()
        super().destroy_node()


def main(args: list[str] | None = None) -> int:
    """Run the node."""
    return run_node(RobotiqGripperNode, args)
