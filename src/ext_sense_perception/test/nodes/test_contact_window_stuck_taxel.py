"""The window node fed a stuck taxel's bytes: no contact, WARN on /diagnostics naming it."""

from __future__ import annotations

import time

import numpy as np
import pytest

pytest.importorskip("rclpy")

from rosutil import spinning, wait_for

pytestmark = pytest.mark.ros

STUCK = 17
OPTIONS = "baud=4000000;flag_polarity=ignore"


class _Probe:
    """Publishes raw packets; collects windows and the window node's diagnostics."""

    def __init__(self, context) -> None:
        from diagnostic_msgs.msg import DiagnosticArray
        from rclpy.node import Node

        from ext_sense_msgs.msg import ContactWindow, SensorPacket
        from ext_sense_runtime.qos import DIAGNOSTICS_QOS, SENSOR_STREAM_QOS, WINDOW_QOS

        self.node = Node("probe", context=context)
        self.packets = self.node.create_publisher(SensorPacket, "packets", SENSOR_STREAM_QOS)
        self.windows: list = []
        self.statuses: list = []
        self.node.create_subscription(ContactWindow, "window", self.windows.append, WINDOW_QOS)
        self.node.create_subscription(
            DiagnosticArray,
            "/diagnostics",
            lambda m: self.statuses.extend(s for s in m.status if s.name.endswith(": taxels")),
            DIAGNOSTICS_QOS,
        )


def _stuck_packets(seconds: float, start_ns: int) -> list:
    """The receiver's words for one taxel at 4000 events/s, one packet per ms, nothing else."""
    from ext_sense_drivers.nodes.link_node import packet_message
    from ext_sense_drivers.nuskin.wire import encode_words
    from ext_sense_drivers.packets import NUSKIN_WORDS_V1, PacketPacker
    from ext_sense_drivers.transports.base import Chunk

    packer = PacketPacker(NUSKIN_WORDS_V1, OPTIONS)
    words = encode_words(np.full(4, STUCK), np.full(4, 512))  # 4 words per ms: 4000/s
    out = []
    for ms in range(int(seconds * 1000)):
        chunk = Chunk(words, start_ns + ms * 1_000_000)
        out += [packet_message(p, "nuskin") for p in packer.pack([(1, chunk)], link_down=False)]
    return out


def test_a_stuck_taxel_triggers_no_contact_and_is_reported_by_its_id():
    from rclpy.parameter import Parameter

    from ext_sense_perception.nodes.contact_window import ContactWindowNode

    probes: list[_Probe] = []

    def probe(context):
        probes.append(_Probe(context))
        return probes[-1].node

    params = [Parameter("task", value="tap_localization"), Parameter("model_path", value="/nx")]
    with spinning(
        lambda context: ContactWindowNode(context=context, parameter_overrides=params), probe
    ) as (node, _):
        p = probes[0]
        time.sleep(0.5)  # discovery
        packets = _stuck_packets(2.5, time.time_ns())
        t0 = time.monotonic()
        for i, msg in enumerate(packets):  # paced as the driver sends them
            p.packets.publish(msg)
            delay = t0 + (i + 1) * 1e-3 - time.monotonic()
            if delay > 0:
                time.sleep(delay)
        assert wait_for(lambda: any(s.level == b"\x01" for s in p.statuses), 10.0)
        warn = next(s for s in p.statuses if s.level == b"\x01")
        values = {kv.key: kv.value for kv in warn.values}
        time.sleep(0.3)  # any window would have closed by now
        assert p.windows == []
        assert node.stage.windower.counters.onsets == 0
        assert node.stage.windower.counters.one_taxel_bursts > 0
    assert warn.message.startswith(f"stuck taxel(s) {STUCK}: 4000 events/s for ")
    assert "masked from onset detection" in warn.message
    assert values["stuck_taxel_ids"] == str(STUCK)
    assert values["stuck_taxel_rate_events_per_s"] == "4000"
    assert float(values["stuck_for_s"]) >= 1.0
    assert values["stuck_threshold_events_per_s"] == "2000"
    assert int(values["masked_events"]) > 0
