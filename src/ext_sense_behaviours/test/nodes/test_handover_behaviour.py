"""The behaviour nodes in one process with rclpy: topics in, topics out."""

from __future__ import annotations

import time
from collections.abc import Callable

import pytest

rclpy = pytest.importorskip("rclpy")

from diagnostic_msgs.msg import DiagnosticStatus, KeyValue  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.node import Node  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402
from std_msgs.msg import String  # noqa: E402
from visualization_msgs.msg import Marker  # noqa: E402

from ext_sense_behaviours.gripper import status_to_values  # noqa: E402
from ext_sense_drivers.robotiq import ActivationStatus, GripperStatus, ObjectStatus  # noqa: E402
from ext_sense_msgs.msg import ContactEstimate, ContactGroundTruth  # noqa: E402
from ext_sense_runtime.qos import COMMAND_QOS, ESTIMATE_QOS  # noqa: E402
from ext_sense_runtime.stamps import stamp_to_ns  # noqa: E402
from ext_sense_sim.devices.robotiq_emulator import (  # noqa: E402
    GripperModel,
    LinkFault,
    PtyGripper,
    RobotiqEmulator,
)

pytestmark = [pytest.mark.ros, pytest.mark.timeout(60)]


@pytest.fixture
def ros():
    context = rclpy.context.Context()
    rclpy.init(context=context)
    executor = SingleThreadedExecutor(context=context)
    nodes: list[Node] = []

    def add(node_cls, **kwargs):
        node = node_cls(context=context, **kwargs)
        nodes.append(node)
        executor.add_node(node)
        return node

    def spin_until(cond: Callable[[], bool], timeout_s: float = 10.0) -> bool:
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.02)
            if cond():
                return True
        return False

    yield add, spin_until
    for node in nodes:
        executor.remove_node(node)
        node.destroy_node()
    executor.shutdown()
    rclpy.try_shutdown(context=context)


class Probe(Node):
    def __init__(self, **kwargs):
        super().__init__("probe", **kwargs)
        self.got: dict[str, list] = {}

    def listen(self, msg_type, topic, qos=COMMAND_QOS):
        self.got[topic] = []
        self.create_subscription(msg_type, topic, self.got[topic].append, qos)

    def publisher(self, msg_type, topic, qos=COMMAND_QOS):
        return self.create_publisher(msg_type, topic, qos)


def test_tap_marker_draws_the_estimate(ros):
    from ext_sense_behaviours.nodes.tap_marker import TapMarkerNode

    add, spin_until = ros
    add(
        TapMarkerNode,
        node_name="tap_marker_renamed",
        parameter_overrides=[Parameter("rod_length_m", value=0.5)],
    )
    probe = add(Probe)
    probe.listen(Marker, "marker")
    pub = probe.publisher(ContactEstimate, "contact_estimate", ESTIMATE_QOS)
    assert spin_until(lambda: pub.get_subscription_count() > 0)
    msg = ContactEstimate(task="tap_localization", tap_position_m=0.21, tap_position_std_m=0.02)
    pub.publish(msg)
    assert spin_until(lambda: any(m.id == 1 for m in probe.got["marker"]))
    tap = next(m for m in probe.got["marker"] if m.id == 1)
    assert tap.type == Marker.SPHERE
    assert tap.pose.position.x == pytest.approx(0.21)
    assert tap.scale.x == pytest.approx(0.04)
    rod = next(m for m in probe.got["marker"] if m.id == 0)
    assert rod.scale.z == pytest.approx(0.5)


