"""The NUSkin driver node over a pty: bytes in, packets out, diagnostics, port lost and back.

The packets are decoded here with the library decoder every consumer uses."""

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
from ext_sense_drivers.packets import NuskinPacketDecoder, packet_of  # noqa: E402
from ext_sense_drivers.transports.base import LinkState  # noqa: E402
from ext_sense_msgs.msg import SensorPacket  # noqa: E402
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
    got = {"diag": [], "packets": []}
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


class _Decoded:
    """The events of a list of received packets, decoded as they come (one decoder per list).

    Each entry keeps its list: an id alone can be reused by a later test's list once the
    earlier one is collected, which handed the new list another stream's decoder.
    """

    def __init__(self):
        self._seen = {}

    def __call__(self, packets):
        kept, decoder, blocks = self._seen.get(id(packets), (None, None, []))
        if kept is not packets:
            decoder, blocks = None, []
        for msg in packets[len(blocks) :]:
            packet = packet_of(msg)
            if decoder is None:
                decoder = NuskinPacketDecoder(packet.encoding, packet.options)
            blocks.append(decoder.decode(packet))
        self._seen[id(packets)] = (packets, decoder, blocks)
        return decoder, blocks


_decoded = _Decoded()


def _events(packets):
    """``(taxels, values)`` of every event in the packets, in order."""
    _, blocks = _decoded(packets)
    taxel = [t for b in blocks for t in b.events.taxel.tolist()]
    value = [v for b in blocks for v in b.events.value.tolist()]
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
    assert spin_until(executor, lambda: len(_events(got["packets"])[0]) >= 299)
    taxels, values = _events(got["packets"])
    assert taxels == taxel[1:].tolist()
    assert values == value[1:].tolist()
    assert got["packets"][-1].header.frame_id == "nuskin_test"
    decoder, blocks = _decoded(got["packets"])
    counters = decoder.stream.batch_counters
    assert (counters.words_total, counters.resyncs, counters.skipped_bytes) == (299, 2, 2 + 3)
    times = np.concatenate([b.events.t_ns for b in blocks])
    assert (np.diff(times) >= 0).all()
    stamps = [stamp_to_ns(m.header.stamp) for m in got["packets"]]
    assert stamps == sorted(stamps)

    # Diagnostics name the port state and the rate.
    assert spin_until(
        executor, lambda: _diag_values(got, "link")[1].get("port_state") == "connected", 5.0
    )
    status, link = _diag_values(got, "link")
    assert link["port_state"] == "connected"
    assert status.hardware_id == str(device.link)
    assert spin_until(executor, lambda: "rate_words_per_s" in _diag_values(got, "words")[1], 5.0)

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
    n_before = len(_events(got["packets"])[0])
    device.send(encode_words([5, 80, 41], [1, 2, 3]))
    assert spin_until(executor, lambda: len(_events(got["packets"])[0]) >= n_before + 3)
    assert _events(got["packets"])[0][n_before:] == [5, 80, 41]
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
    """Spin a driver and a probe until ``until(packets, driver)``; returns (ok, packets, state)."""
    context = rclpy.Context()
    rclpy.init(context=context)
    driver = probe = executor = None
    batches = []
    try:
        driver = NuskinDriverNode(context=context, parameter_overrides=overrides)
        probe = rclpy.create_node("probe", context=context)
        probe.create_subscription(SensorPacket, "packets", batches.append, SENSOR_STREAM_QOS)
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
        ],
        lambda b, d: len(_events(b)[0]) >= n and d.reader.state == LinkState.EXHAUSTED,
    )
    assert ok
    taxels, values = _events(batches)
    assert taxels[:n] == tact.taxel.tolist()
    assert values[:n] == tact.value.tolist()
    assert state == LinkState.EXHAUSTED


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
    _, blocks = _decoded(batches)
    assert [p for b in blocks for p in b.events.polarity.tolist()] == polarity


def test_frame_id_changes_at_run_time_and_never_to_empty():
    context = rclpy.Context()
    rclpy.init(context=context)
    driver = probe = executor = None
    packets = []
    try:
        driver = NuskinDriverNode(
            context=context,
            parameter_overrides=[Parameter("port", Parameter.Type.STRING, "loop://")],
        )
        probe = rclpy.create_node("probe", context=context)
        probe.create_subscription(SensorPacket, "packets", packets.append, SENSOR_STREAM_QOS)
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(driver)
        executor.add_node(probe)
        assert spin_until(executor, lambda: driver.reader.state == LinkState.CONNECTED, 5.0)
        empty = Parameter("frame_id", Parameter.Type.STRING, "")
        assert not driver.set_parameters([empty])[0].successful
        assert driver.set_parameters([Parameter("frame_id", Parameter.Type.STRING, "left")])[
            0
        ].successful
        read_only = Parameter("baud", Parameter.Type.INTEGER, 9600)
        assert not driver.set_parameters([read_only])[0].successful
        driver.reader.transport.write(encode_words([11], [7]))
        assert spin_until(executor, lambda: _events(packets)[0] == [11], 5.0)
        assert packets[-1].header.frame_id == "left"
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
    real = driver._publish_packet

    def broken(*args):
        raise RuntimeError("publisher bug")

    driver._publish_packet = broken  # the drain timer's callback raises
    device.send(encode_words([4], [40]))
    assert spin_until(executor, lambda: driver.guard.total == 1, 5.0)
    assert "RuntimeError: publisher bug" in driver.guard.last_cause
    driver._diagnostics.publish()
    assert spin_until(executor, lambda: _diag_values(got, "callbacks")[0] is not None, 5.0)
    status, values = _diag_values(got, "callbacks")
    assert status.level == b"\x02"
    assert values["exceptions_total"] == "1"
    driver._publish_packet = real  # the node lives on: the next words are published
    device.send(encode_words([5, 6], [50, 60]))
    assert spin_until(executor, lambda: _events(got["packets"])[0][-2:] == [5, 6], 5.0)


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
        assert driver.get_parameter("quiet_packets_period_s").value == 0.002
        assert driver.get_parameter("batch_period_s").value == 0.001
        assert driver.liveness.watches[0].expected_rate_hz == 540.0
        assert driver.liveness.watches[0].warn_ns == 200_000_000
    finally:
        if driver is not None:
            driver.destroy_node()
        rclpy.try_shutdown(context=context)


