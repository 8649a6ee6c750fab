"""The tap graph with ``view:=true``: a Foxglove protocol client sees and decodes every channel,
and the display rate stays bounded while all 80 taxels fire at 4 kHz (issue 19's Show); the
handover graph on the BioTac: its electrode grid and PAC panels on a running graph.

Both graphs are the defaults: the drivers publish raw packets only, so the view draws the
sensor from the packets it decodes itself.
"""

from __future__ import annotations

import signal
import threading
import time
from collections import Counter

import numpy as np
import pytest
from foxglove_client import FoxgloveClient, free_port
from rosutil import spinning, wait_for
from sim_models import Graph, stop_problems, train_sim_model
from synthetic import tap_stream

pytestmark = [pytest.mark.ros, pytest.mark.slow]

RATE_HZ = 15.0
LOAD_S = 4.0
"""The flood is held this long after the view first counted half of it, s."""
FULL = 80 * 4000
"""Every taxel at 4 kHz, events/s."""


@pytest.fixture(scope="module")
def tap_model(tmp_path_factory):
    model, _ = train_sim_model(
        tmp_path_factory.mktemp("view_model"), "tap_rod30_nuskin", "tap_localization", 16
    )
    return model


PACKET_MS = 5
FLOOD_CONNECTION = 1000
"""The flood's link connection: not the driver's (1, 2, ...), so the view decodes the two
packet streams on the topic apart (ext_sense.view.feed) and neither breaks the other's."""


def _flood(stop: threading.Event, sent: list[int]) -> None:
    """Every taxel at 4 kHz as raw packets on /extsense/nuskin/packets, where the driver's
    packets go and the view reads: 5 ms packets of receiver words, paced by the wall clock.

    5 ms, not 1 ms: a 1 ms publisher fell 2 % behind 4 kHz on a loaded CI machine (314k of
    320k events/s), which left the taxels just under the view's saturation rate."""
    from ext_sense_drivers.nodes.link_node import packet_message
    from ext_sense_drivers.nuskin.wire import encode_words
    from ext_sense_drivers.packets import NUSKIN_WORDS_V1, PacketPacker
    from ext_sense_drivers.transports.base import Chunk
    from ext_sense_msgs.msg import SensorPacket
    from ext_sense_runtime.qos import SENSOR_STREAM_QOS

    def source(**kw):
        from rclpy.node import Node

        return Node("view_flood", **kw)

    batches = tap_stream([0.0], 100, taxels=80, burst_ms=100, noise_per_s=0)  # 100 x 320 events
    per_ms = [(encode_words(b.taxel, b.value), b.taxel.size) for b in batches]
    words = [
        (
            b"".join(w for w, _ in per_ms[i : i + PACKET_MS]),
            sum(n for _, n in per_ms[i : i + PACKET_MS]),
        )
        for i in range(0, len(per_ms), PACKET_MS)
    ]
    packer = PacketPacker(NUSKIN_WORDS_V1, "baud=4000000;flag_polarity=ignore")
    with spinning(source) as (node,):
        pub = node.create_publisher(SensorPacket, "/extsense/nuskin/packets", SENSOR_STREAM_QOS)
        start = time.monotonic()
        k = 0
        while not stop.is_set():
            due = int((time.monotonic() - start) * 1000) // PACKET_MS
            while k < due:
                data, n = words[k % len(words)]
                chunk = Chunk(data, time.time_ns())
                [packet] = packer.pack([(FLOOD_CONNECTION, chunk)], link_down=False)
                pub.publish(packet_message(packet, "nuskin"))
                sent[0] += n
                k += 1
            time.sleep(0.001)


