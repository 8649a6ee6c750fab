"""``food_behaviour`` node: lower the fork, stop on contact, classify, retract, publish.

Runs :class:`~ext_sense_behaviours.food.FoodMachine` on an arm adapter (``arm`` = ``sim``: the
simulated arm inside the node; ``franka``: a franka_ros2 robot, or the ``sim_arm`` node that
stands in for one, through :class:`~ext_sense_behaviours.nodes.franka_adapter.FrankaArmAdapter`:
robot state, collision thresholds, ``FollowJointTrajectory`` goals) from a timer at
``control_rate_hz``. Publishes ``motion_start`` (``ContactGroundTruth``, task
``food_identification``, stamp = motion start) so the ``contact_window`` node cuts the food
window, takes the final food ``ContactEstimate`` for that motion start from ``contact_estimate``
(or, with ``accept_provisional``, a provisional one from ``contact_estimate/provisional``),
and republishes it on ``food/result`` once retracted; every decision goes to
``food/decision`` (``std_msgs/String``) and the log; every arm state sample read while
probing goes to ``arm/state`` (``sensor_msgs/JointState``, joint ``ee_z``: position = height z
in m, velocity = vertical velocity in m/s, effort = external force norm in N). A probe starts on
``food/start`` (``std_msgs/Bool`` true) or at start-up with ``auto_start`` (once
``motion_start`` has ``start_subscribers`` subscribers), and again ``repeat_s`` after each one
ends.
"""

from __future__ import annotations

import math
from typing import Any

from rclpy.node import Node
from sensor_msgs.msg import JointState
from std_msgs.msg import Bool, String

from ext_sense_behaviours.arm import SimulatedArm
from ext_sense_behaviours.decisions import Decision
from ext_sense_behaviours.execution import FoodProbe
from ext_sense_behaviours.food import FOOD_TASK, FoodConfig, FoodMachine, FoodResult, FoodState
from ext_sense_behaviours.franka import FrankaNames
from ext_sense_behaviours.records import ArmState
from ext_sense_msgs.msg import ContactEstimate, ContactGroundTruth
from ext_sense_runtime.callback_guard import CallbackGuard
from ext_sense_runtime.diagnostics import Level, Updater
from ext_sense_runtime.diagnostics_ros import DiagnosticsPublisher
from ext_sense_runtime.node_main import run_node
from ext_sense_runtime.parameters import declare
from ext_sense_runtime.qos import COMMAND_QOS, ESTIMATE_QOS
from ext_sense_runtime.records import estimate_of
from ext_sense_runtime.stamps import S, fill_stamp, stamp_to_ns


