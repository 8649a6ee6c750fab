"""The NUSkin driver node over a pty: bytes in, batches out, diagnostics, port lost and back."""

import os
from pathlib import Path

import numpy as np
import pytest

pytestmark = pytest.mark.ros

rclpy = pytest.importorskip("rclpy")

from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rosutil import spin_until  # noqa: E402

from ext_sense_drivers.nodes.nuskin_driver import NuskinDriverNode  # noqa: E402
from ext_sense_drivers.nuskin.wire import encode_words  # noqa: E402
from ext_sense_drivers.transports.base import LinkState  # noqa: E402
from ext_sense_msgs.msg import SensorPacket, TaxelEventBatch  # noqa: E402
from ext_sense_runtime.qos import DIAGNOSTICS_QOS, SENSOR_STREAM_QOS  # noqa: E402
from ext_sense_runtime.stamps import stamp_to_ns  # noqa: E402


class FakeDevice:
    """A pty whose slave is reached through a stable symlink, like a udev name."""

    def __init__(self, link: Path):
        self.link = link
        self.master = None

    def plug(self):
        master, slave = os.openpty()
        tmp = self.link.with_suffix(".new")
        tmp.unlink(missing_ok=True)
        tmp.symlink_to(os.ttyname(slave))
        os.replace(tmp, self.link)
        os.close(slave)
        self.master = master

    def unplug(self):
        # udev removes the name too; a dangling name could meet a reused /dev/pts number.
        self.link.unlink(missing_ok=True)
        os.close(self.master)
        self.master = None

    def send(self, data: bytes):
        os.write(self.master, data)


@pytest.fixture
def graph(tmp_path, request):
    """Driver on a fake device, and a probe; ``request.param``: more parameters (name: value)."""
    context = rclpy.Context()
    rclpy.init(context=context)
    device = FakeDevice(tmp_path / "nuskin.pty")
    device.plug()
    extra = [Parameter(k, value=v) for k, v in getattr(request, "param", {}).items()]
    driver = NuskinDriverNode(
        context=context,
        parameter_overrides=[
            Parameter("port", Parameter.Type.STRING, str(device.link)),
            Parameter("reconnect_initial_s", Parameter.Type.DOUBLE, 0.02),
            Parameter("reconnect_max_s", Parameter.Type.DOUBLE, 0.05),
            Parameter("frame_id", Parameter.Type.STRING, "nuskin_test"),
            *extra,
        ],
    )
    probe = rclpy.create_node("probe", context=context)
    got = {"batches": [], "diag": [], "packets": []}
    probe.create_subscription(TaxelEventBatch, "events", got["batches"].append, SENSOR_STREAM_QOS)
    probe.create_subscription(SensorPacket, "packets", got["packets"].append, SENSOR_STREAM_QOS)
    probe.create_subscription(DiagnosticArray, "/diagnostics", got["diag"].append, DIAGNOSTICS_QOS)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(driver)
    executor.add_node(probe)
    try:
        yield device, driver, executor, got
    finally:
        executor.shutdown()
        driver.destroy_node()
        probe.destroy_node()
        rclpy.try_shutdown(context=context)
        if device.master is not None:
            device.unplug()


def _events(batches):
    taxel = [t for b in batches for t in b.taxel]
    value = [v for b in batches for v in b.value]
    return taxel, value


def _diag_values(got, task):
    for arr in reversed(got["diag"]):
        for status in arr.status:
            if status.name.endswith(f": {task}"):
                return status, {kv.key: kv.value for kv in status.values}
    return None, {}