def test_robotiq_gripper_node_on_the_emulator(ros):
    from ext_sense_behaviours.nodes.robotiq_gripper import RobotiqGripperNode

    add, spin_until = ros
    emulator = RobotiqEmulator(GripperModel(activation_s=0.1, object_position=120))
    with PtyGripper(emulator) as pty:
        add(
            RobotiqGripperNode,
            parameter_overrides=[
                Parameter("port", value=pty.path),
                Parameter("timeout_s", value=0.5),
                Parameter("retries", value=1),
                Parameter("poll_rate_hz", value=20.0),
            ],
        )
        probe = add(Probe)
        probe.listen(DiagnosticStatus, "gripper/status")
        probe.listen(JointState, "gripper/joint_states")
        cmd = probe.publisher(JointState, "gripper/command")
        statuses = probe.got["gripper/status"]
        assert spin_until(lambda: statuses and statuses[-1].message == "activated, idle")
        cmd.publish(JointState(position=[1.0], velocity=[1.0], effort=[0.5]))
        assert spin_until(lambda: statuses[-1].message == "holding an object")
        values = dict((kv.key, kv.value) for kv in statuses[-1].values)
        assert values["gOBJ"] == "2"
        assert values["gPO"] == "120"
        joints = probe.got["gripper/joint_states"]
        assert spin_until(lambda: joints[-1].position[0] == pytest.approx(120 / 255))
        emulator.set_fault(LinkFault.NO_ANSWER)
        assert spin_until(lambda: statuses[-1].level == bytes([2]))
        assert "No answer" in statuses[-1].message
        emulator.set_fault(LinkFault.NONE)
        assert spin_until(lambda: statuses[-1].message == "holding an object")


def _gripper_status(obj: ObjectStatus, position: int, request: int) -> DiagnosticStatus:
    status = GripperStatus(True, True, ActivationStatus.COMPLETED, obj, 0, 0, request, position, 0)
    return DiagnosticStatus(
        level=bytes([0]),
        name="robotiq_2f",
        message="",
        values=[KeyValue(key=k, value=v) for k, v in status_to_values(status)],
    )


def test_handover_node_opens_after_three_stable_estimates(ros):
    from ext_sense_behaviours.nodes.handover_behaviour import HandoverBehaviourNode

    add, spin_until = ros
    add(HandoverBehaviourNode, parameter_overrides=[Parameter("consecutive", value=3)])
    probe = add(Probe)
    probe.listen(JointState, "gripper/command")
    probe.listen(String, "handover/decision")
    status_pub = probe.publisher(DiagnosticStatus, "gripper/status")
    est_pub = probe.publisher(ContactEstimate, "contact_estimate", ESTIMATE_QOS)
    decisions = probe.got["handover/decision"]
    assert spin_until(lambda: status_pub.get_subscription_count() > 0)
    assert spin_until(lambda: est_pub.get_subscription_count() > 0)
    status_pub.publish(_gripper_status(ObjectStatus.DETECTED_CLOSING, 150, 255))
    assert spin_until(lambda: any("HOLDING" in d.data for d in decisions))
    for p, prov in [
        (0.9, False),
        (0.95, True),
        (0.9, False),
        (0.3, False),
        (0.9, False),
        (0.9, False),
    ]:
        est_pub.publish(
            ContactEstimate(task="handover_stability", stability_probability=p, provisional=prov)
        )
        spin_until(lambda: False, 0.1)
    assert probe.got["gripper/command"] == []  # the streak was broken by the 0.3
    est_pub.publish(ContactEstimate(task="handover_stability", stability_probability=0.97))
    assert spin_until(lambda: len(probe.got["gripper/command"]) == 1)
    assert probe.got["gripper/command"][0].position[0] == 0.0
    status_pub.publish(_gripper_status(ObjectStatus.AT_POSITION, 0, 0))
    assert spin_until(lambda: "RELEASED" in decisions[-1].data)
    texts = [d.data for d in decisions]
    assert any("provisional estimate" in t for t in texts)
    assert any("unstable grasp" in t for t in texts)


def test_food_node_on_the_simulated_arm(ros):
    from ext_sense_behaviours.nodes.food_behaviour import FoodBehaviourNode

    add, spin_until = ros
    add(
        FoodBehaviourNode,
        parameter_overrides=[
            Parameter("auto_start", value=True),
            Parameter("window_end_s", value=1.0),
            Parameter("sim_start_z_m", value=0.125),
            Parameter("sim_surface_z_m", value=0.12),
            Parameter("sim_stiffness_n_per_m", value=20000.0),
            Parameter("retract_speed_mps", value=0.1),
        ],
    )
    probe = add(Probe)
    probe.listen(ContactGroundTruth, "motion_start")
    probe.listen(ContactEstimate, "food/result", ESTIMATE_QOS)
    probe.listen(String, "food/decision")
    est_pub = probe.publisher(ContactEstimate, "contact_estimate", ESTIMATE_QOS)
    decisions = probe.got["food/decision"]
    assert spin_until(lambda: probe.got["motion_start"])
    start = probe.got["motion_start"][0]
    assert start.task == "food_identification"
    assert spin_until(lambda: any("contact: |F|=" in d.data for d in decisions))
    assert spin_until(lambda: any("CLASSIFYING" in d.data for d in decisions))
    result = ContactEstimate(task="food_identification", class_label="apple")
    result.header.stamp = start.header.stamp
    est_pub.publish(result)
    assert spin_until(lambda: probe.got["food/result"])
    assert probe.got["food/result"][0].class_label == "apple"
    assert stamp_to_ns(probe.got["food/result"][0].header.stamp) == stamp_to_ns(start.header.stamp)
    assert spin_until(lambda: "DONE: PUBLISH" in decisions[-1].data)
    states = [d.data.split("] ")[1].split(":")[0] for d in decisions]
    assert states == ["LOWERING", "COLLECTING", "CLASSIFYING", "RETRACTING", "DONE"]


