import contextlib
import os
import time

import pytest

pytestmark = pytest.mark.ros


@contextlib.contextmanager
def _device_and_listener(**params):
    """A ``sim_device`` with ``params`` and ground-truth listener nodes (created by the caller
    through the returned ``listen(name)``, each appending to ``got``), torn down with their
    context."""
    rclpy = pytest.importorskip("rclpy")
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import Parameter

    from ext_sense_msgs.msg import ContactGroundTruth
    from ext_sense_runtime.qos import GROUND_TRUTH_OFFERED_QOS, GROUND_TRUTH_QOS
    from ext_sense_sim.nodes.sim_device import SimDeviceNode

    context = rclpy.Context()
    rclpy.init(context=context)
    nodes = []
    try:
        overrides = [Parameter(k, value=v) for k, v in params.items()]
        node = SimDeviceNode(context=context, parameter_overrides=overrides)
        nodes.append(node)
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(node)
        got: list = []

        def listen(name: str = "gt_listener", latched: bool = False) -> None:
            listener = rclpy.create_node(name, context=context)
            nodes.append(listener)
            qos = GROUND_TRUTH_OFFERED_QOS if latched else GROUND_TRUTH_QOS
            listener.create_subscription(ContactGroundTruth, "ground_truth", got.append, qos)
            executor.add_node(listener)

        yield node, executor, listen, got
    finally:
        for n in nodes:
            n.destroy_node()
        rclpy.try_shutdown(context=context)


def _spin(executor, seconds: float, done=lambda: False, fd: int | None = None) -> bytes:
    """Spin ``executor`` for ``seconds`` or until ``done()``; what was read from ``fd`` (the
    device's pty, non-blocking) meanwhile."""
    data = b""
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline and not done():
        executor.spin_once(timeout_sec=0.05)
        if fd is not None:
            with contextlib.suppress(BlockingIOError):
                data += os.read(fd, 65536)
    return data


def test_node_streams_bytes_and_publishes_ground_truth(tmp_path):
    from ext_sense_runtime.stamps import stamp_to_ns

    link = tmp_path / "nuskin_port"
    device = _device_and_listener(
        scene="tap_rod20_nuskin", port_link=str(link), trials=0, trial_period_s=0.5
    )
    with device as (_node, executor, listen, got):
        listen()
        fd = os.open(link, os.O_RDONLY | os.O_NONBLOCK)
        data = _spin(executor, 20, lambda: len(got) >= 2, fd)
        os.close(fd)
        # the first trials may be published before discovery matched the listener (volatile
        # QoS), so the stream runs forever and any two consecutive trials will do
        trials = [m.trial for m in got]
        assert len(trials) == 2
        assert trials[1] == trials[0] + 1
        assert 0.03 < got[0].tap_position_m < 0.2
        assert got[0].rod_length_m == pytest.approx(0.2)
        stamp = stamp_to_ns(got[0].header.stamp)
        assert abs(stamp - time.time_ns()) < 30 * 10**9
        from ext_sense_drivers.nuskin.wire import WordDecoder

        words = WordDecoder().feed(data)
        assert words.taxel.size > 100  # the taps' receiver words arrived on the pty
        assert words.taxel.min() >= 1
        assert words.taxel.max() <= 80
    assert not link.exists()


def test_a_listener_asking_for_transient_local_gets_the_truths_from_before_it_joined(tmp_path):
    """The device offers its truths latched: a recorder matched after the first trials (as a
    test's recorder under load was) still gets them; a volatile listener still matches."""
    link = tmp_path / "nuskin_port"
    device = _device_and_listener(
        scene="tap_rod20_nuskin", port_link=str(link), trials=0, trial_period_s=0.4
    )
    with device as (node, executor, listen, got):
        fd = os.open(link, os.O_RDONLY | os.O_NONBLOCK)
        try:
            _spin(executor, 30, lambda: node.played >= 2, fd)
            assert node.played >= 2  # two trials published before anyone listened
            listen("late_volatile")
            listen("late_recorder", latched=True)
            _spin(executor, 10, lambda: len(got) >= 2)
        finally:
            os.close(fd)
        assert [m.trial for m in got][:2] == [0, 1]


def test_with_wait_for_listener_the_first_trial_waits_for_a_ground_truth_subscriber(tmp_path):
    """No trial before someone listens: trial 0 is the first the listener hears."""
    device = _device_and_listener(
        scene="tap_rod20_nuskin",
        port_link=str(tmp_path / "nuskin_port"),
        trial_period_s=0.4,
        wait_for_listener_s=60.0,
    )
    with device as (node, executor, listen, got):
        _spin(executor, 5.0)  # the first trial is simulated in about 1.5 s
        assert node.played == 0  # nobody listens: nothing streamed
        assert node.stats.writes == 0
        listen()
        _spin(executor, 20, lambda: bool(got))
        assert [m.trial for m in got][:1] == [0]


def test_with_a_listener_node_only_that_node_starts_the_trials(tmp_path):
    """A view or recorder subscribing first does not start the trials; the monitor does."""
    device = _device_and_listener(
        scene="tap_rod20_nuskin",
        port_link=str(tmp_path / "nuskin_port"),
        trial_period_s=0.4,
        wait_for_listener_s=60.0,
        listener_node="estimate_monitor",
    )
    with device as (node, executor, listen, got):
        listen("view")
        _spin(executor, 5.0)  # the first trial is simulated in about 1.5 s
        assert node.pub.get_subscription_count() == 1  # the view is matched ...
        assert node.played == 0  # ... and nothing was streamed for it alone
        listen("estimate_monitor")
        _spin(executor, 20, lambda: bool(got))
        assert got[0].trial == 0  # the view and the monitor both hear trial 0 first
