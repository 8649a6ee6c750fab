"""``handover_behaviour`` node: open the gripper once the person's grasp is stable.

Feeds ``contact_estimate`` to :class:`~ext_sense_behaviours.handover.HandoverMachine` and
commands the gripper through ``GripperCommand`` on ``gripper_action`` (ours or a
``GripperActionController``). It first grasps the object (``grasp_on_start``); the handover
starts when the grasp stalls on it (``auto_start``) or on ``handover/start``. Publishes
``handover/decision`` and ``handover/offer``. A gripper error keeps the object held; the next
``gripper/status`` read logs where the fingers are.
"""

from __future__ import annotations

import contextlib
import math
from dataclasses import dataclass
from typing import Any

from diagnostic_msgs.msg import DiagnosticStatus
from rclpy.node import Node
from std_msgs.msg import Bool, String

from ext_sense_behaviours.decisions import Decision
from ext_sense_behaviours.errors import BehaviourError
from ext_sense_behaviours.gripper import describe_position, is_open, settled, status_from_values
from ext_sense_behaviours.handover import (
    HANDOVER_TASK,
    HandoverAction,
    HandoverConfig,
    HandoverMachine,
    HandoverState,
)
from ext_sense_behaviours.nodes.gripper_client import GripperClient, GripperReply
from ext_sense_msgs.msg import ContactEstimate, ContactGroundTruth
from ext_sense_runtime.callback_guard import CallbackGuard
from ext_sense_runtime.diagnostics import Level, Updater
from ext_sense_runtime.diagnostics_ros import DiagnosticsPublisher
from ext_sense_runtime.node_main import run_node
from ext_sense_runtime.parameters import declare_all, param
from ext_sense_runtime.qos import COMMAND_QOS, DECISION_QOS, ESTIMATE_QOS
from ext_sense_runtime.records import estimate_of
from ext_sense_runtime.stamps import S, fill_stamp


@dataclass(frozen=True)
class HandoverParameters:
    """``handover_behaviour``'s parameters; all but the action and tick rate change live."""

    threshold: float = param(0.8, "P(stable) an estimate must reach, 0..1.", low=0.01, high=1.0)
    consecutive: int = param(3, "Stable estimates in a row before opening.", low=1, high=50)
    accept_provisional: bool = param(False, "Let provisional (anytime) estimates count.")
    timeout_s: float = param(30.0, "Safety timeout while holding, seconds.", low=0.1, high=3600.0)
    release_timeout_s: float = param(
        3.0, "Longest wait for the gripper to report open, seconds.", low=0.1, high=60.0
    )
    open_position_m: float = param(
        0.085, "Finger gap of the open goal, m (the 2F-85's stroke).", low=0.0, high=0.5
    )
    open_effort_n: float = param(70.0, "max_effort of the open goal, N.", low=0.0, high=1000.0)
    grasp_on_start: bool = param(
        True,
        "Close the ready gripper on the object first (then the handover starts on contact).",
    )
    grasp_effort_n: float = param(70.0, "max_effort of the grasp goal, N.", low=0.0, high=1000.0)
    gripper_action: str = param(
        "/robotiq_gripper_controller/gripper_cmd",
        "GripperCommand action of the gripper (our robotiq_gripper or a ros2_control "
        "GripperActionController).",
        read_only=True,
    )
    regrasp_s: float = param(
        0.0,
        "After a release or a timeout, wait this long, grasp again and start the next "
        "handover, seconds (0: one handover only).",
        low=0.0,
        high=3600.0,
    )
    auto_start: bool = param(True, "Start when the gripper reports it holds an object.")
    start_subscribers: int = param(
        0,
        "auto_start waits until handover/offer has this many subscribers (a simulated "
        "person), so none misses the offer.",
        low=0,
        high=100,
    )
    start_delay_s: float = param(
        0.0,
        "auto_start no sooner than this after start-up, seconds (lets the perception "
        "nodes load their model before the first offer).",
        low=0.0,
        high=600.0,
    )
    tick_rate_hz: float = param(
        20.0, "Timeout check rate, Hz.", low=1.0, high=200.0, read_only=True
    )

    def handover_config(self) -> HandoverConfig:
        """The decision's config (durations in ns)."""
        return HandoverConfig(
            self.threshold,
            self.consecutive,
            self.accept_provisional,
            round(self.timeout_s * S),
            round(self.release_timeout_s * S),
        )