class FoodBehaviourNode(Node):
    """Probes food with a fork held by the arm."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(kwargs.pop("node_name", "food_behaviour"), **kwargs)
        self.guard = CallbackGuard(self.get_logger().error)
        arm_kind = declare(self, "arm", "sim", "Arm adapter: sim or franka.", read_only=True)

        def d(name: str, default: Any, text: str, low: Any = None, high: Any = None) -> Any:
            return declare(self, name, default, text, low=low, high=high, read_only=True)

        config = FoodConfig(
            speed_mps=d("speed_mps", 0.01, "Lowering speed, m/s.", 0.001, 0.1),
            contact_threshold_n=d(
                "contact_threshold_n", 10.0, "Contact force norm, N.", 0.5, 100.0
            ),
            contact_consecutive=d("contact_consecutive", 1, "Samples over the threshold.", 1, 10),
            stop_height_m=d(
                "stop_height_m", 0.103, "Preset stop height, m (base frame).", -2.0, 2.0
            ),
            window_end_ns=round(
                d("window_end_s", 8.0, "Window end after motion start, s.", 0.1, 60.0) * S
            ),
            classify_timeout_ns=round(
                d("classify_timeout_s", 5.0, "Wait for the class after the window, s.", 0.1, 60.0)
                * S
            ),
            max_lowering_ns=round(
                d("max_lowering_s", 15.0, "Lowering time limit, s.", 0.5, 120.0) * S
            ),
            max_retract_ns=round(
                d(
                    "max_retract_s",
                    10.0,
                    "How much longer than planned (distance / retract_speed_mps) the retract "
                    "may take before the probe stops and holds, s.",
                    0.5,
                    120.0,
                )
                * S
            ),
            state_timeout_ns=round(
                d(
                    "state_timeout_s",
                    0.5,
                    "Longest gap between arm states while moving before the probe stops and "
                    "holds, s.",
                    0.01,
                    10.0,
                )
                * S
            ),
            retract_speed_mps=d("retract_speed_mps", 0.05, "Retract speed, m/s.", 0.001, 0.25),
            accept_provisional=d("accept_provisional", False, "Accept a provisional class."),
        )
        rate_hz = d("control_rate_hz", 100.0, "Control loop rate, Hz.", 1.0, 1000.0)
        self.auto_start = d("auto_start", False, "Start one probe at start-up.")
        self.start_subscribers = d(
            "start_subscribers",
            0,
            "auto_start waits until motion_start has this many subscribers (the window node, "
            "a simulated sensor), so none misses the motion start.",
            0,
            100,
        )
        self.repeat_ns = round(
            d(
                "repeat_s",
                0.0,
                "Start the next probe this long after one ends, s (0: no).",
                0.0,
                3600.0,
            )
            * S
        )
        self._done_ns: int | None = None
        if arm_kind == "sim":
            surface = d(
                "sim_surface_z_m", 0.12, "Simulated food surface height, m (< 0: none).", -1.0, 2.0
            )
            arm = SimulatedArm(
                start_z_m=d("sim_start_z_m", 0.16, "Simulated start height, m.", 0.0, 2.0),
                surface_z_m=surface if surface >= 0 else None,
                stiffness_n_per_m=d(
                    "sim_stiffness_n_per_m", 1000.0, "Simulated food stiffness, N/m.", 1.0, 1e6
                ),
                clock_ns=lambda: self.get_clock().now().nanoseconds,
            )
        elif arm_kind == "franka":
            from ext_sense_behaviours.nodes.franka_adapter import (
                ACCEPT_TIMEOUT_S,
                FrankaArmAdapter,
            )

            defaults = FrankaNames()
            names = FrankaNames(
                state_topic=d(
                    "franka.state_topic", defaults.state_topic, "FrankaRobotState topic."
                ),
                trajectory_action=d(
                    "franka.trajectory_action",
                    defaults.trajectory_action,
                    "FollowJointTrajectory action of the arm's joint_trajectory_controller.",
                ),
                collision_service=d(
                    "franka.collision_service",
                    defaults.collision_service,
                    "SetFullCollisionBehavior service.",
                ),
                error_recovery_action=d(
                    "franka.error_recovery_action",
                    defaults.error_recovery_action,
                    "ErrorRecovery action.",
                ),
            )
            arm = FrankaArmAdapter(
                self,
                names,
                collision_force_n=d(
                    "franka.collision_force_n",
                    20.0,
                    "Robot reflex force threshold, N (its contact flag, half of it, also stops "
                    "the descent).",
                    1.0,
                    100.0,
                ),
                accept_timeout_s=d(
                    "franka.accept_timeout_s",
                    ACCEPT_TIMEOUT_S,
                    "Longest wait for the controller to accept a trajectory goal, s.",
                    0.1,
                    60.0,
                ),
                max_descent_m=d(
                    "franka.max_descent_m",
                    0.15,
                    "Length of the planned descent, m (the probe stops it earlier).",
                    0.005,
                    0.5,
                ),
                guard=self.guard,
            )
        else:
            raise ValueError(
                f"The 'arm' parameter must be 'sim' or 'franka'. Got {arm_kind!r} instead."
            )
        self.arm = arm
        self.machine = FoodMachine(config, sink=self._on_decision)
        self.probe = FoodProbe(
            self.machine,
            arm,
            self._on_motion_start,
            None,
            self._on_publish,
            on_state=self._publish_arm,
        )
        self.motion_pub = self.create_publisher(ContactGroundTruth, "motion_start", COMMAND_QOS)
        self.result_pub = self.create_publisher(ContactEstimate, "food/result", ESTIMATE_QOS)
        self.decision_pub = self.create_publisher(String, "food/decision", COMMAND_QOS)
        self.arm_pub = self.create_publisher(JointState, "arm/state", COMMAND_QOS)
        for topic in ("contact_estimate", "contact_estimate/provisional"):
            self.create_subscription(
                ContactEstimate, topic, self.guard(self._on_estimate), ESTIMATE_QOS
            )
        self.create_subscription(Bool, "food/start", self.guard(self._on_start), COMMAND_QOS)
        self._estimate_msgs: dict[int, ContactEstimate] = {}
        self.results = 0
        self.create_timer(1.0 / rate_hz, self.guard(self._on_timer))
        self.updater = Updater(hardware_id=f"arm:{arm_kind}")
        self.updater.add_check("food", self._check)
        self.guard.attach(self.updater)
        self.diagnostics = DiagnosticsPublisher(self, self.updater)

    def _publish_arm(self, state: ArmState) -> None:
        msg = JointState(
            name=["ee_z"],
            position=[state.z_m],
            velocity=[state.velocity_z_mps],
            effort=[state.force_norm_n],
        )
        fill_stamp(msg.header.stamp, state.stamp_ns)
        msg.header.frame_id = "base"
        self.arm_pub.publish(msg)

    def _on_decision(self, decision: Decision) -> None:
        if decision.state == "DONE":
            self._done_ns = decision.stamp_ns
        self.get_logger().info(f"{decision.state}: {decision.action} - {decision.reason}")
        self.decision_pub.publish(String(data=str(decision)))

    def _on_motion_start(self, stamp_ns: int) -> None:
        msg = ContactGroundTruth(task=FOOD_TASK, tap_position_m=math.nan, rod_length_m=math.nan)
        fill_stamp(msg.header.stamp, stamp_ns)
        self.motion_pub.publish(msg)

    def _on_publish(self, result: FoodResult) -> None:
        if result.estimate is None:
            return
        msg = self._estimate_msgs.get(result.estimate.onset_ns)
        if msg is not None:
            self.result_pub.publish(msg)
            self.results += 1

    def _on_start(self, msg: Bool) -> None:
        if msg.data and self.probe.start(self.get_clock().now().nanoseconds) is None:
            self.get_logger().error("food/start ignored: no arm state yet")

    def _on_estimate(self, msg: ContactEstimate) -> None:
        if msg.task != FOOD_TASK:
            return
        self._estimate_msgs = {stamp_to_ns(msg.header.stamp): msg}
        self.probe.deliver(estimate_of(msg), self.get_clock().now().nanoseconds)

    def _on_timer(self) -> None:
        now = self.get_clock().now().nanoseconds
        if self.auto_start and self.machine.state == FoodState.IDLE:
            if self.motion_pub.get_subscription_count() < self.start_subscribers:
                return
            if self.probe.start(now) is not None:
                self.auto_start = False
            return
        if (
            self.machine.state == FoodState.DONE
            and self.repeat_ns > 0
            and self._done_ns is not None
            and now - self._done_ns >= self.repeat_ns
        ):
            self._done_ns = None
            self.probe.start(now)
            return
        if self.machine.state not in (FoodState.IDLE, FoodState.DONE, FoodState.FAULT):
            self.probe.step(now)

    def _check(self) -> tuple[Level, str, dict[str, object]]:
        state = self.machine.state
        level = Level.ERROR if state == FoodState.FAULT else Level.OK
        last = self.machine.log.entries[-1].reason if self.machine.log.entries else "idle"
        return (
            level,
            f"{state.name}: {last}",
            {
                "results_published": self.results,
                "force_n": f"{self.machine.detector.last_norm_n:.2f}",
                "invalid_force_samples": self.machine.detector.invalid_samples,
                **(self.arm.status() if hasattr(self.arm, "status") else {}),
            },
        )

    def destroy_node(self) -> None:
        """Destroy the Franka adapter's action clients too (``destroy_node`` leaves them alive)."""
        destroy = getattr(self.arm, "destroy", None)  # FrankaArmAdapter's; a SimulatedArm has none
        if destroy is not None:
            destroy()
        super().destroy_node()


def main(args: list[str] | None = None) -> int:
    """Run the node."""
    return run_node(FoodBehaviourNode, args)
