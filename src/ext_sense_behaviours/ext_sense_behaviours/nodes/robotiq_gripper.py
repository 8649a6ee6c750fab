"""``robotiq_gripper`` node: a Robotiq 2F over Modbus RTU behind two topics.

``control_msgs`` (GripperCommand action) and ``std_srvs`` are not available here, so the
interface is topics:

- ``gripper/command`` (``sensor_msgs/JointState``, in): ``position[0]`` the requested closure,
  0.0 open .. 1.0 closed; optional ``velocity[0]`` speed and ``effort[0]`` force, each 0..1
  (missing: the ``speed``/``force`` parameters).
- ``gripper/activate`` (``std_msgs/Bool``, in): true resets and activates (clears faults),
  false resets (rACT = 0).
- ``gripper/status`` (``diagnostic_msgs/DiagnosticStatus``, out, every poll): level OK / WARN
  (not ready) / ERROR (fault or link error), a readable message, and the register fields as
  key-values ``gACT gGTO gSTA gOBJ gFLT gPR gPO gCU``, plus ``link`` = ``ok`` when they were
  read just now or ``error`` when they are the last values read before a link error.
- ``gripper/joint_states`` (``sensor_msgs/JointState``, out): ``position[0]`` = gPO / 255
  (normalised closure, not the URDF joint angle), ``effort[0]`` = gCU x 0.01 A.

The serial link lives in a worker thread
(:class:`~ext_sense_behaviours.gripper_worker.GripperWorker`), so the executor never blocks on
the device.
"""

from __future__ import annotations

import math
import threading
from typing import Any

from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
from rclpy.node import Node
from sensor_msgs.msg import JointState
from std_msgs.msg import Bool

from ext_sense_behaviours.gripper import describe, status_to_values
from ext_sense_behaviours.gripper_worker import GripperCommandRequest, GripperWorker
from ext_sense_drivers.robotiq import GripperStatus, RobotiqClient, RobotiqError
from ext_sense_runtime.diagnostics import Level, Updater
from ext_sense_runtime.diagnostics_ros import DiagnosticsPublisher
from ext_sense_runtime.node_main import run_node
from ext_sense_runtime.parameters import declare
from ext_sense_runtime.qos import COMMAND_QOS


def _fraction_to_byte(value: float) -> int:
    return round(min(max(value, 0.0), 1.0) * 255)


