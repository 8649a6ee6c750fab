"""``tap_marker`` node: tap estimates drawn on the rod as ``visualization_msgs/Marker``.

Subscribes ``contact_estimate`` and ``contact_estimate/provisional`` (``ContactEstimate``: the
final estimates and the provisional ones); publishes on ``marker`` the rod (id 0,
CYLINDER, also once a second), the tap (id 1, SPHERE, 2-sigma diameter, yellow when provisional,
green when final, red when clamped onto the rod) and its label (id 2, TEXT_VIEW_FACING), all in
``frame_id`` with the rod along ``rod_axis`` from the held end at the origin.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from builtin_interfaces.msg import Duration
from rclpy.node import Node
from visualization_msgs.msg import Marker

from ext_sense_behaviours.errors import BehaviourError
from ext_sense_behaviours.tap import TAP_TASK, MarkerSpec, rod_marker, tap_marker
from ext_sense_msgs.msg import ContactEstimate
from ext_sense_runtime.callback_guard import CallbackGuard
from ext_sense_runtime.diagnostics import Level, Updater
from ext_sense_runtime.diagnostics_ros import DiagnosticsPublisher
from ext_sense_runtime.node_main import run_node
from ext_sense_runtime.parameters import declare_all, param
from ext_sense_runtime.qos import COMMAND_QOS, ESTIMATE_QOS
from ext_sense_runtime.records import estimate_of

NS = "tap"


@dataclass(frozen=True)
class TapMarkerParameters:
    """``tap_marker``'s parameters; all change live."""

    rod_length_m: float = param(
        0.3, "Rod length, metres (held end at the frame origin).", low=0.01, high=5.0
    )
    rod_axis: str = param(
        "x", "Axis of frame_id along the rod: x, y or z.", choices=("x", "y", "z")
    )
    frame_id: str = param("rod", "Frame of the markers (the rod's frame).")
    min_diameter_m: float = param(
        0.01, "Smallest tap sphere diameter, metres.", low=0.001, high=0.2
    )
    lifetime_s: float = param(
        0.0, "Tap marker lifetime, seconds (0: until replaced).", low=0.0, high=3600.0
    )


class TapMarkerNode(Node):
    """Publishes each tap estimate as a marker on the rod."""

    PARAMETERS = TapMarkerParameters

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(kwargs.pop("node_name", "tap_marker"), **kwargs)
        self.guard = CallbackGuard(self.get_logger().error)
        self.p = declare_all(self, TapMarkerParameters, self._on_change, self.guard)
        self.published = 0
        self.dropped = 0
        self.last_text = ""
        self.pub = self.create_publisher(Marker, "marker", COMMAND_QOS)
        for topic in ("contact_estimate", "contact_estimate/provisional"):
            self.create_subscription(
                ContactEstimate, topic, self.guard(self._on_estimate), ESTIMATE_QOS
            )
        self.create_timer(1.0, self.guard(self._publish_rod))
        self.updater = Updater(hardware_id=self.p.frame_id)
        self.updater.add_check("markers", self._check)
        self.guard.attach(self.updater)
        self.diagnostics = DiagnosticsPublisher(self, self.updater)

    def _on_change(self, new: TapMarkerParameters) -> None:
        self.p = new

    def _marker(
        self, spec: MarkerSpec, stamp: Any, marker_id: int, kind: int, lifetime_s: float = 0.0
    ) -> Marker:
        """A ``visualization_msgs/Marker`` (ADD) drawing ``spec`` in ``frame_id``."""
        m = Marker()
        m.header.frame_id = self.p.frame_id
        m.header.stamp = stamp
        m.ns, m.id, m.type, m.action = NS, marker_id, kind, Marker.ADD
        m.pose.position.x, m.pose.position.y, m.pose.position.z = spec.position
        o = m.pose.orientation
        o.x, o.y, o.z, o.w = spec.orientation
        m.scale.x, m.scale.y, m.scale.z = spec.scale
        m.color.r, m.color.g, m.color.b, m.color.a = spec.rgba
        m.text = spec.text
        sec = int(lifetime_s)
        m.lifetime = Duration(sec=sec, nanosec=round((lifetime_s - sec) * 1e9))
        return m

    def _publish_rod(self) -> None:
        spec = rod_marker(self.p.rod_length_m, self.p.rod_axis)
        self.pub.publish(self._marker(spec, self.get_clock().now().to_msg(), 0, Marker.CYLINDER))

    def _on_estimate(self, msg: ContactEstimate) -> None:
        estimate = estimate_of(msg)
        if estimate.task != TAP_TASK:
            return
        try:
            spec = tap_marker(estimate, self.p.rod_length_m, self.p.rod_axis, self.p.min_diameter_m)
        except BehaviourError as err:
            self.dropped += 1
            self.get_logger().warning(f"estimate dropped: {err}")
            return
        self._publish_rod()
        stamp, lifetime = msg.header.stamp, self.p.lifetime_s
        self.pub.publish(self._marker(spec, stamp, 1, Marker.SPHERE, lifetime))
        label = spec._replace(
            position=(spec.position[0], spec.position[1], spec.position[2] + 0.03),
            scale=(0.0, 0.0, 0.02),
            rgba=(1.0, 1.0, 1.0, 1.0),
        )
        self.pub.publish(self._marker(label, stamp, 2, Marker.TEXT_VIEW_FACING, lifetime))
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
                "rod_length_m": self.p.rod_length_m,
            },
        )


def main(args: list[str] | None = None) -> int:
    """Run the node."""
    return run_node(TapMarkerNode, args)