def test_bytes_in_batches_out_and_port_lost_and_back(graph):
    device, driver, executor, got = graph
    rng = np.random.default_rng(1)
    taxel = rng.integers(1, 81, 300)
    value = rng.integers(0, 1024, 300)
    # A stream that starts mid-word and carries a burst of garbage between two halves.
    raw = encode_words(taxel, value)
    # pyserial flushes the input buffer when it opens a port: send once the driver has it open.
    assert spin_until(executor, lambda: driver.reader.state == LinkState.CONNECTED, 5.0)
    device.send(raw[2:600] + bytes([0x00, 0x13, 0xFF]) + raw[600:])
    assert spin_until(executor, lambda: len(_events(got["batches"])[0]) >= 299)
    taxels, values = _events(got["batches"])
    assert taxels == taxel[1:].tolist()
    assert values == value[1:].tolist()
    last = got["batches"][-1]
    assert last.header.frame_id == "nuskin_test"
    assert last.words_total == 299
    assert last.resyncs == 2
    assert last.skipped_bytes == 2 + 3
    assert all(min(b.offset_ns) == 0 for b in got["batches"])
    assert all(list(b.offset_ns) == sorted(b.offset_ns) for b in got["batches"])
    stamps = [stamp_to_ns(b.header.stamp) for b in got["batches"]]
    assert stamps == sorted(stamps)

    # Diagnostics name the counters and the port state.
    assert spin_until(
        executor, lambda: _diag_values(got, "decode")[1].get("words_total") == "299", 5.0
    )
    _, decode = _diag_values(got, "decode")
    assert decode["resyncs"] == "2"
    assert decode["skipped_bytes"] == "5"
    status, link = _diag_values(got, "link")
    assert link["port_state"] == "connected"
    assert status.hardware_id == str(device.link)
    assert "rate_words_per_s" in _diag_values(got, "events")[1]

    # The port vanishes: the node reports it and keeps retrying.
    device.unplug()
    assert spin_until(executor, lambda: driver.reader.disconnects == 1, 5.0)
    assert spin_until(executor, lambda: driver.reader.open_failures >= 1, 5.0)
    got["diag"].clear()
    assert spin_until(executor, lambda: _diag_values(got, "link")[0] is not None, 5.0)
    assert _diag_values(got, "link")[1]["port_state"] in ("backoff", "connecting")

    # The port comes back: same node, new connection, events flow again.
    device.plug()
    assert spin_until(executor, lambda: driver.reader.state == LinkState.CONNECTED, 5.0)
    n_before = len(_events(got["batches"])[0])
    device.send(encode_words([5, 80, 41], [1, 2, 3]))
    assert spin_until(executor, lambda: len(_events(got["batches"])[0]) >= n_before + 3)
    assert _events(got["batches"])[0][n_before:] == [5, 80, 41]
    assert driver.reader.connects == 2
    assert driver.reader.alive


def test_bad_configuration_is_a_clear_error():
    context = rclpy.Context()
    rclpy.init(context=context)
    try:
        with pytest.raises(Exception, match="'transport' parameter must be one of"):
            NuskinDriverNode(
                context=context,
                parameter_overrides=[Parameter("transport", Parameter.Type.STRING, "usb")],
            )
    finally:
        rclpy.try_shutdown(context=context)


def _run_driver(overrides, until, timeout_s=8.0, feed=None):
    """Spin a driver and a probe until ``until(batches, driver)``; returns (ok, batches, state)."""
    context = rclpy.Context()
    rclpy.init(context=context)
    driver = probe = executor = None
    batches = []
    try:
        driver = NuskinDriverNode(context=context, parameter_overrides=overrides)
        probe = rclpy.create_node("probe", context=context)
        probe.create_subscription(TaxelEventBatch, "events", batches.append, SENSOR_STREAM_QOS)
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(driver)
        executor.add_node(probe)
        if feed is not None:
            assert spin_until(executor, lambda: driver.reader.state == LinkState.CONNECTED, 5.0)
            feed()
        ok = spin_until(executor, lambda: until(batches, driver), timeout_s)
        return ok, batches, driver.reader.state
    finally:
        if executor is not None:
            executor.shutdown()
        for node in (driver, probe):
            if node is not None:
                node.destroy_node()
        rclpy.try_shutdown(context=context)


def test_can_transport_events_out():
    from ext_sense_drivers.transports.can_bus import CanSink

    def feed():
        with CanSink("virtual", "t_node_can", 0x2A) as sink:
            sink.write(encode_words([1, 2, 40, 41, 80], [0, 1, 2, 3, 1023]))

    ok, batches, _ = _run_driver(
        [
            Parameter("transport", Parameter.Type.STRING, "can"),
            Parameter("can_interface", Parameter.Type.STRING, "virtual"),
            Parameter("can_channel", Parameter.Type.STRING, "t_node_can"),
            Parameter("can_arbitration_id", Parameter.Type.INTEGER, 0x2A),
        ],
        lambda b, _: len(_events(b)[0]) >= 5,
        feed=feed,
    )
    assert ok
    assert _events(batches) == ([1, 2, 40, 41, 80], [0, 1, 2, 3, 1023])


