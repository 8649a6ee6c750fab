"""``tap_marker`` node: tap estimates drawn on the rod as ``visualization_msgs/Marker``.

Subscribes ``contact_estimate`` and ``contact_estimate/provisional`` (``ContactEstimate``: the
final estimates and the provisional ones); publishes on ``marker`` the rod (id 0,
CYLINDER, also once a second), the tap (id 1, SPHERE, 2-sigma diameter, yellow when provisional,
green when final, red when clamped onto the rod) and its label (id 2, TEXT_VIEW_FACING), all in
``frame_id`` with the rod along ``rod_axis`` from the held end at the origin.
"""

from __future__ import annotations

from typing import Any

from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node
from visualization_msgs.msg import Marker

from ext_sense_behaviours.errors import BehaviourError
from ext_sense_behaviours.nodes.conversions import marker_from_spec
from ext_sense_behaviours.tap import TAP_TASK, rod_marker, tap_marker
from ext_sense_msgs.msg import ContactEstimate
from ext_sense_runtime.callback_guard import CallbackGuard
from ext_sense_runtime.diagnostics import Level, Updater
from ext_sense_runtime.diagnostics_ros import DiagnosticsPublisher
from ext_sense_runtime.node_main import run_node
from ext_sense_runtime.parameters import declare, refused
from ext_sense_runtime.qos import COMMAND_QOS, ESTIMATE_QOS
from ext_sense_runtime.records import estimate_of

NS = "tap"


class TapMarkerNode(Node):
    """Publishes each tap estimate as a marker on the rod."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(kwargs.pop("node_name", "tap_marker"), **kwargs)
        self.guard = CallbackGuard(self.get_logger().error)
        self.rod_length_m = declare(
            self,
            "rod_length_m",
            0.3,
            "Rod length, metres (held end at the frame origin).",
            low=0.01,
            high=5.0,
        )
        self.rod_axis = declare(self, "rod_axis", "x", "Axis of frame_id along the rod: x, y or z.")
        self.frame_id = declare(self, "frame_id", "rod", "Frame of the markers (the rod's frame).")
        self.min_diameter_m = declare(
            self,
            "min_diameter_m",
            0.01,
            "Smallest tap sphere diameter, metres.",
            low=0.001,
            high=0.2,
        )
        self.lifetime_s = declare(
            self,
            "lifetime_s",
            0.0,
            "Tap marker lifetime, seconds (0: until replaced).",
            low=0.0,
            high=3600.0,
        )
        self.add_on_set_parameters_callback(self.guard.wrap(self._on_set, fallback=refused))
        self.published = 0
        self.dropped = 0
        self.last_text = ""
        self.pub = self.create_publisher(Marker, "marker", COMMAND_QOS)
        for topic in ("contact_estimate", "contact_estimate/provisional"):
            self.create_subscription(
                ContactEstimate, topic, self.guard(self._on_estimate), ESTIMATE_QOS
            )
        self.create_timer(1.0, self.guard(self._publish_rod))
        self.updater = Updater(hardware_id=self.frame_id)
        self.updater.add_check("markers", self._check)
        self.guard.attach(self.updater)
        self.diagnostics = DiagnosticsPublisher(self, self.updater)

    def _on_set(self, params: list) -> SetParametersResult:
        for p in params:
            if p.name == "rod_axis" and p.value not in ("x", "y", "z"):
                return SetParametersResult(
                    successful=False, reason=f"rod_axis must be x, y or z. Got {p.value!r} instead."
                )
        for p in params:
            if p.name in ("rod_length_m", "rod_axis", "frame_id", "min_diameter_m", "lifetime_s"):
                setattr(self, p.name, p.value)
        return SetParametersResult(successful=True)

    def _publish_rod(self) -> None:
        spec = rod_marker(self.rod_length_m, self.rod_axis)
        stamp = self.get_clock().now().to_msg()
        self.pub.publish(marker_from_spec(spec, self.frame_id, stamp, NS, 0, Marker.CYLINDER))

    def _on_estimate(self, msg: ContactEstimate) -> None:
        estimate = estimate_of(msg)
        if estimate.task != TAP_TASK:
            return
        try:
            spec = tap_marker(estimate, self.rod_length_m, self.rod_axis, self.min_diameter_m)
        except BehaviourError as err:
            self.dropped += 1
            self.get_logger().warning(f"estimate dropped: {err}")
            return
        self._publish_rod()
        self.pub.publish(
            marker_from_spec(
                spec, self.frame_id, msg.header.stamp, NS, 1, Marker.SPHERE, self.lifetime_s
            )
        )
        label = spec._replace(
            position=(spec.position[0], spec.position[1], spec.position[2] + 0.03),
            scale=(0.0, 0.0, 0.02),
            rgba=(1.0, 1.0, 1.0, 1.0),
        )
        self.pub.publish(
            marker_from_spec(
                label,
                self.frame_id,
                msg.header.stamp,
                NS,
                2,
                Marker.TEXT_VIEW_FACING,
                self.lifetime_s,
            )
        )
        self.published += 1
        self.last_text = spec.text

    def _check(self) -> tuple[Level, str, dict[str, object]]:
        level = Level.WARN if self.dropped else Level.OK
        return (
            level,
            self.last_text or "no tap yet",
            {
                "taps_published": self.published,
                "estimates_dropped": self.dropped,
                "rod_length_m": self.rod_length_m,
            },
        )


def main(args: list[str] | None = None) -> int:
    """Run the node."""
    return run_node(TapMarkerNode, args)
