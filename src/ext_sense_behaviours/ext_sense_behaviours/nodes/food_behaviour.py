"""``food_behaviour`` node: lower the fork, stop on contact, classify, retract, publish.

Runs :class:`~ext_sense_behaviours.food.FoodMachine` on the ``arm`` (sim, or franka) at
``control_rate_hz``. Publishes ``motion_start`` (``ContactGroundTruth``) for the
``contact_window`` node and republishes the food estimate for it on ``food/result`` once
retracted; decisions on ``food/decision``, arm states on ``arm/state`` (JointState ``ee_z``: z,
vertical velocity, force norm). A probe starts on ``food/start`` or with ``auto_start``.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Any

from rclpy.node import Node
from sensor_msgs.msg import JointState
from std_msgs.msg import Bool, String

from ext_sense_behaviours.arm import SimulatedArm
from ext_sense_behaviours.decisions import Decision
from ext_sense_behaviours.execution import FoodProbe
from ext_sense_behaviours.food import FOOD_TASK, FoodConfig, FoodMachine, FoodResult, FoodState
from ext_sense_behaviours.franka import FrankaNames
from ext_sense_behaviours.nodes.franka_adapter import ACCEPT_TIMEOUT_S, FrankaArmAdapter
from ext_sense_behaviours.records import ArmState
from ext_sense_msgs.msg import ContactEstimate, ContactGroundTruth
from ext_sense_runtime.callback_guard import CallbackGuard
from ext_sense_runtime.diagnostics import Level, Updater
from ext_sense_runtime.diagnostics_ros import DiagnosticsPublisher
from ext_sense_runtime.node_main import run_node
from ext_sense_runtime.parameters import declare_all, param
from ext_sense_runtime.qos import COMMAND_QOS, DECISION_QOS, ESTIMATE_QOS
from ext_sense_runtime.records import estimate_of
from ext_sense_runtime.stamps import S, fill_stamp, stamp_to_ns

ARMS = ("sim", "franka")
_ro = functools.partial(param, read_only=True)


@dataclass(frozen=True)
class FoodParameters:
    """``food_behaviour``'s parameters, all read-only.

    ``sim_*`` apply to the simulated arm (``arm`` sim), ``franka.*`` to a franka_ros2 robot.
    """

    arm: str = param("sim", "Arm adapter: sim or franka.", read_only=True, choices=ARMS)
    speed_mps: float = _ro(0.01, "Lowering speed, m/s.", low=0.001, high=0.1)
    contact_threshold_n: float = _ro(10.0, "Contact force norm, N.", low=0.5, high=100.0)
    contact_consecutive: int = _ro(1, "Samples over the threshold.", low=1, high=10)
    stop_height_m: float = _ro(0.103, "Preset stop height, m (base frame).", low=-2.0, high=2.0)
    window_end_s: float = _ro(8.0, "Window end after motion start, s.", low=0.1, high=60.0)
    classify_timeout_s: float = _ro(
        5.0, "Wait for the class after the window, s.", low=0.1, high=60.0
    )
    max_lowering_s: float = _ro(15.0, "Lowering time limit, s.", low=0.5, high=120.0)
    max_retract_s: float = _ro(
        10.0,
        "How much longer than planned (distance / retract_speed_mps) the retract may take "
        "before the probe stops and holds, s.",
        low=0.5,
        high=120.0,
    )
    state_timeout_s: float = _ro(
        0.5,
        "Longest gap between arm states while moving before the probe stops and holds, s.",
        low=0.01,
        high=10.0,
    )
    retract_speed_mps: float = _ro(0.05, "Retract speed, m/s.", low=0.001, high=0.25)
    accept_provisional: bool = _ro(False, "Accept a provisional class.")
    control_rate_hz: float = _ro(100.0, "Control loop rate, Hz.", low=1.0, high=1000.0)
    auto_start: bool = _ro(False, "Start one probe at start-up.")
    start_subscribers: int = _ro(
        0,
        "auto_start waits until motion_start has this many subscribers (the window node, a "
        "simulated sensor), so none misses the motion start.",
        low=0,
        high=100,
    )
    start_delay_s: float = _ro(
        0.0,
        "auto_start no sooner than this after start-up, s (lets listeners started with the "
        "graph, such as a recorder, match the simulated sensor's truth before the first probe).",
        low=0.0,
        high=600.0,
    )
    repeat_s: float = _ro(
        0.0, "Start the next probe this long after one ends, s (0: no).", low=0.0, high=3600.0
    )
    sim_surface_z_m: float = _ro(
        0.12, "arm sim: food surface height, m (< 0: none).", low=-1.0, high=2.0
    )
    sim_start_z_m: float = _ro(0.16, "arm sim: start height, m.", low=0.0, high=2.0)
    sim_stiffness_n_per_m: float = _ro(1000.0, "arm sim: food stiffness, N/m.", low=1.0, high=1e6)
    franka_state_topic: str = _ro(
        FrankaNames.state_topic, "FrankaRobotState topic.", name="franka.state_topic"
    )
    franka_trajectory_action: str = _ro(
        FrankaNames.trajectory_action,
        "FollowJointTrajectory action of the arm's joint_trajectory_controller.",
        name="franka.trajectory_action",
    )
    franka_collision_service: str = _ro(
        FrankaNames.collision_service,
        "SetFullCollisionBehavior service.",
        name="franka.collision_service",
    )
    franka_error_recovery_action: str = _ro(
        FrankaNames.error_recovery_action,
        "ErrorRecovery action.",
        name="franka.error_recovery_action",
    )
    franka_collision_force_n: float = _ro(
        20.0,
        "Robot reflex force threshold, N (its contact flag, half of it, also stops the descent).",
        low=1.0,
        high=100.0,
        name="franka.collision_force_n",
    )
    franka_accept_timeout_s: float = _ro(
        ACCEPT_TIMEOUT_S,
        "Longest wait for the controller to accept a trajectory goal, s.",
        low=0.1,
        high=60.0,
        name="franka.accept_timeout_s",
    )
    franka_max_descent_m: float = _ro(
        0.15,
        "Length of the planned descent, m (the probe stops it earlier).",
        low=0.005,
        high=0.5,
        name="franka.max_descent_m",
    )

    def food_config(self) -> FoodConfig:
        """The probing's config (durations in ns)."""
        return FoodConfig(
            speed_mps=self.speed_mps,
            contact_threshold_n=self.contact_threshold_n,
            contact_consecutive=self.contact_consecutive,
            stop_height_m=self.stop_height_m,
            window_end_ns=round(self.window_end_s * S),
            classify_timeout_ns=round(self.classify_timeout_s * S),
            max_lowering_ns=round(self.max_lowering_s * S),
            max_retract_ns=round(self.max_retract_s * S),
            state_timeout_ns=round(self.state_timeout_s * S),
            retract_speed_mps=self.retract_speed_mps,
            accept_provisional=self.accept_provisional,
        )

    def franka_names(self) -> FrankaNames:
        """Where the franka_ros2 interfaces live."""
        return FrankaNames(
            self.franka_state_topic,
            self.franka_trajectory_action,
            self.franka_collision_service,
            self.franka_error_recovery_action,
        )


