"""Between ROS messages and the plain records of the behaviours.

Estimates are read with :func:`ext_sense_runtime.records.estimate_of`.
"""

from __future__ import annotations

from builtin_interfaces.msg import Duration
from visualization_msgs.msg import Marker

from ext_sense_behaviours.tap import MarkerSpec


def marker_from_spec(
    spec: MarkerSpec,
    frame_id: str,
    stamp: object,
    ns: str,
    marker_id: int,
    kind: int,
    lifetime_s: float = 0.0,
) -> Marker:
    """A ``visualization_msgs/Marker`` (ADD) drawing ``spec``."""
    m = Marker()
    m.header.frame_id = frame_id
    m.header.stamp = stamp
    m.ns, m.id, m.type, m.action = ns, int(marker_id), int(kind), Marker.ADD
    m.pose.position.x, m.pose.position.y, m.pose.position.z = spec.position
    o = m.pose.orientation
    o.x, o.y, o.z, o.w = spec.orientation
    m.scale.x, m.scale.y, m.scale.z = spec.scale
    m.color.r, m.color.g, m.color.b, m.color.a = spec.rgba
    m.text = spec.text
    sec = int(lifetime_s)
    m.lifetime = Duration(sec=sec, nanosec=round((lifetime_s - sec) * 1e9))
    return m
