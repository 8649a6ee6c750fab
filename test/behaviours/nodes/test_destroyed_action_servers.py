"""A destroyed node serves no action: rclpy's ``destroy_node`` alone leaves action servers alive.

Until garbage collection, such a ghost server stays discoverable as ready. A node made next in
the same process (a test, or a graph run in one process) then sends its goals to a node nobody
spins; CI failed on exactly that (test_franka_adapter: ready, then gone, before its goal).
Each test keeps a reference to the destroyed node, so garbage collection cannot hide a leak.
"""

from __future__ import annotations

import pytest

pytestmark = [pytest.mark.ros, pytest.mark.timeout(60)]

rclpy = pytest.importorskip("rclpy")

from control_msgs.action import FollowJointTrajectory, GripperCommand  # noqa: E402
from rclpy.action import ActionClient  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rosutil import spin_until  # noqa: E402

from ext_sense_behaviours.nodes.robotiq_gripper import RobotiqGripperNode  # noqa: E402

LOOK_S = 2.0  # a leaked server was found in well under a second by a fresh participant


def _ready_seen(make_node, action_type, action_name: str) -> tuple[bool, bool, object]:
    """Whether a client sees the action with the node alive, then from a fresh context after.

    Returns (seen while alive, seen after destroy_node, the destroyed node kept alive).
    """
    context = rclpy.Context()
    rclpy.init(context=context)
    node = make_node(context)
    probe = rclpy.create_node("probe", context=context)
    client = ActionClient(probe, action_type, action_name)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    executor.add_node(probe)
    alive = spin_until(executor, client.server_is_ready)
    executor.shutdown()
    node.destroy_node()
    client.destroy()
    probe.destroy_node()
    rclpy.try_shutdown(context=context)

    fresh = rclpy.Context()
    rclpy.init(context=fresh)
    later = rclpy.create_node("later", context=fresh)
    later_client = ActionClient(later, action_type, action_name)
    later_executor = SingleThreadedExecutor(context=fresh)
    later_executor.add_node(later)
    try:
        after = spin_until(later_executor, later_client.server_is_ready, LOOK_S)
    finally:
        later_executor.shutdown()
        later_client.destroy()
        later.destroy_node()
        rclpy.try_shutdown(context=fresh)
    return alive, after, node


def test_a_destroyed_sim_arm_leaves_no_trajectory_server():
    pytest.importorskip("franka_msgs", reason="franka_msgs is not built into this venv")
    from ext_sense_sim.nodes.sim_arm import SimArmNode

    alive, after, _kept = _ready_seen(
        lambda context: SimArmNode(context=context),
        FollowJointTrajectory,
        "/fr3_arm_controller/follow_joint_trajectory",
    )
    assert alive
    assert not after, "the destroyed sim_arm's trajectory server is still discoverable"


def test_a_destroyed_robotiq_gripper_leaves_no_gripper_server():
    alive, after, _kept = _ready_seen(
        lambda context: RobotiqGripperNode(
            context=context,
            parameter_overrides=[
                Parameter("port", value="/dev/ext_sense_no_such_port"),
                Parameter("autostart", value=False),  # unconfigured: the port is never opened
            ],
        ),
        GripperCommand,
        "/robotiq_gripper_controller/gripper_cmd",
    )
    assert alive
    assert not after, "the destroyed gripper node's GripperCommand server is still discoverable"