def _handover_on_the_gripper(add, port: str, consecutive: int, gripper: list[Parameter]):
    """Start ``robotiq_gripper`` on ``port`` and ``handover_behaviour``; returns the estimate
    publisher and the list the decisions arrive in."""
    from ext_sense_behaviours.nodes.handover_behaviour import HandoverBehaviourNode
    from ext_sense_behaviours.nodes.robotiq_gripper import RobotiqGripperNode

    add(
        RobotiqGripperNode,
        parameter_overrides=[
            Parameter("port", value=port),
            Parameter("poll_rate_hz", value=20.0),
            *gripper,
        ],
    )
    add(HandoverBehaviourNode, parameter_overrides=[Parameter("consecutive", value=consecutive)])
    probe = add(Probe)
    probe.listen(String, "handover/decision")
    est_pub = probe.publisher(ContactEstimate, "contact_estimate", ESTIMATE_QOS)
    return est_pub, probe.got["handover/decision"]


def test_handover_and_gripper_nodes_on_the_emulated_gripper(ros):
    add, spin_until = ros
    emulator = RobotiqEmulator(GripperModel(activation_s=0.1, object_position=150))
    with PtyGripper(emulator) as pty:
        est_pub, decisions = _handover_on_the_gripper(
            add, pty.path, consecutive=2, gripper=[Parameter("timeout_s", value=0.5)]
        )
        # the behaviour grasps the object by itself, then waits for stable estimates
        assert spin_until(lambda: any("HOLDING" in d.data for d in decisions))
        assert emulator.status().object_held
        for p in (0.9, 0.2, 0.9):
            est_pub.publish(ContactEstimate(task="handover_stability", stability_probability=p))
            spin_until(lambda: False, 0.2)
        assert emulator.status().object_held  # 0.2 broke the streak: still holding
        est_pub.publish(ContactEstimate(task="handover_stability", stability_probability=0.95))
        assert spin_until(lambda: "RELEASED" in decisions[-1].data)
        status = emulator.status()
        assert status.position == 0
        assert status.object == ObjectStatus.AT_POSITION


def test_a_corrupted_reply_to_the_open_command_is_resolved_by_reading_the_gripper(ros):
    """BAD_CRC on the open command: FAULT (outcome unknown), then once the link answers the
    node reads where the fingers are and records the release that did happen."""
    add, spin_until = ros
    emulator = RobotiqEmulator(GripperModel(activation_s=0.1, object_position=150))
    with PtyGripper(emulator) as pty:
        est_pub, decisions = _handover_on_the_gripper(
            add,
            pty.path,
            consecutive=1,
            gripper=[Parameter("timeout_s", value=0.2), Parameter("retries", value=0)],
        )
        assert spin_until(lambda: any("HOLDING" in d.data for d in decisions))
        emulator.set_fault(LinkFault.BAD_CRC)
        est_pub.publish(ContactEstimate(task="handover_stability", stability_probability=0.95))
        assert spin_until(lambda: any("FAULT" in d.data for d in decisions))
        fault = next(d.data for d in decisions if "FAULT" in d.data)
        assert "CRC" in fault
        spin_until(lambda: False, 0.5)
        assert "RELEASED" not in decisions[-1].data  # nothing known while the link fails
        emulator.set_fault(LinkFault.NONE)
        assert spin_until(lambda: "link answers again" in decisions[-1].data)
        last = decisions[-1].data
        status = emulator.status()
        assert status.position <= 10  # the write ran despite the corrupted reply
        assert "RELEASED" in last
        assert "open command was carried out" in last