@pytest.mark.real_data
def test_file_transport_replays_a_lab_capture_flat_out(food_poking_dir):
    from ext_sense_drivers.nuskin.tact import decoded_path, read_tact

    raw = food_poking_dir / "banana_zero_0_raw.tact"
    if not raw.exists():
        raw = sorted(food_poking_dir.glob("*_raw.tact"))[0]
    tact = read_tact(decoded_path(raw))
    n = tact.taxel.shape[0]
    ok, batches, state = _run_driver(
        [
            Parameter("transport", Parameter.Type.STRING, "file"),
            Parameter("file_path", Parameter.Type.STRING, str(raw)),
            Parameter("file_pace", Parameter.Type.STRING, "flat"),
            Parameter("max_batch_events", Parameter.Type.INTEGER, 500),
        ],
        lambda b, d: len(_events(b)[0]) >= n and d.reader.state == LinkState.EXHAUSTED,
    )
    assert ok
    taxels, values = _events(batches)
    assert taxels[:n] == tact.taxel.tolist()
    assert values[:n] == tact.value.tolist()
    assert state == LinkState.EXHAUSTED
    assert max(len(b.taxel) for b in batches) <= 500


def test_aces_line_mode_over_a_pty(tmp_path):
    from ext_sense_drivers.aces.encoder import encode_line
    from ext_sense_drivers.aces.wire import samples_to_bytes

    taxel = [3, 44, 80]
    polarity = [1, -1, 1]
    line = encode_line([20_000, 300_000, 700_000], taxel, polarity, n_samples=20_000)
    data = samples_to_bytes(line.samples).data
    device = FakeDevice(tmp_path / "aces.pty")
    device.plug()
    try:
        ok, batches, _ = _run_driver(
            [
                Parameter("port", Parameter.Type.STRING, str(device.link)),
                Parameter("mode", Parameter.Type.STRING, "aces_line"),
            ],
            lambda b, _: len(_events(b)[0]) >= 3,
            feed=lambda: device.send(data),
        )
    finally:
        device.unplug()
    assert ok
    assert _events(batches)[0] == taxel
    assert [p for b in batches for p in b.polarity] == polarity


class _BrokenStream:
    """A decoding path with a bug: raises on every chunk."""

    def __init__(self, real):
        self.real = real
        self.batch_counters = real.batch_counters

    def feed(self, chunk):
        raise RuntimeError("decoder bug")

    def feed_flagged(self, chunk):
        raise RuntimeError("decoder bug")

    def restart(self):
        return self.real.restart()

    def diagnostics(self):
        return self.real.diagnostics()


def test_a_decoder_failure_costs_a_chunk_not_the_node():
    context = rclpy.Context()
    rclpy.init(context=context)
    driver = probe = executor = None
    batches = []
    try:
        driver = NuskinDriverNode(
            context=context,
            parameter_overrides=[Parameter("port", Parameter.Type.STRING, "loop://")],
        )
        probe = rclpy.create_node("probe", context=context)
        probe.create_subscription(TaxelEventBatch, "events", batches.append, SENSOR_STREAM_QOS)
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(driver)
        executor.add_node(probe)
        assert spin_until(executor, lambda: driver.reader.state == LinkState.CONNECTED, 5.0)
        real = driver.stream
        driver.stream = _BrokenStream(real)
        driver.reader.transport.write(encode_words([1], [1]))
        assert spin_until(executor, lambda: driver.decode_failures == 1, 5.0)
        driver.stream = real
        driver.reader.transport.write(encode_words([9, 10], [5, 6]))
        assert spin_until(executor, lambda: len(_events(batches)[0]) >= 2, 5.0)
        assert _events(batches) == ([9, 10], [5, 6])
        # frame_id is the one parameter that changes at run time, and never to empty.
        empty = Parameter("frame_id", Parameter.Type.STRING, "")
        assert not driver.set_parameters([empty])[0].successful
        assert driver.set_parameters([Parameter("frame_id", Parameter.Type.STRING, "left")])[
            0
        ].successful
        read_only = Parameter("baud", Parameter.Type.INTEGER, 9600)
        assert not driver.set_parameters([read_only])[0].successful
        driver.reader.transport.write(encode_words([11], [7]))
        assert spin_until(executor, lambda: batches[-1].taxel.tolist() == [11], 5.0)
        assert batches[-1].header.frame_id == "left"
    finally:
        if executor is not None:
            executor.shutdown()
        for node in (driver, probe):
            if node is not None:
                node.destroy_node()
        rclpy.try_shutdown(context=context)