@pytest.mark.timeout(300)
def test_view_serves_every_channel_and_holds_its_rate_under_a_full_flood(tap_model, tmp_path):
    from ext_sense.view import channels as ch

    port = free_port()
    graph = Graph(
        "trials:=0",
        f"model:={tap_model}",
        f"port:={tmp_path / 'nuskin.pty'}",
        "view:=true",
        f"view_port:={port}",
        f"view_rate:={RATE_HZ:g}",
    )
    client = None
    try:
        client = FoxgloveClient(f"ws://127.0.0.1:{port}", connect_timeout_s=60)
        wanted = set(ch.view_channels("nuskin"))
        assert wait_for(lambda: wanted <= set(client.topics()), timeout=30), client.topics()

        def missing() -> set[str]:
            return wanted - {m.topic for m in client.messages()}

        ok = wait_for(lambda: not missing(), timeout=90, step=0.2)
        if not ok:
            print(Counter(m.topic for m in client.messages()))
            print(client.topics())
        assert ok, (
            f"no message on {sorted(missing())}",
            Counter(m.topic for m in client.messages()),
            client.statuses,
            "".join(graph.out)[-1500:],
            "".join(graph.err)[-3000:],
        )
        first = {}
        for m in client.messages():
            first.setdefault(m.topic, m)
        decoded = {topic: client.decode(m) for topic, m in first.items()}
        assert decoded[ch.TAXELS].encoding == "rgb8"
        assert decoded["/extsense/contact_estimate"].task == "tap_localization"
        assert decoded[ch.ESTIMATE_INFO]["task"] == "tap_localization"

        stop, sent = threading.Event(), [0]
        flood = threading.Thread(target=_flood, args=(stop, sent), daemon=True)
        t0 = time.monotonic()
        flood.start()

        def flood_seen() -> float | None:  # when the view first counted half the flood
            for m in client.messages(ch.RATES):
                if m.arrival_s >= t0 and client.decode(m)["total_events_per_s"] > 0.5 * FULL:
                    return m.arrival_s
            return None

        assert wait_for(lambda: flood_seen() is not None, 30.0, step=0.1)
        # the rates are smoothed over 0.5 s and saturation is 95 % of 4 kHz: hold the flood
        # long enough past the moment it was seen for every taxel's rate to settle above it
        time.sleep(max(0.0, flood_seen() + LOAD_S - time.monotonic()))
        t1 = time.monotonic()
        stop.set()
        flood.join(timeout=10)
        frames = [m for m in client.messages(ch.TAXELS) if t0 + 1.0 <= m.arrival_s <= t1]
        rates = [
            client.decode(m) for m in client.messages(ch.RATES) if t0 + 1.0 <= m.arrival_s <= t1
        ]
    finally:
        if client is not None:
            client.close()
        graph.stop([(0.0, signal.SIGINT)])
    span = t1 - t0 - 1.0
    fps = len(frames) / span
    peak = max(r["total_events_per_s"] for r in rates)
    print(
        f"flood: {sent[0] / (t1 - t0):.0f} events/s sent; view peak {peak:.0f} events/s; "
        f"taxel frames {fps:.1f}/s (display_rate_hz {RATE_HZ:g})"
    )
    assert fps <= RATE_HZ * 1.25 + 0.5  # bounded whatever the sensor does
    # and the view kept showing under the flood (4.9 of 15 frames/s once on a slow 2-core
    # machine running the whole suite)
    assert fps >= RATE_HZ * 0.25
    assert peak > 0.3 * FULL  # it saw the flood (best effort may lose some of it)
    # saturated taxels framed white once the rate (smoothed over 0.5 s) has settled: the frames
    # of the flood's last 2 s (from 2 s after the view first counted half of it), each judged
    framed = []
    for m in frames:
        if m.arrival_s >= t1 - 2.0:
            grid = client.decode(m)
            img = np.frombuffer(grid.data, np.uint8).reshape(grid.height, grid.width, 3)
            framed.append(int((img == 255).all(axis=2).sum() > 40 * 24))
    print(f"frames with saturated taxels framed in the last 2 s: {sum(framed)} of {len(framed)}")
    assert framed
    # at least one: the flood is exactly the full rate, and the view frames a taxel from 95 % of
    # it, so a loaded machine's losses decide how many (on a slow 2-core machine running the
    # whole suite 19 of 26 once, 2 of 18 once, the view's peak count 339 k events/s)
    assert sum(framed) >= 1
    problems = stop_problems(graph.proc, "".join(graph.out), "".join(graph.err))
    assert not [p for p in problems if "foxglove_view" in p], problems


@pytest.fixture(scope="module")
def handover_biotac_model(tmp_path_factory):
    """A handover model for the BioTac plate scene, trained as the demo trains (no NUSkin
    delivery step: BioTac frames carry no polarity)."""
    from ext_sense_perception.data.sources import from_sim_dataset
    from ext_sense_perception.training.recipe import train_bundle
    from ext_sense_sim.run import run_scene
    from ext_sense_sim.scene import load_scene

    root = tmp_path_factory.mktemp("view_biotac_model")
    run_scene(load_scene("handover_plate_biotac"), root / "data", 16, 11, formats=("npz",))
    train_bundle(from_sim_dataset(root / "data" / "dataset.npz"), root / "model")
    return root / "model"


