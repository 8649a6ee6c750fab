"""The Robotiq gripper node as a lifecycle node, driven through the standard lifecycle services.

Unconfigured it holds no link (the emulated gripper hears nothing); configured it opens the
Modbus link and polls, but refuses goals; active it serves them; deactivated it refuses them
again with the link open; cleaned up it closes the link.
"""

from __future__ import annotations

import pytest

pytestmark = [pytest.mark.ros, pytest.mark.timeout(60)]

rclpy = pytest.importorskip("rclpy")

from action_msgs.msg import GoalStatus  # noqa: E402
from control_msgs.action import GripperCommand  # noqa: E402
from lifecycle_msgs.msg import State, Transition  # noqa: E402
from lifecycle_msgs.srv import ChangeState, GetState  # noqa: E402
from rclpy.action import ActionClient  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rosutil import spin_until  # noqa: E402

from ext_sense_behaviours.nodes.robotiq_gripper import RobotiqGripperNode  # noqa: E402
from ext_sense_sim.devices.robotiq_emulator import (  # noqa: E402
    GripperModel,
    PtyGripper,
    RobotiqEmulator,
)


def _call(executor, client, request):
    assert spin_until(executor, client.service_is_ready)
    future = client.call_async(request)
    assert spin_until(executor, future.done)
    return future.result()


def _goal(executor, client, position):
    """Send a GripperCommand goal; returns ``None`` when refused, else the final status."""
    assert spin_until(executor, client.server_is_ready)
    goal = GripperCommand.Goal()
    goal.command.position = position
    sent = client.send_goal_async(goal)
    assert spin_until(executor, sent.done)
    if not sent.result().accepted:
        return None
    result = sent.result().get_result_async()
    assert spin_until(executor, result.done)
    return result.result().status


def test_gripper_waits_for_a_manager_and_follows_its_transitions():
    context = rclpy.Context()
    rclpy.init(context=context)
    emulator = RobotiqEmulator(GripperModel(activation_s=0.1))
    executor = SingleThreadedExecutor(context=context)
    with PtyGripper(emulator) as pty:
        gripper = RobotiqGripperNode(
            context=context,
            cli_args=["--ros-args", "-r", "__node:=gripper"],
            parameter_overrides=[
                Parameter("port", value=pty.path),
                Parameter("autostart", value=False),
                Parameter("poll_rate_hz", value=20.0),
            ],
        )
        manager = rclpy.create_node("manager", context=context)
        change = manager.create_client(ChangeState, "/gripper/change_state")
        get = manager.create_client(GetState, "/gripper/get_state")
        action = ActionClient(manager, GripperCommand, "/robotiq_gripper_controller/gripper_cmd")
        executor.add_node(gripper)
        executor.add_node(manager)

        def transition(tid):
            return _call(executor, change, ChangeState.Request(transition=Transition(id=tid)))

        try:
            state = _call(executor, get, GetState.Request()).current_state
            assert state.id == State.PRIMARY_STATE_UNCONFIGURED
            spin_until(executor, lambda: False, 0.3)
            assert gripper.worker is None
            assert emulator.counters.requests == 0  # no link held
            assert _goal(executor, action, 0.0) is None  # refused
            assert transition(Transition.TRANSITION_CONFIGURE).success
            # configured: the link is open and polled, and the gripper activated; no goals
            assert spin_until(executor, lambda: bool(gripper.status and gripper.status.ready))
            assert emulator.counters.requests > 0
            assert _goal(executor, action, 0.0) is None
            assert transition(Transition.TRANSITION_ACTIVATE).success
            assert _goal(executor, action, 0.0) == GoalStatus.STATUS_SUCCEEDED
            assert emulator.status().position > 200  # closed
            assert transition(Transition.TRANSITION_DEACTIVATE).success
            assert _goal(executor, action, 0.085) is None
            assert emulator.status().position > 200  # did not move
            assert transition(Transition.TRANSITION_CLEANUP).success
            assert gripper.worker is None
            polled = emulator.counters.requests
            spin_until(executor, lambda: False, 0.3)
            assert emulator.counters.requests == polled  # the link is closed
            assert gripper.goals["rejected"] == 3
        finally:
            executor.shutdown()
            gripper.destroy_node()
            manager.destroy_node()
            rclpy.try_shutdown(context=context)