class RobotiqGripperNode(Node):
    """Drives one Robotiq 2F gripper."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(kwargs.pop("node_name", "robotiq_gripper"), **kwargs)
        self.port = declare(self, "port", "", "Serial device of the gripper.", read_only=True)
        baud = declare(
            self, "baud", 115200, "Baud rate, bit/s.", low=9600, high=921600, read_only=True
        )
        slave = declare(self, "slave_id", 9, "Modbus slave id.", low=1, high=247, read_only=True)
        timeout_s = declare(
            self,
            "timeout_s",
            0.5,
            "Reply timeout per exchange, seconds.",
            low=0.01,
            high=5.0,
            read_only=True,
        )
        retries = declare(
            self,
            "retries",
            2,
            "Retries after a missing or corrupt reply.",
            low=0,
            high=10,
            read_only=True,
        )
        poll_hz = declare(
            self, "poll_rate_hz", 10.0, "Status poll rate, Hz.", low=0.5, high=100.0, read_only=True
        )
        auto_activate = declare(self, "auto_activate", True, "Activate the gripper on connect.")
        self.speed = declare(
            self, "speed", 0.5, "Default finger speed, 0..1 of maximum.", low=0.0, high=1.0
        )
        self.force = declare(
            self, "force", 0.5, "Default grip force, 0..1 of maximum.", low=0.0, high=1.0
        )
        self.joint_name = declare(self, "joint_name", "finger_joint", "Joint name in joint_states.")
        self.add_on_set_parameters_callback(self._on_set)

        self._lock = threading.Lock()
        self.status: GripperStatus | None = None
        self.error: str = ""
        self.status_pub = self.create_publisher(DiagnosticStatus, "gripper/status", COMMAND_QOS)
        self.joint_pub = self.create_publisher(JointState, "gripper/joint_states", COMMAND_QOS)
        self.create_subscription(JointState, "gripper/command", self._on_command, COMMAND_QOS)
        self.create_subscription(Bool, "gripper/activate", self._on_activate, COMMAND_QOS)

        self.worker: GripperWorker | None = None
        if not self.port:
            self.error = (
                "parameter 'port' is empty: set it to the gripper's serial device (e.g. the pty "
                "path printed by `ext-sense sim serve robotiq`)"
            )
            self.get_logger().error(self.error)
            self.create_timer(1.0, lambda: self._publish_status(None, None))
        else:
            self.worker = GripperWorker(
                lambda: RobotiqClient.open(
                    self.port, baud, timeout_s, slave=slave, retries=retries
                ),
                self._on_worker_status,
                poll_period_s=1.0 / poll_hz,
                auto_activate=auto_activate,
            )
            self.worker.start()
        self.updater = Updater(hardware_id=self.port or "no port")
        self.updater.add_check("link", self._check_link)
        self.diagnostics = DiagnosticsPublisher(self, self.updater)

    def _on_set(self, params: list) -> Any:
        from rcl_interfaces.msg import SetParametersResult

        for p in params:
            if p.name in ("speed", "force"):
                setattr(self, p.name, float(p.value))
        return SetParametersResult(successful=True)

    def _on_command(self, msg: JointState) -> None:
        if not msg.position or not math.isfinite(msg.position[0]):
            self.get_logger().warning(
                "gripper/command ignored: position[0] (0 open .. 1 closed) missing or NaN"
            )
            return
        speed = msg.velocity[0] if msg.velocity and math.isfinite(msg.velocity[0]) else self.speed
        force = msg.effort[0] if msg.effort and math.isfinite(msg.effort[0]) else self.force
        request = GripperCommandRequest(
            "move",
            _fraction_to_byte(msg.position[0]),
            _fraction_to_byte(speed),
            _fraction_to_byte(force),
        )
        if self.worker is None or not self.worker.submit(request):
            self.get_logger().error(f"gripper command dropped: {self.error or 'queue full'}")

    def _on_activate(self, msg: Bool) -> None:
        if self.worker is not None:
            self.worker.submit(GripperCommandRequest("activate" if msg.data else "reset"))

    def _on_worker_status(self, status: GripperStatus | None, error: RobotiqError | None) -> None:
        with self._lock:
            self.status = status
            previous, self.error = self.error, "" if error is None else str(error)
        if error is not None and str(error) != previous:
            self.get_logger().error(f"gripper: {error}")
        self._publish_status(status, error)

    def _publish_status(self, status: GripperStatus | None, error: RobotiqError | None) -> None:
        msg = DiagnosticStatus(name="robotiq_2f", hardware_id=self.port or "no port")
        if error is not None or self.error:
            level, text = Level.ERROR, self.error
        elif status is None:
            level, text = Level.WARN, "no status yet"
        elif status.fault:
            level, text = Level.ERROR, describe(status)
        else:
            level, text = (Level.OK if status.ready else Level.WARN), describe(status)
        msg.level, msg.message = bytes([int(level)]), text
        if status is not None:
            # ``link``: "ok" when these values were read just now, "error" when they are the
            # last ones read before a link error (so a reader knows whether they are current)
            fresh = error is None and not self.error
            msg.values = [KeyValue(key=k, value=v) for k, v in status_to_values(status)]
            msg.values.append(KeyValue(key="link", value="ok" if fresh else "error"))
            joints = JointState(
                name=[self.joint_name],
                position=[status.position / 255.0],
                effort=[status.current * 0.01],
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
        if error:
            return Level.ERROR, error, values
        if status is None:
            return Level.WARN, "no status yet", values
        return (Level.OK if status.ready else Level.WARN), describe(status), values

    def destroy_node(self) -> None:
        """Stop the worker thread and close the port, then destroy the node."""
        if self.worker is not None:
            self.worker.stop()
        super().destroy_node()


def main(args: list[str] | None = None) -> int:
    """Run the node."""
    return run_node(RobotiqGripperNode, args)
