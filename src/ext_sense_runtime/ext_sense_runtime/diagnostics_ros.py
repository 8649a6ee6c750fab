"""Publishing :class:`ext_sense_runtime.diagnostics.Updater` reports on ``/diagnostics``."""

from __future__ import annotations

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.node import Node

from ext_sense_runtime.diagnostics import StatusReport, Updater
from ext_sense_runtime.qos import DIAGNOSTICS_QOS


def to_msg(report: StatusReport, node_name: str) -> DiagnosticStatus:
    """Convert one report; the status name is ``"<node>: <task>"`` as diagnostic_updater does."""
    return DiagnosticStatus(
        level=bytes([int(report.level)]),
        name=f"{node_name}: {report.name}",
        message=report.message,
        hardware_id=report.hardware_id,
        values=[KeyValue(key=k, value=v) for k, v in report.values],
    )


class DiagnosticsPublisher:
    """Runs an updater on a timer of the node (1 Hz by default) and publishes the reports."""

    def __init__(self, node: Node, updater: Updater, period_s: float = 1.0) -> None:
        self._node = node
        self.updater = updater
        self._pub = node.create_publisher(DiagnosticArray, "/diagnostics", DIAGNOSTICS_QOS)
        self._timer = node.create_timer(period_s, self.publish)

    def publish(self, force: bool = True) -> None:
        """Publish the current reports now."""
        reports = self.updater.update(force=force)
        if not reports:
            return
        msg = DiagnosticArray()
        msg.header.stamp = self._node.get_clock().now().to_msg()
        msg.status = [to_msg(r, self._node.get_name()) for r in reports]
        self._pub.publish(msg)
