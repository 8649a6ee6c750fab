"""Window, inference and recorder nodes in one process, with a stand-in model."""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np
import pytest
from rosutil import spinning, wait_for
from synthetic import MS, WORDS_OPTIONS, CountingModel, stream_packets, tap_stream

pytestmark = pytest.mark.ros


def _params(**kw):
    from rclpy.parameter import Parameter

    return [Parameter(k, value=v) for k, v in kw.items()]


def _json_loader(path, backend, *_):
    """Stand-in for the bundle loader: ``path/model.json`` must hold {"ok": true}."""
    from ext_sense_perception.errors import PerceptionError

    file = Path(path) / "model.json"
    if not file.is_file():
        raise PerceptionError(f"Model file {file} is missing.")
    try:
        ok = json.loads(file.read_text())["ok"]
    except (ValueError, KeyError) as err:
        raise PerceptionError(f"Model file {file} is corrupt: {err}") from err
    if not ok:
        raise PerceptionError(f"Model file {file} is corrupt.")
    return CountingModel()


class Probe:
    """A plain node publishing packets/windows and collecting estimates and diagnostics."""

    def __init__(self, context):
        from diagnostic_msgs.msg import DiagnosticArray
        from rclpy.node import Node

        from ext_sense_drivers.packets import NUSKIN_WORDS_V1, PacketPacker
        from ext_sense_msgs.msg import ContactEstimate, ContactWindow, SensorPacket
        from ext_sense_runtime.qos import (
            DIAGNOSTICS_QOS,
            ESTIMATE_QOS,
            SENSOR_STREAM_QOS,
            WINDOW_QOS,
        )

        self.node = Node("probe", context=context)
        self.packets = self.node.create_publisher(SensorPacket, "packets", SENSOR_STREAM_QOS)
        self.packer = PacketPacker(NUSKIN_WORDS_V1, WORDS_OPTIONS)
        """The driver's packer, one stream across every publish_batches."""
        self.windows = self.node.create_publisher(ContactWindow, "window", WINDOW_QOS)
        self.estimates = []
        """Estimates of both topics, as they came."""
        self.finals = []
        """What came on ``contact_estimate``: the final estimates alone."""
        self.diagnostics = []
        self.node.create_subscription(
            ContactEstimate, "contact_estimate", self._on_final, ESTIMATE_QOS
        )
        self.node.create_subscription(
            ContactEstimate, "contact_estimate/provisional", self.estimates.append, ESTIMATE_QOS
        )
        self.node.create_subscription(
            DiagnosticArray, "/diagnostics", self.diagnostics.append, DIAGNOSTICS_QOS
        )

    def _on_final(self, msg):
        self.finals.append(msg)
        self.estimates.append(msg)

    def end_stream(self):
        """The driver's last packet: the link went down, the stream ended."""
        from ext_sense_drivers.nodes.link_node import packet_message

        for packet in self.packer.pack([], link_down=True):
            self.packets.publish(packet_message(packet, "nuskin"))

    def status(self, name_part):
        for arr in reversed(self.diagnostics):
            for st in arr.status:
                if name_part in st.name:
                    return st
        return None

    def publish_batches(self, batches, base_ns, pace=True):
        """The batches as the driver's packets (one per ms), their time moved to ``base_ns``."""
        from ext_sense_drivers.nodes.link_node import packet_message

        moved = [b._replace(stamp_ns=base_ns + b.stamp_ns - batches[0].stamp_ns) for b in batches]
        t_start = time.monotonic()
        for i, packet in enumerate(stream_packets(moved, packer=self.packer)):
            self.packets.publish(packet_message(packet, "nuskin"))
            if pace:
                delay = t_start + (i + 1) * 1e-3 - time.monotonic()
                if delay > 0:
                    time.sleep(delay)


def _probe_factory(holder):
    def make(context):
        holder.append(Probe(context))
        return holder[-1].node

    return make