class HandoverBehaviourNode(Node):
    """Runs the handover state machine on estimates and gripper status."""

    PARAMETERS = HandoverParameters

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(kwargs.pop("node_name", "handover_behaviour"), **kwargs)
        self.guard = CallbackGuard(self.get_logger().error)
        self.p = declare_all(self, HandoverParameters, self._on_change, self.guard)
        self.gripper = GripperClient(self, self.p.gripper_action)
        self._object_held = False
        self._grasp_retry_ns = 0
        self._grasp_pending = False
        self._ended_ns: int | None = None
        self._started_ns = self._now()
        self.machine = HandoverMachine(self.p.handover_config(), sink=self._on_decision)
        self.gripper_level = Level.STALE
        self.gripper_message = "no gripper status yet"
        self.estimates = 0
        self.decision_pub = self.create_publisher(String, "handover/decision", DECISION_QOS)
        self.offer_pub = self.create_publisher(ContactGroundTruth, "handover/offer", COMMAND_QOS)
        for topic in ("contact_estimate", "contact_estimate/provisional"):
            self.create_subscription(
                ContactEstimate, topic, self.guard(self._on_estimate), ESTIMATE_QOS
            )
        self.create_subscription(
            DiagnosticStatus, "gripper/status", self.guard(self._on_gripper), COMMAND_QOS
        )
        self.create_subscription(Bool, "handover/start", self.guard(self._on_start), COMMAND_QOS)
        self.create_timer(1.0 / self.p.tick_rate_hz, self.guard(self._on_tick))
        self.updater = Updater(hardware_id="handover")
        self.updater.add_check("handover", self._check)
        self.guard.attach(self.updater)
        self.diagnostics = DiagnosticsPublisher(self, self.updater)

    def _now(self) -> int:
        return self.get_clock().now().nanoseconds

    def _on_change(self, new: HandoverParameters) -> str | None:
        config = new.handover_config()
        if config != self.machine.config:
            if self.machine.state == HandoverState.RELEASING:
                return "cannot change while releasing"
            self.machine.config = config
        self.p = new
        return None

    def _on_decision(self, decision: Decision) -> None:
        if decision.state == "HOLDING" and decision.action == "HOLD":  # a handover starts
            offer = ContactGroundTruth(
                task=HANDOVER_TASK, tap_position_m=math.nan, rod_length_m=math.nan
            )
            fill_stamp(offer.header.stamp, decision.stamp_ns)
            self.offer_pub.publish(offer)
        if decision.state in ("RELEASED", "TIMED_OUT"):
            self._ended_ns = decision.stamp_ns
        elif decision.state == "HOLDING":
            self._grasp_pending, self._ended_ns = False, None
        self.get_logger().info(f"{decision.state}: {decision.action} - {decision.reason}")
        self.decision_pub.publish(String(data=str(decision)))

    def _act(self, decision: Decision | None) -> None:
        if decision is not None and HandoverAction[decision.action] == HandoverAction.OPEN_GRIPPER:
            self.gripper.send(
                self.p.open_position_m, self.p.open_effort_n, self.guard(self._on_open_done)
            )

    def _on_open_done(self, reply: GripperReply) -> None:
        """The open goal ended: released, or a fault (keep holding) unless one is known."""
        now = self._now()
        self._object_held = False
        if self.machine.state != HandoverState.RELEASING:
            return  # a fault from gripper/status came first
        if reply.succeeded:
            self.machine.on_gripper(True, now)
            return
        cause = self.gripper_message if self.gripper_level == Level.ERROR else ""
        why = f"open goal {reply.reason}" + (f": {cause}" if cause else "")
        self._act(self.machine.on_fault(why, now))

    def _on_grasp_done(self, reply: GripperReply) -> None:
        """The grasp goal ended: an object is held when the fingers stalled on it."""
        self._grasp_pending = False
        if reply.succeeded and reply.stalled:
            self._object_held = True
            return
        if reply.succeeded:
            self.get_logger().warning(
                "gripper closed on nothing (reached the goal gap): no object to hand over",
                throttle_duration_sec=10.0,
            )
        else:
            self.get_logger().warning(
                f"grasp goal {reply.reason}; trying again in 1 s", throttle_duration_sec=10.0
            )
        self._grasp_retry_ns = self._now() + S

    def _prepare_next(self, now: int) -> None:
        """Grasp the object, then start the handover once it is held (from the tick)."""
        state = self.machine.state
        if state != HandoverState.IDLE and not (
            state in (HandoverState.RELEASED, HandoverState.TIMED_OUT)
            and self.p.regrasp_s > 0
            and self._ended_ns is not None
            and now - self._ended_ns >= round(self.p.regrasp_s * S)
        ):
            return
        if self._object_held:
            if (
                self.p.auto_start
                and self.offer_pub.get_subscription_count() >= self.p.start_subscribers
                and now - self._started_ns >= round(self.p.start_delay_s * S)
            ):
                self._act(self.machine.start(now))
        elif (
            self.p.grasp_on_start
            and not self._grasp_pending
            and now >= self._grasp_retry_ns
            and self.gripper.ready()
        ):
            self._grasp_pending = True
            self.get_logger().info("grasping the object before the handover")
            self.gripper.send(0.0, self.p.grasp_effort_n, self.guard(self._on_grasp_done))

    def _on_start(self, msg: Bool) -> None:
        if not msg.data:
            return
        if self.machine.state == HandoverState.FAULT:
            self.machine.reset(self._now(), "handover/start after a fault: operator reset")
        self._act(self.machine.start(self._now()))

    def _on_estimate(self, msg: ContactEstimate) -> None:
        self.estimates += 1
        self._act(self.machine.on_estimate(estimate_of(msg), self._now()))

    def _on_gripper(self, msg: DiagnosticStatus) -> None:
        level = Level(msg.level[0] if isinstance(msg.level, bytes) else int(msg.level))
        self.gripper_level, self.gripper_message = level, msg.message
        now = self._now()
        state = self.machine.state
        values = {kv.key: kv.value for kv in msg.values}
        if state == HandoverState.FAULT and self.machine.awaiting_status:
            # after a fault: the first status read from a working link says where the
            # fingers really are (an open command may have run despite the error)
            if values.get("link") == "ok":
                with contextlib.suppress(BehaviourError):
                    status = status_from_values(values)
                    self.machine.on_status_after_fault(
                        is_open(status), settled(status), describe_position(status), now
                    )
            return
        if level == Level.ERROR and state in (HandoverState.HOLDING, HandoverState.RELEASING):
            self._act(self.machine.on_fault(msg.message, now))

    def _on_tick(self) -> None:
        now = self._now()
        self._act(self.machine.on_tick(now))
        self._prepare_next(now)

    def _check(self) -> tuple[Level, str, dict[str, object]]:
        state = self.machine.state
        level = Level.ERROR if state == HandoverState.FAULT else Level.OK
        last = self.machine.log.entries[-1].reason if self.machine.log.entries else "idle"
        return (
            level,
            f"{state.name}: {last}",
            {
                "estimates": self.estimates,
                "streak": self.machine.streak,
                "gripper": self.gripper_message,
            },
        )

    def destroy_node(self) -> None:
        """Destroy the gripper's action client too (``destroy_node`` leaves it alive)."""
        self.gripper.destroy()
        super().destroy_node()


def main(args: list[str] | None = None) -> int:
    """Run the node."""
    return run_node(HandoverBehaviourNode, args)
