"""Late packets: a window holding them is complete (not degraded), and no clock of the node's
closes a window before them: the node cuts the windows an offline stage cuts from the same
packets."""

from __future__ import annotations

import time

import numpy as np
import pytest

pytest.importorskip("rclpy")

from rosutil import spinning, wait_for

pytestmark = pytest.mark.ros

OPTIONS = "baud=4000000;flag_polarity=ignore"
MS = 1_000_000


class _Probe:
    def __init__(self, context) -> None:
        from rclpy.node import Node

        from ext_sense_msgs.msg import ContactWindow, SensorPacket
        from ext_sense_runtime.qos import SENSOR_STREAM_QOS, WINDOW_QOS

        self.node = Node("probe", context=context)
        self.packets = self.node.create_publisher(SensorPacket, "packets", SENSOR_STREAM_QOS)
        self.windows: list = []
        self.node.create_subscription(ContactWindow, "window", self.windows.append, WINDOW_QOS)


def _packets(base_ns: int, onsets_ms: tuple[int, ...], end_ms: int) -> list:
    """A packet per ms: a word of noise, and 60 words over 40 taxels for 30 ms at each onset."""
    from ext_sense_drivers.nodes.link_node import packet_message
    from ext_sense_drivers.nuskin.wire import encode_words
    from ext_sense_drivers.packets import NUSKIN_WORDS_V1, PacketPacker
    from ext_sense_drivers.transports.base import Chunk

    rng = np.random.default_rng(4)
    packer = PacketPacker(NUSKIN_WORDS_V1, OPTIONS)
    out = []
    for ms in range(end_ms):
        n = 60 if any(0 <= ms - o < 30 for o in onsets_ms) else 1
        data = encode_words(rng.integers(1, 41, n), rng.integers(0, 1024, n))
        chunk = Chunk(data, base_ns + ms * MS)
        out += [packet_message(p, "nuskin") for p in packer.pack([(1, chunk)], link_down=False)]
    return out


def _send(probe: _Probe, packets: list, paced: bool = True) -> None:
    t0 = time.monotonic()
    for i, msg in enumerate(packets):
        probe.packets.publish(msg)
        delay = t0 + (i + 1) * 1e-3 - time.monotonic()
        if paced and delay > 0:
            time.sleep(delay)


def test_late_packets_leave_a_window_whole_and_the_node_cuts_what_a_replay_cuts():
    from rclpy.parameter import Parameter

    from ext_sense_perception.nodes.contact_window import ContactWindowNode
    from ext_sense_perception.online.messages import window_fields
    from ext_sense_perception.online.stage import WindowStage
    from ext_sense_runtime.stamps import stamp_to_ns

    probes: list[_Probe] = []

    def probe(context):
        probes.append(_Probe(context))
        return probes[-1].node

    params = [
        Parameter("task", value="tap_localization"),
        Parameter("model_path", value="/nx"),
        Parameter("late_ms", value=20.0),
        # a stall only past 500 ms: a loaded machine's pauses in the sending are no stall here
        Parameter("stall_warn_ms", value=500.0),
        Parameter("stall_error_ms", value=1000.0),
    ]
    with spinning(
        lambda context: ContactWindowNode(context=context, parameter_overrides=params), probe
    ) as (node, _):
        p = probes[0]
        time.sleep(0.5)  # discovery
        packets = _packets(time.time_ns(), (100, 1000), 1400)
        # tap 1: the packets of 200-260 ms held back 60 ms (no stall), then
        # the backlog at once: late, but the window closes on data and holds them all
        _send(p, packets[:200])
        time.sleep(0.06)
        _send(p, packets[200:260], paced=False)
        _send(p, packets[260:1240])
        # tap 2: nothing past 1240 ms for 200 ms: its window (ends 1250 ms) waits for the
        # packets, whatever the node's clock says; then the packets read before its end come
        assert wait_for(lambda: sum(not w.provisional for w in p.windows) == 1, 3.0)
        time.sleep(0.2)
        assert sum(not w.provisional for w in p.windows) == 1
        _send(p, packets[1240:], paced=False)
        assert wait_for(lambda: sum(not w.provisional for w in p.windows) == 2, 5.0)
        late = node.liveness.late_packets
        gaps = node.liveness.packets_lost  # a loaded machine may drop a best-effort packet
        config = node.config
    finals = [w for w in p.windows if not w.provisional]
    reasons = [w.degraded_reason for w in finals]
    assert late > 0
    assert len(finals) == 2
    # complete windows: nothing but a dropped packet (its seq gap) may degrade them
    assert all(not w.degraded or "(seq gap)" in w.degraded_reason for w in finals), reasons
    assert gaps or not any(w.degraded for w in finals), reasons
    if not gaps:  # every packet reached the node: a replay of them cuts the very same windows
        stage = WindowStage(config)
        offline = [w for m in packets for w in stage.on_packet(m) if not w.provisional]
        assert [window_fields(w)["stamp_ns"] for w in offline] == [
            stamp_to_ns(w.header.stamp) for w in finals
        ]
        for live, again in zip(finals, offline, strict=True):
            assert np.asarray(live.data).tolist() == window_fields(again)["data"].tolist()