def test_window_and_inference_nodes_give_provisional_then_final(monkeypatch, tmp_path):
    from ext_sense_perception.nodes import contact_inference
    from ext_sense_perception.nodes.contact_inference import ContactInferenceNode
    from ext_sense_perception.nodes.contact_window import ContactWindowNode

    monkeypatch.setattr(contact_inference, "load_model", lambda p, b, *_: CountingModel())
    probes = []
    with spinning(
        lambda context: ContactWindowNode(context=context),
        lambda context: ContactInferenceNode(
            context=context, parameter_overrides=_params(model_path=str(tmp_path))
        ),
        _probe_factory(probes),
    ):
        probe = probes[0]
        time.sleep(0.5)  # discovery
        batches = tap_stream([50.0, 700.0], 1000.0, seed=1)
        probe.publish_batches(batches, time.time_ns())
        assert wait_for(lambda: sum(not e.provisional for e in probe.estimates) >= 2, 5.0)
        assert wait_for(lambda: probe.status("contact_inference: inference") is not None, 3.0)
    finals = [e for e in probe.estimates if not e.provisional]
    provisional = [e for e in probe.estimates if e.provisional]
    assert len(finals) == 2
    assert probe.finals == finals  # the final estimates alone on contact_estimate
    assert len(provisional) == 8  # 25, 50, 100, 150 ms for each tap, on their own topic
    assert [e.post_contact_used.nanosec // MS for e in provisional[:4]] == [25, 50, 100, 150]
    assert all(e.model_id == "counting-test-model" for e in finals)
    assert all(e.tap_position_m > 0 for e in finals)
    latency_ms = [e.compute_latency.sec * 1e3 + e.compute_latency.nanosec / 1e6 for e in finals]
    assert all(0 <= x < 1000 for x in latency_ms)


def test_inference_faults_keep_the_node_alive_and_recording_complete(monkeypatch, tmp_path):
    from ext_sense.nodes.recorder import RecorderNode
    from ext_sense_bags import BagReader
    from ext_sense_msgs.msg import ContactWindow
    from ext_sense_perception.nodes import contact_inference
    from ext_sense_perception.nodes.contact_inference import ContactInferenceNode
    from ext_sense_runtime.stamps import fill_stamp

    monkeypatch.setattr(contact_inference, "load_model", _json_loader)
    model_dir = tmp_path / "model"
    model_dir.mkdir()
    bag = tmp_path / "bag"
    probes = []

    def window(values, post_ms=250):
        msg = ContactWindow()
        fill_stamp(msg.header.stamp, time.time_ns() - (post_ms + 1) * MS)
        msg.task, msg.sensor = "tap_localization", "nuskin"
        msg.pre_onset_ns, msg.post_onset_ns, msg.sample_period_ns = 50 * MS, post_ms * MS, MS
        msg.shape = [2, 3]
        msg.channels = [1, 2]
        msg.data = np.asarray(values, dtype=np.float32)
        msg.provisional = post_ms < 250  # an anytime window, as the window node marks it
        return msg

    with spinning(
        lambda context: ContactInferenceNode(
            context=context,
            parameter_overrides=_params(model_path=str(model_dir), reload_period_s=0.2),
        ),
        lambda context: RecorderNode(
            context=context, parameter_overrides=_params(bag=str(bag), topics=["/window"])
        ),
        _probe_factory(probes),
    ) as (inference, recorder, _):
        probe = probes[0]
        assert wait_for(lambda: "/window" in recorder.received, 5.0)  # type discovered
        time.sleep(0.3)
        # missing model: windows are dropped and counted, diagnostics say why
        probe.windows.publish(window([1, 2, 3, 4, 5, 6]))
        assert wait_for(lambda: inference.dropped_no_model == 1, 3.0)
        assert wait_for(lambda: probe.status("contact_inference: model") is not None)
        st = probe.status("contact_inference: model")
        assert st.level == b"\x02"
        assert "missing" in st.message
        # corrupt model: still an error, still alive
        (model_dir / "model.json").write_text("{not json")
        probe.windows.publish(window([1, 2, 3, 4, 5, 6]))
        assert wait_for(lambda: inference.dropped_no_model == 2, 3.0)
        assert wait_for(lambda: "corrupt" in inference.model_error, 3.0)
        # fixed model file: loading is retried and estimates flow
        (model_dir / "model.json").write_text('{"ok": true}')
        assert wait_for(lambda: inference.model is not None, 3.0)
        probe.windows.publish(window([1, 2, 3, 4, 5, 6]))
        assert wait_for(lambda: len(probe.estimates) == 1, 3.0)
        # NaN in a window: rejected, counted, reported; the next window is fine
        probe.windows.publish(window([1, np.nan, 3, 4, 5, 6]))
        assert wait_for(lambda: inference.dropped_bad_window == 1, 3.0)
        assert wait_for(
            lambda: (
                (s := probe.status("contact_inference: inference")) is not None
                and s.level == b"\x01"
                and "NaN" in s.message
            ),
            3.0,
        )
        probe.windows.publish(window([1, 1, 1, 1, 1, 1], post_ms=100))
        assert wait_for(lambda: len(probe.estimates) == 2, 3.0)
        assert probe.estimates[-1].provisional
        assert wait_for(lambda: recorder.received.get("/window") == 5, 3.0)
    with BagReader(bag) as reader:
        assert reader.topics["/window"].count == 5
        assert reader.topics["/window"].msgtype == "ext_sense_msgs/msg/ContactWindow"


class _BrokenOnceModel(CountingModel):
    """A model whose first prediction raises an unexpected error (not a PerceptionError)."""

    def __init__(self) -> None:
        super().__init__()
        self.calls = 0

    def predict(self, window):
        self.calls += 1
        if self.calls == 1:
            raise TypeError("class_names is not a list")
        return super().predict(window)


def test_an_exception_in_a_callback_is_caught_counted_and_diagnosed(monkeypatch, tmp_path):
    from ext_sense_msgs.msg import ContactWindow
    from ext_sense_perception.nodes import contact_inference
    from ext_sense_perception.nodes.contact_inference import ContactInferenceNode
    from ext_sense_runtime.stamps import fill_stamp

    monkeypatch.setattr(contact_inference, "load_model", lambda p, b, *_: _BrokenOnceModel())
    probes = []

    def window():
        msg = ContactWindow()
        fill_stamp(msg.header.stamp, time.time_ns() - 251 * MS)
        msg.task, msg.sensor = "tap_localization", "nuskin"
        msg.pre_onset_ns, msg.post_onset_ns, msg.sample_period_ns = 50 * MS, 250 * MS, MS
        msg.shape, msg.channels = [2, 3], [1, 2]
        msg.data = np.ones(6, dtype=np.float32)
        return msg

    with spinning(
        lambda context: ContactInferenceNode(
            context=context, parameter_overrides=_params(model_path=str(tmp_path))
        ),
        _probe_factory(probes),
    ) as (inference, _):
        probe = probes[0]
        time.sleep(0.5)  # discovery
        probe.windows.publish(window())
        assert wait_for(lambda: inference.guard.total == 1, 3.0)
        probe.windows.publish(window())  # the node goes on: the next window is estimated
        assert wait_for(lambda: len(probe.estimates) == 1, 3.0)
        assert wait_for(
            lambda: (
                (s := probe.status("contact_inference: callbacks")) is not None
                and s.level == b"\x02"
            ),
            3.0,
        )
        st = probe.status("contact_inference: callbacks")
        assert "_on_window: TypeError: class_names is not a list" in st.message
        assert dict((kv.key, kv.value) for kv in st.values)["exceptions__on_window"] == "1"


def test_a_stall_mid_contact_is_diagnosed_within_a_second_and_degrades_the_window(
    monkeypatch, tmp_path
):
    """The packets stop 50 ms into a tap (as a driver under ``kill -STOP``), then return."""
    from ext_sense_msgs.msg import ContactWindow
    from ext_sense_perception.nodes import contact_inference
    from ext_sense_perception.nodes.contact_inference import ContactInferenceNode
    from ext_sense_perception.nodes.contact_window import ContactWindowNode
    from ext_sense_runtime.qos import WINDOW_QOS

    monkeypatch.setattr(contact_inference, "load_model", lambda p, b, *_: CountingModel())
    probes = []
    windows: list = []
    with spinning(
        lambda context: ContactWindowNode(context=context),
        lambda context: ContactInferenceNode(
            context=context, parameter_overrides=_params(model_path=str(tmp_path))
        ),
        _probe_factory(probes),
    ) as (window_node, _, _):
        probe = probes[0]
        probe.node.create_subscription(ContactWindow, "window", windows.append, WINDOW_QOS)
        time.sleep(0.5)  # discovery
        batches = tap_stream([100.0], 1000.0, seed=2)
        base = time.time_ns()
        probe.publish_batches(batches[:150], base)  # stops 50 ms after the onset
        stalled_at = time.monotonic()
        seen: dict[int, float] = {}

        def liveness_level():
            st = probe.status("contact_window: liveness")
            if st is not None and st.level[0] not in seen:
                seen[st.level[0]] = time.monotonic() - stalled_at
            return st

        assert wait_for(lambda: (liveness_level(), 2 in seen)[1], 2.0, step=0.005)
        st = probe.status("contact_window: liveness")
        assert st.message.startswith("stall: no input on /packets for ")
        assert 1 in seen  # WARN first
        print(f"stall: WARN after {seen[1]:.3f} s, ERROR after {seen[2]:.3f} s")
        assert seen[1] < seen[2] < 1.0  # ERROR within a second of the stall
        values = {kv.key: kv.value for kv in st.values}
        assert values["stream"] == "/packets"
        # no clock closes the window: it waits for the stream to pass its end
        assert not any(not e.provisional for e in probe.estimates)
        early = [e for e in probe.estimates if e.provisional and e.post_contact_used.nanosec < 40e6]
        assert early
        # cut before the stall (failed once in make test, 24 November 2026, reason not kept)
        assert not any(e.degraded for e in early), [e.degraded_reason for e in early]
        # data returns: the window closes on it, degraded, and the status clears
        probe.publish_batches(batches[150:400], base + 1500 * MS)
        probe.end_stream()  # else its silence after them is the next stall
        assert wait_for(lambda: any(not e.provisional for e in probe.estimates), 2.0)
        finals = [e for e in probe.estimates if not e.provisional]
        assert len(finals) == 1
        assert finals[0].degraded
        assert finals[0].degraded_reason.startswith("stall: no input on /packets")
        assert window_node.liveness.contacts_degraded == 1  # its estimate came, degraded
        assert window_node.liveness.contacts_lost == 0

        def cleared():
            st = probe.status("contact_window: liveness")
            values = {} if st is None else {kv.key: kv.value for kv in st.values}
            return st.level == b"\x00" and values["contacts_degraded"] == "1"

        assert wait_for(cleared, 3.0)  # the next status, 1 Hz
    final_windows = [w for w in windows if not w.provisional]
    assert [w.degraded for w in final_windows] == [True]


def test_an_estimate_later_than_the_deadline_is_degraded(monkeypatch, tmp_path):
    from ext_sense_msgs.msg import ContactWindow
    from ext_sense_perception.nodes import contact_inference
    from ext_sense_perception.nodes.contact_inference import ContactInferenceNode
    from ext_sense_runtime.stamps import fill_stamp

    monkeypatch.setattr(contact_inference, "load_model", lambda p, b, *_: CountingModel())
    probes = []

    def window(ended_ms_ago):
        msg = ContactWindow()
        fill_stamp(msg.header.stamp, time.time_ns() - (250 + ended_ms_ago) * MS)
        msg.task, msg.sensor = "tap_localization", "nuskin"
        msg.pre_onset_ns, msg.post_onset_ns, msg.sample_period_ns = 50 * MS, 250 * MS, MS
        msg.shape, msg.channels = [2, 3], [1, 2]
        msg.data = np.ones(6, dtype=np.float32)
        return msg

    with spinning(
        lambda context: ContactInferenceNode(
            context=context,
            parameter_overrides=_params(model_path=str(tmp_path), deadline_ms=300.0),
        ),
        _probe_factory(probes),
    ) as (inference, _):
        probe = probes[0]
        time.sleep(0.5)  # discovery
        probe.windows.publish(window(1))
        probe.windows.publish(window(2000))  # its window ended 2 s ago: a stalled node's
        assert wait_for(lambda: len(probe.estimates) == 2, 3.0)
        assert wait_for(
            lambda: (
                (s := probe.status("contact_inference: inference")) is not None
                and s.level == b"\x01"
            ),
            3.0,
        )
    on_time, late = probe.estimates
    assert not on_time.degraded
    assert on_time.degraded_reason == ""
    assert late.degraded
    assert late.degraded_reason.startswith("late: ready 20")
    assert late.degraded_reason.endswith("ms after the window ended (deadline 300 ms)")
    assert inference.degraded_out == 1


def test_the_drivers_quiet_packets_close_the_window_and_an_ended_stream_stops_the_timer():
    """Windows close on data: the events stop 60 ms after the onset and the driver's "nothing
    read" packets carry the stream past the window's end. The node's one timer is for stalls
    of a stream that goes; once it ended the node arms none (issue #16: idle cost)."""
    from ext_sense_msgs.msg import ContactWindow
    from ext_sense_perception.nodes.contact_window import ContactWindowNode
    from ext_sense_runtime.qos import WINDOW_QOS

    probes = []
    windows: list = []
    with spinning(
        lambda context: ContactWindowNode(context=context),
        _probe_factory(probes),
    ) as (
        window_node,
        _,
    ):
        probe = probes[0]
        probe.node.create_subscription(ContactWindow, "window", windows.append, WINDOW_QOS)
        time.sleep(0.5)  # discovery
        assert window_node._armed_ns is None  # nothing arrived: nothing to wait for
        batches = tap_stream([100.0], 370.0, noise_per_s=0.0, seed=3)
        probe.publish_batches(batches, time.time_ns())
        assert wait_for(lambda: any(not w.provisional for w in windows), 3.0)
        final = [w for w in windows if not w.provisional]
        assert len(final) == 1
        assert not final[0].truncated  # closed at its end, by the packets past it
        assert not final[0].degraded
        assert [w.post_onset_ns // MS for w in windows] == [25, 50, 100, 150, 250]
        probe.end_stream()
        assert wait_for(lambda: window_node._armed_ns is None, 2.0)
        assert window_node._stall_timer.is_canceled()
        woken = window_node.wakeups
        time.sleep(0.5)
        assert window_node.wakeups == woken  # idle: no timer callbacks at all
