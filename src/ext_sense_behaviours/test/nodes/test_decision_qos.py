"""A behaviour's decisions are latched: a subscriber matched after the first step still gets it."""

from __future__ import annotations

import pytest

rclpy = pytest.importorskip("rclpy")

from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rosutil import spin_until  # noqa: E402
from std_msgs.msg import String  # noqa: E402

from ext_sense_behaviours.food import FoodState  # noqa: E402
from ext_sense_behaviours.nodes.food_behaviour import FoodBehaviourNode  # noqa: E402
from ext_sense_runtime.qos import COMMAND_QOS, DECISION_QOS  # noqa: E402

pytestmark = [pytest.mark.ros, pytest.mark.timeout(60)]


@pytest.fixture
def started_food_behaviour():
    """A food behaviour that has already published its first decision, with no one listening."""
    context = rclpy.context.Context()
    rclpy.init(context=context)
    executor = SingleThreadedExecutor(context=context)
    behaviour = FoodBehaviourNode(
        context=context,
        namespace="/decision_qos_test",
        parameter_overrides=[Parameter("auto_start", value=True)],
    )
    executor.add_node(behaviour)
    assert spin_until(executor, lambda: behaviour.machine.state != FoodState.IDLE, 10.0)
    listener = rclpy.create_node("decision_listener", context=context)
    executor.add_node(listener)
    yield behaviour, listener, executor
    for node in (listener, behaviour):
        executor.remove_node(node)
        node.destroy_node()
    executor.shutdown()
    rclpy.try_shutdown(context=context)


def test_a_late_latched_subscriber_gets_the_first_decision(started_food_behaviour):
    _, listener, executor = started_food_behaviour
    got: list[str] = []
    listener.create_subscription(
        String, "/decision_qos_test/food/decision", lambda m: got.append(m.data), DECISION_QOS
    )
    assert spin_until(executor, lambda: bool(got), 10.0), "no decision reached a late subscriber"
    assert "LOWERING" in got[0], got


def test_a_volatile_subscriber_is_still_served(started_food_behaviour):
    """Durability is compatible downwards: an ``ros2 topic echo`` without options still matches."""
    behaviour, listener, executor = started_food_behaviour
    listener.create_subscription(String, "/decision_qos_test/food/decision", print, COMMAND_QOS)
    assert spin_until(executor, lambda: behaviour.decision_pub.get_subscription_count() == 1, 10.0)