@pytest.mark.timeout(300)
def test_view_draws_the_biotac_panels_on_the_handover_graph(handover_biotac_model, tmp_path):
    """The BioTac panels on a running graph: the electrode grid (both sensors, 19 electrodes
    each, coloured by their departure from rest) and the PAC plot (the last second of each
    sensor), with the window raster, the estimate panels (stability), the truth and the
    diagnostics beside them."""
    from ext_sense.topics import TOPIC_ESTIMATE, TOPIC_GROUND_TRUTH, TOPIC_WINDOW
    from ext_sense.view import channels as ch

    port = free_port()
    graph = Graph(
        "sensor:=biotac",
        "trials:=0",
        f"model:={handover_biotac_model}",
        f"port:={tmp_path / 'biotac.pty'}",
        "view:=true",
        f"view_port:={port}",
        f"view_rate:={RATE_HZ:g}",
        graph="handover",
    )
    client = None
    try:
        client = FoxgloveClient(f"ws://127.0.0.1:{port}", connect_timeout_s=60)
        wanted = set(ch.view_channels("biotac"))
        assert wait_for(lambda: wanted <= set(client.topics()), timeout=30), client.topics()
        assert ch.PAC in wanted
        assert ch.RATES not in client.topics()

        def heard() -> set[str]:
            return {m.topic for m in client.messages()}

        def pac_moving() -> bool:  # a trial's vibration in the last second of PAC
            for m in client.messages(ch.PAC)[-5:]:
                pac = client.decode(m)
                if all(np.ptp(pac.get(f"pac_{s}", [0])) > 0 for s in (0, 1)):
                    return True
            return False

        ok = wait_for(lambda: wanted <= heard() and pac_moving(), timeout=120, step=0.5)
        assert ok, (
            f"no message on {sorted(wanted - heard())}",
            Counter(m.topic for m in client.messages()),
            client.statuses,
            "".join(graph.err)[-3000:],
        )
        grids = [client.decode(m) for m in client.messages(ch.TAXELS)]
        pacs = [client.decode(m) for m in client.messages(ch.PAC)]
        window = client.decode(client.messages(TOPIC_WINDOW)[-1])
        raster = client.decode(client.messages(ch.WINDOW)[-1])
        truth = client.decode(client.messages(TOPIC_GROUND_TRUTH)[-1])
        diagnostics = client.decode(client.messages(ch.DIAGNOSTICS)[-1])
        estimate = client.decode(client.messages(TOPIC_ESTIMATE)[-1])
        info = client.decode(client.messages(ch.ESTIMATE_INFO)[-1])
        panel = client.decode(client.messages(ch.ESTIMATE)[-1])
    finally:
        if client is not None:
            client.close()
        graph.stop([(0.0, signal.SIGINT)])

    # the electrode grid: two sensors side by side, 4 x 5 cells of 24 px with an 8 px margin
    grid = grids[-1]
    assert grid.encoding == "rgb8"
    assert (grid.width, grid.height) == (2 * 5 * 24 + 24 + 2 * 8, 4 * 24 + 2 * 8)
    img = np.frombuffer(grid.data, np.uint8).reshape(grid.height, grid.width, 3)
    background = img[0, 0]
    centres = [
        (8 + r * 24 + 12, 8 + s * (5 * 24 + 24) + c * 24 + 12)
        for s in (0, 1)
        for r in range(4)
        for c in range(5)
        if r * 5 + c < 19
    ]
    assert all((img[y, x] != background).any() for y, x in centres)  # every electrode drawn
    assert len({bytes(g.data) for g in grids}) > 1  # the colours follow the electrodes
    # the PAC plot: up to the last second of each sensor (every 2nd sample of 2200 Hz)
    pac = pacs[-1]
    assert pac["sensor_ids"] == [0, 1]
    assert 0 < len(pac["pac_0"]) <= 1100
    assert 0 < len(pac["pac_1"]) <= 1100
    # the window raster and the passed-through topics
    assert raster.encoding == "rgb8"
    assert raster.width > 0
    assert raster.height > 0
    assert len(window.shape) == 2
    assert truth.task == "handover_stability"
    assert "worst_level" in diagnostics
    # the estimates of both fingers' windows (the emulated bridge streams between trials, so
    # the window node closes each window on the frames that follow it)
    assert (estimate.task, estimate.sensor) == ("handover_stability", "biotac")
    assert 0.0 <= estimate.stability_probability <= 1.0
    assert info["task"] == "handover_stability"
    assert 0.0 <= info["stability_probability"] <= 1.0  # shown to 4 decimals
    assert panel.encoding == "rgb8"
    problems = stop_problems(graph.proc, "".join(graph.out), "".join(graph.err))
    assert not [p for p in problems if "foxglove_view" in p], problems