class FoodBehaviourNode(Node):
    """Probes food with a fork held by the arm."""

    PARAMETERS = FoodParameters

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(kwargs.pop("node_name", "food_behaviour"), **kwargs)
        self.guard = CallbackGuard(self.get_logger().error)
        p = declare_all(self, FoodParameters)
        self.auto_start = p.auto_start
        self.start_subscribers = p.start_subscribers
        self.start_delay_ns = round(p.start_delay_s * S)
        self.repeat_ns = round(p.repeat_s * S)
        self._done_ns: int | None = None
        arm: Any
        if p.arm == "sim":
            arm = SimulatedArm(
                start_z_m=p.sim_start_z_m,
                surface_z_m=p.sim_surface_z_m if p.sim_surface_z_m >= 0 else None,
                stiffness_n_per_m=p.sim_stiffness_n_per_m,
                clock_ns=lambda: self.get_clock().now().nanoseconds,
            )
        else:
            arm = FrankaArmAdapter(
                self,
                p.franka_names(),
                collision_force_n=p.franka_collision_force_n,
                accept_timeout_s=p.franka_accept_timeout_s,
                max_descent_m=p.franka_max_descent_m,
                guard=self.guard,
            )
        self.arm = arm
        self.machine = FoodMachine(p.food_config(), sink=self._on_decision)
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
        self.decision_pub = self.create_publisher(String, "food/decision", DECISION_QOS)
        self.arm_pub = self.create_publisher(JointState, "arm/state", COMMAND_QOS)
        for topic in ("contact_estimate", "contact_estimate/provisional"):
            self.create_subscription(
                ContactEstimate, topic, self.guard(self._on_estimate), ESTIMATE_QOS
            )
        self.create_subscription(Bool, "food/start", self.guard(self._on_start), COMMAND_QOS)
        self._estimate_msgs: dict[int, ContactEstimate] = {}
        self.results = 0
        self._started_ns = self.get_clock().now().nanoseconds
        self.create_timer(1.0 / p.control_rate_hz, self.guard(self._on_timer))
        self.updater = Updater(hardware_id=f"arm:{p.arm}")
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
            if (
                self.motion_pub.get_subscription_count() < self.start_subscribers
                or now - self._started_ns < self.start_delay_ns
            ):
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