@pytest.mark.parametrize("graph", [{"quiet_packets_period_s": 0.0}], indirect=True)
def test_the_drain_timer_stops_while_the_link_is_silent_and_data_restarts_it(graph):
    """An idle driver does not tick every batch period (issue #16: idle cost); the reader
    thread restarts the drain with the next bytes, and no byte waits for a later chunk."""
    device, driver, executor, got = graph
    assert spin_until(executor, lambda: driver.reader.state == LinkState.CONNECTED, 5.0)
    assert spin_until(executor, lambda: driver._drain_timer.is_canceled(), 2.0)
    for burst, taxels in enumerate(([3, 4, 5], [7], [80, 1])):
        n_before = len(_events(got["packets"])[0])
        wanted = n_before + len(taxels)
        device.send(encode_words(taxels, [burst] * len(taxels)))
        assert spin_until(executor, lambda w=wanted: len(_events(got["packets"])[0]) >= w)
        assert _events(got["packets"])[0][n_before:] == taxels
        # the queue drained: the timer stops again until the next bytes
        assert spin_until(executor, lambda: driver._drain_timer.is_canceled(), 2.0)
        assert driver.reader.queued_chunks == 0


@pytest.mark.parametrize("graph", [{"quiet_packets_period_s": 0.005}], indirect=True)
def test_while_the_sensor_is_silent_the_driver_says_it_read_nothing_on_its_own_cadence(graph):
    """After bytes, a timer publishes an empty packet (no reads, stamped when it looked) every
    ``quiet_packets_period_s`` while no bytes come, for as long as the stream goes: a cadence
    of the driver's own, so a window node closes its windows on data. Nothing is said before
    the first bytes, nor after the link went down (the stream ended)."""
    device, driver, executor, got = graph
    assert spin_until(executor, lambda: driver.reader.state == LinkState.CONNECTED, 5.0)
    assert spin_until(executor, lambda: driver._drain_timer.is_canceled(), 2.0)
    assert driver._quiet_timer.is_canceled()
    executor.spin_once(timeout_sec=0.05)
    assert got["packets"] == []  # nothing read before any bytes: nothing said, not even the open
    device.send(encode_words([3, 4], [1, 2]))
    assert spin_until(executor, lambda: len(got["packets"]) > 60, 5.0)  # 0.3 s of silence
    opened, *packets = [packet_of(m) for m in got["packets"]]
    # first, with the first bytes' drain: the link opened then and read nothing before them
    assert (opened.seq, opened.connection, opened.data, opened.read_end.size) == (0, 1, b"", 0)
    assert opened.stamp_ns < packets[0].stamp_ns
    assert packets[0].data
    assert packets[0].seq == 1
    quiet = packets[1:]
    assert [p.seq for p in quiet] == list(range(2, len(packets) + 1))
    assert all(p.data == b"" and p.read_end.size == 0 for p in quiet)
    gaps_ms = np.diff([p.stamp_ns for p in quiet]) / 1e6
    print(f"{len(quiet)} 'nothing read' packets, gaps p50 {np.median(gaps_ms):.2f} ms")
    assert 4.0 <= np.median(gaps_ms) <= 7.0  # the fixed cadence (loaded: a little late)
    decoder = NuskinPacketDecoder(packets[0].encoding, packets[0].options)
    assert decoder.decode(opened).complete_ns == opened.stamp_ns
    decoded = [decoder.decode(p) for p in packets]
    assert [d.events.size for d in decoded] == [2] + [0] * len(quiet)
    assert [d.complete_ns for d in decoded[1:]] == [p.stamp_ns for p in quiet]
    device.send(encode_words([7], [3]))
    assert spin_until(executor, lambda: 7 in _events(got["packets"])[0], 5.0)
    # the link goes down: its stream ends, and the driver stops saying anything
    device.unplug()
    assert spin_until(executor, lambda: got["packets"][-1].end_of_stream, 5.0)
    assert spin_until(executor, lambda: driver._quiet_timer.is_canceled(), 2.0)
    n = len(got["packets"])
    executor.spin_once(timeout_sec=0.1)
    assert len(got["packets"]) == n


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
