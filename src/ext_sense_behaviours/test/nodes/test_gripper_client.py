"""The gripper action client answers every goal: a lost reply ends as a timeout, not a hang."""

from __future__ import annotations

import threading
import time

import pytest

rclpy = pytest.importorskip("rclpy")

from control_msgs.action import GripperCommand  # noqa: E402
from rclpy.action import ActionServer, CancelResponse  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.node import Node  # noqa: E402
from rosutil import spin_until  # noqa: E402

from ext_sense_behaviours.nodes.gripper_client import GripperClient, GripperReply  # noqa: E402

pytestmark = [pytest.mark.ros, pytest.mark.timeout(60)]
ACTION = "/test_gripper_client/gripper_cmd"


@pytest.fixture
def nodes():
    """A client node and a server node, each on an executor of its own (spun on demand)."""
    context = rclpy.context.Context()
    rclpy.init(context=context)
    client_node = Node("gripper_client_test", context=context)
    server_node = Node("gripper_server_test", context=context)
    executors = []
    for node in (client_node, server_node):
        ex = SingleThreadedExecutor(context=context)
        ex.add_node(node)
        executors.append(ex)
    yield client_node, server_node, executors
    for ex, node in zip(executors, (client_node, server_node), strict=True):
        ex.remove_node(node)
        node.destroy_node()
        ex.shutdown()
    rclpy.try_shutdown(context=context)


def test_a_goal_the_server_does_not_answer_ends_as_unanswered_and_a_late_answer_is_ignored(nodes):
    client_node, server_node, (client_ex, server_ex) = nodes
    canceled = threading.Event()

    def execute(handle):
        handle.succeed()
        return GripperCommand.Result(position=0.01, stalled=True)

    def cancel(_request):
        canceled.set()
        return CancelResponse.ACCEPT

    server = ActionServer(server_node, GripperCommand, ACTION, execute, cancel_callback=cancel)
    client = GripperClient(client_node, ACTION, accept_timeout_s=0.5, result_timeout_s=5.0)
    replies: list[GripperReply] = []
    assert spin_until([client_ex, server_ex], client._client.server_is_ready, 10.0)
    client.send(0.0, 20.0, replies.append)
    # the server's executor is not spun: its goal response never comes
    assert spin_until([client_ex], lambda: bool(replies), 5.0)
    assert replies[0].reason == "unanswered"
    assert not replies[0].succeeded
    assert not client.busy
    assert client.timed_out == 1
    # the server answers late: the client reports nothing more (and cancels the stale goal)
    spin_until([client_ex, server_ex], canceled.is_set, 5.0)
    assert len(replies) == 1
    # the next goal is answered as usual
    client.send(0.0, 20.0, replies.append)
    assert spin_until([client_ex, server_ex], lambda: len(replies) == 2, 10.0)
    assert replies[1].succeeded
    assert replies[1].stalled
    server.destroy()
    client.destroy()


def test_a_result_that_does_not_come_ends_as_timed_out_and_cancels_the_goal(nodes):
    client_node, server_node, (client_ex, server_ex) = nodes
    canceled = threading.Event()

    def execute(handle):  # never finishes by itself: holds until canceled
        while not handle.is_cancel_requested:
            time.sleep(0.01)
        canceled.set()
        handle.canceled()
        return GripperCommand.Result()

    from rclpy.callback_groups import ReentrantCallbackGroup
    from rclpy.executors import MultiThreadedExecutor

    server_ex.remove_node(server_node)
    threaded = MultiThreadedExecutor(num_threads=2, context=server_node.context)
    threaded.add_node(server_node)
    server = ActionServer(
        server_node,
        GripperCommand,
        ACTION,
        execute,
        cancel_callback=lambda _r: CancelResponse.ACCEPT,
        callback_group=ReentrantCallbackGroup(),
    )
    spinner = threading.Thread(target=threaded.spin, daemon=True)
    spinner.start()
    try:
        client = GripperClient(client_node, ACTION, accept_timeout_s=2.0, result_timeout_s=0.5)
        replies: list[GripperReply] = []
        assert spin_until([client_ex], client._client.server_is_ready, 10.0)
        client.send(0.0, 20.0, replies.append)
        assert spin_until([client_ex], lambda: bool(replies), 5.0)
        assert replies[0].reason == "timed out"
        assert not client.busy
        assert spin_until([client_ex], canceled.is_set, 5.0)
        spin_until([client_ex], lambda: False, 0.3)  # the canceled goal's result: ignored
        assert len(replies) == 1
        client.destroy()
        server.destroy()
    finally:
        threaded.shutdown()
        server_ex.add_node(server_node)  # the fixture removes it from here