def test_an_exception_in_a_driver_callback_is_caught_counted_and_diagnosed(graph):
    device, driver, executor, got = graph
    assert spin_until(executor, lambda: driver.reader.state == LinkState.CONNECTED, 5.0)
    real = driver._publish

    def broken(*args):
        raise RuntimeError("publisher bug")

    driver._publish = broken  # the drain timer's callback raises past the decoder's own try
    device.send(encode_words([4], [40]))
    assert spin_until(executor, lambda: driver.guard.total == 1, 5.0)
    assert "RuntimeError: publisher bug" in driver.guard.last_cause
    driver._diagnostics.publish()
    assert spin_until(executor, lambda: _diag_values(got, "callbacks")[0] is not None, 5.0)
    status, values = _diag_values(got, "callbacks")
    assert status.level == b"\x02"
    assert values["exceptions_total"] == "1"
    driver._publish = real  # the node lives on: the next words are published
    device.send(encode_words([5, 6], [50, 60]))
    assert spin_until(executor, lambda: _events(got["batches"])[0][-2:] == [5, 6], 5.0)


def test_shipped_parameter_file_is_accepted():
    config = Path(__file__).resolve().parents[2] / "config" / "nuskin_driver.yaml"
    context = rclpy.Context()
    rclpy.init(
        context=context, args=["--ros-args", "--params-file", str(config), "-p", "port:=loop://"]
    )
    driver = None
    try:
        driver = NuskinDriverNode(context=context)
        assert driver.config.baud == 4_000_000
        assert driver.config.can_arbitration_id == 0x100
        assert driver.max_batch_events == 20000
        assert driver.get_parameter("batch_period_s").value == 0.001
        assert driver.liveness.watches[0].expected_rate_hz == 540.0
        assert driver.liveness.watches[0].warn_ns == 200_000_000
    finally:
        if driver is not None:
            driver.destroy_node()
        rclpy.try_shutdown(context=context)


@pytest.mark.parametrize("graph", [{"quiet_packets_s": 0.0}], indirect=True)
def test_the_drain_timer_stops_while_the_link_is_silent_and_data_restarts_it(graph):
    """An idle driver does not tick every batch period (issue #16: idle cost); the reader
    thread restarts the drain with the next bytes, and no byte waits for a later chunk."""
    device, driver, executor, got = graph
    assert spin_until(executor, lambda: driver.reader.state == LinkState.CONNECTED, 5.0)
    assert spin_until(executor, lambda: driver._drain_timer.is_canceled(), 2.0)
    for burst, taxels in enumerate(([3, 4, 5], [7], [80, 1])):
        n_before = len(_events(got["batches"])[0])
        wanted = n_before + len(taxels)
        device.send(encode_words(taxels, [burst] * len(taxels)))
        assert spin_until(executor, lambda w=wanted: len(_events(got["batches"])[0]) >= w)
        assert _events(got["batches"])[0][n_before:] == taxels
        # the queue drained: the timer stops again until the next bytes
        assert spin_until(executor, lambda: driver._drain_timer.is_canceled(), 2.0)
        assert driver.reader.queued_chunks == 0


