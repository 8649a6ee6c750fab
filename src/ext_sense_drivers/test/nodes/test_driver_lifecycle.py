"""The driver nodes as lifecycle nodes, driven through the standard lifecycle services.

An external manager (``nav2_lifecycle_manager``, ``ros2 lifecycle set``) talks to
``<node>/change_state``; with ``autostart`` false the driver waits for it: unconfigured it holds
no device, configured it opens the device (and retries until it is plugged in), active it
streams, deactivated it stops, cleaned up it lets the device go.
"""

import os

import pytest

pytestmark = pytest.mark.ros

rclpy = pytest.importorskip("rclpy")

from lifecycle_msgs.msg import State, Transition  # noqa: E402
from lifecycle_msgs.srv import ChangeState, GetState  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rosutil import spin_until  # noqa: E402

from ext_sense_drivers.nodes.nuskin_driver import NuskinDriverNode  # noqa: E402
from ext_sense_drivers.nuskin.wire import encode_words  # noqa: E402
from ext_sense_drivers.packets import NuskinPacketDecoder, packet_of  # noqa: E402
from ext_sense_drivers.transports.base import LinkState  # noqa: E402
from ext_sense_msgs.msg import SensorPacket  # noqa: E402
from ext_sense_runtime.qos import SENSOR_STREAM_QOS  # noqa: E402


def _taxels(packets):
    """The taxels of every event in the packets (decoded with the library decoder)."""
    if not packets:
        return []
    first = packet_of(packets[0])
    decoder = NuskinPacketDecoder(first.encoding, first.options)
    return [t for m in packets for t in decoder.decode(packet_of(m)).events.taxel.tolist()]


def _call(executor, client, request):
    assert spin_until(executor, client.service_is_ready)
    future = client.call_async(request)
    assert spin_until(executor, future.done)
    return future.result()


def test_nuskin_driver_waits_for_a_manager_and_follows_its_transitions(tmp_path, capfd):
    context = rclpy.Context()
    rclpy.init(context=context)
    link = tmp_path / "nuskin.pty"  # not plugged in yet: configure must still succeed
    driver = NuskinDriverNode(
        context=context,
        cli_args=["--ros-args", "-r", "__node:=skin"],
        parameter_overrides=[
            Parameter("port", value=str(link)),
            Parameter("autostart", value=False),
            Parameter("reconnect_initial_s", value=0.02),
            Parameter("reconnect_max_s", value=0.05),
        ],
    )
    manager = rclpy.create_node("manager", context=context)
    batches = []
    manager.create_subscription(SensorPacket, "packets", batches.append, SENSOR_STREAM_QOS)
    change = manager.create_client(ChangeState, "/skin/change_state")
    get = manager.create_client(GetState, "/skin/get_state")
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(driver)
    executor.add_node(manager)
    master = None
    try:
        state = _call(executor, get, GetState.Request()).current_state
        assert state.id == State.PRIMARY_STATE_UNCONFIGURED
        assert driver.reader.state == LinkState.STOPPED  # no device held

        def transition(tid):
            return _call(executor, change, ChangeState.Request(transition=Transition(id=tid)))

        assert transition(Transition.TRANSITION_CONFIGURE).success
        assert spin_until(executor, lambda: driver.reader.open_failures > 0)
        assert driver.reader.state in (LinkState.BACKOFF, LinkState.CONNECTING)
        spin_until(executor, lambda: False, 0.5)
        # the missing device is said on the console, not only on /diagnostics
        assert f"{link} unavailable" in capfd.readouterr().err
        # the device is plugged in late
        master, slave = os.openpty()
        link.symlink_to(os.ttyname(slave))
        os.close(slave)
        assert spin_until(executor, lambda: driver.reader.state == LinkState.CONNECTED)
        os.write(master, encode_words([5], [100]))
        spin_until(executor, lambda: False, 0.3)
        assert batches == []  # configured, not active: nothing streams
        assert transition(Transition.TRANSITION_ACTIVATE).success
        os.write(master, encode_words([7, 8], [200, 300]))
        assert spin_until(executor, lambda: _taxels(batches) == [7, 8])
        assert transition(Transition.TRANSITION_DEACTIVATE).success
        os.write(master, encode_words([9], [400]))
        spin_until(executor, lambda: False, 0.3)
        assert _taxels(batches) == [7, 8]
        assert transition(Transition.TRANSITION_CLEANUP).success
        assert driver.reader.state == LinkState.STOPPED
        state = _call(executor, get, GetState.Request()).current_state
        assert state.id == State.PRIMARY_STATE_UNCONFIGURED
    finally:
        executor.shutdown()
        driver.destroy_node()
        manager.destroy_node()
        rclpy.try_shutdown(context=context)
        if master is not None:
            os.close(master)