@pytest.mark.parametrize(
    "graph", [{"quiet_packets_s": 0.5, "quiet_packets_fast_s": 0.15}], indirect=True
)
def test_after_its_last_bytes_the_driver_says_it_read_nothing_then_goes_idle(graph):
    """For ``quiet_packets_s`` after the last bytes a timer publishes an empty packet (no reads,
    stamped when it looked) every ``batch_period_s`` for ``quiet_packets_fast_s``, then every
    ``quiet_packets_period_s``, so a window node closes its windows on data; then it stops
    (idle cost) until the next bytes."""
    from ext_sense_drivers.packets import QUIET_PACKETS_PERIOD_S, NuskinPacketDecoder, packet_of

    device, driver, executor, got = graph
    assert spin_until(executor, lambda: driver.reader.state == LinkState.CONNECTED, 5.0)
    assert spin_until(executor, lambda: driver._drain_timer.is_canceled(), 2.0)
    assert driver._quiet_timer.is_canceled()
    assert got["packets"] == []  # nothing read before any bytes: nothing said, not even the open
    device.send(encode_words([3, 4], [1, 2]))
    assert spin_until(executor, lambda: len(got["packets"]) > 1)
    assert spin_until(executor, lambda: driver._quiet_timer.is_canceled(), 3.0)
    opened, *packets = [packet_of(m) for m in got["packets"]]
    # first, with the first bytes' drain: the link opened then and read nothing before them
    assert (opened.seq, opened.connection, opened.data, opened.read_end.size) == (0, 1, b"", 0)
    assert opened.stamp_ns < packets[0].stamp_ns
    assert packets[0].data
    assert packets[0].seq == 1
    quiet = packets[1:]
    assert [p.seq for p in quiet] == list(range(2, len(packets) + 1))
    assert all(p.data == b"" and p.read_end.size == 0 for p in quiet)
    span_s = (quiet[-1].stamp_ns - packets[0].end_ns) / 1e9
    since_s = (np.array([p.stamp_ns for p in quiet]) - packets[0].end_ns) / 1e9
    fast, slow = quiet[: int(np.sum(since_s < 0.13))], quiet[int(np.sum(since_s < 0.17)) :]
    fast_ms, slow_ms = (np.diff([p.stamp_ns for p in part]) / 1e6 for part in (fast, slow))
    print(
        f"{len(quiet)} 'nothing read' packets over {span_s:.3f} s after the bytes, gaps p50 "
        f"{np.median(fast_ms):.2f} ms in the fast phase ({len(fast)}), "
        f"{np.median(slow_ms):.2f} ms after it ({len(slow)})"
    )
    assert 0.45 <= span_s <= 0.6
    assert len(fast) >= 0.13 / 0.001 / 3  # one per batch period (loaded: fewer)
    assert np.median(fast_ms) <= 2.0
    assert len(slow) >= 0.33 / QUIET_PACKETS_PERIOD_S / 2
    assert np.median(slow_ms) >= 0.8 * QUIET_PACKETS_PERIOD_S * 1e3
    decoder = NuskinPacketDecoder(packets[0].encoding, packets[0].options)
    assert decoder.decode(opened).complete_ns == opened.stamp_ns
    decoded = [decoder.decode(p) for p in packets]
    assert [d.events.size for d in decoded] == [2] + [0] * len(quiet)
    assert [d.complete_ns for d in decoded[1:]] == [p.stamp_ns for p in quiet]
    n = len(got["packets"])
    executor.spin_once(timeout_sec=0.3)
    assert len(got["packets"]) == n  # idle: nothing more until the next bytes
    device.send(encode_words([7], [3]))
    assert spin_until(executor, lambda: len(got["packets"]) > n)
    later = decoder.decode(packet_of(got["packets"][n]))
    assert later.events.taxel.tolist() == [7]
    assert later.complete_ns > quiet[-1].stamp_ns


def test_reader_priority_is_asked_for_and_reported_on_the_link_status(tmp_path):
    """``reader_priority`` reaches the reader thread, and ``/diagnostics`` says what the OS gave
    (SCHED_FIFO where CAP_SYS_NICE or an rtprio limit allows it, else the fallback and why)."""
    device = FakeDevice(tmp_path / "nuskin.pty")
    device.plug()
    caller = os.sched_getscheduler(0), os.sched_getparam(0)
    seen = []

    def scheduled(_batches, driver):
        seen.append(driver.reader.scheduling)
        return seen[-1] is not None

    try:
        ok, _, _ = _run_driver(
            [
                Parameter("port", Parameter.Type.STRING, str(device.link)),
                Parameter("reader_priority", Parameter.Type.INTEGER, 15),
            ],
            until=scheduled,
        )
        assert ok, "the reader thread never reported its scheduling"
        got = seen[-1]
        assert got.requested == 15
        line = got.describe()
        assert line == "SCHED_FIFO 15" if got.granted else "asked SCHED_FIFO 15" in line, line
    finally:
        # the thread that starts the reader is raised too (the node's executor): this test's
        os.sched_setscheduler(0, *caller)  # thread goes back to what it was
        device.unplug()


def test_reader_priority_shows_on_diagnostics(graph):
    _device, _driver, executor, got = graph
    assert spin_until(executor, lambda: _diag_values(got, "link")[0] is not None, 5.0)
    _, values = _diag_values(got, "link")
    assert values["reader_scheduling"] == "default scheduling (reader_priority 0: left as is)"
