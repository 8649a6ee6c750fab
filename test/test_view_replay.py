"""Bags and live views agree (issue 19): the view of ``ext-sense replay BAG view:=true`` serves
the channels the view of the live graph served, with the recorded session's data.

A short run of the tap graph (``view:=true``) is recorded by ``ext-sense record``; a Foxglove
protocol client on the live view keeps what it receives. The bag is then replayed with the view
on (the ``foxglove_view`` node of :mod:`ext_sense.view.graph`, as the graphs start it) and a
second client does the same. Both views must advertise the same channels (topic, encoding,
schema name) and decode at least one message on each; the channels that pass the graph's topics
through must carry the very bytes the bag holds, and the estimate the view draws must read the
same (numbers and picture) from both sources.

The graph is the default one: its driver publishes raw packets only, so the bag is a packet
bag, as every bag is, and both views draw the taxels from the packets they decode.
"""

from __future__ import annotations

import signal
from collections import Counter
from pathlib import Path

import pytest
from foxglove_client import FoxgloveClient, Received, free_port
from rosutil import wait_for
from sim_models import CRASH_MARKERS, Command, Graph, stop_problems, train_sim_model

from ext_sense.topics import (
    TOPIC_DIAGNOSTICS,
    TOPIC_ESTIMATE,
    TOPIC_EVENTS,
    TOPIC_GROUND_TRUTH,
    TOPIC_NUSKIN_PACKETS,
    TOPIC_WINDOW,
)
from ext_sense.view import channels as ch
from ext_sense_bags import BagReader
from ext_sense_runtime.records import estimate_of, truth_of

pytestmark = [pytest.mark.ros, pytest.mark.slow]

FINALS = 6
"""Final estimates the live client must see before the recording stops."""
COMPARED = 2
"""Contacts whose drawings are compared, at least: the recorder may match the estimate
publisher only after the first trials (seen: after the third, under CI's load)."""
MATCH_NS = 300_000_000
"""The view's ``match_tolerance_ms`` (its default) in ns: an estimate's truth is the nearest
within it."""

LIVE_ONLY: dict[str, str] = {}
"""Channels only a live graph's view serves, each with why. None: the simulator's truth
(``/extsense/ground_truth``) and ``/diagnostics`` are recorded into the bag and played back with
the view on, and the view creates every channel of its sensor at start, whatever feeds it."""

RECORDED = (TOPIC_ESTIMATE, TOPIC_GROUND_TRUTH, TOPIC_WINDOW)
"""Passed-through channels whose every replayed message is a recorded one, byte for byte.
``/diagnostics`` is not among them: on replay it also carries the player's and the replay
view's own statuses (checked below: every recorded status message is still served)."""


@pytest.fixture(scope="module")
def tap_model(tmp_path_factory):
    model, _ = train_sim_model(
        tmp_path_factory.mktemp("view_replay_model"), "tap_rod30_nuskin", "tap_localization", 16
    )
    return model


def _signature(client: FoxgloveClient) -> dict[str, tuple[str, str]]:
    """Advertised channels: topic -> (message encoding, schema name)."""
    return {t: (c["encoding"], c["schemaName"]) for t, c in client.topics().items()}


def _finals(client: FoxgloveClient) -> int:
    """Final estimates the client got whose trial's truth it got too (the view draws those
    with their truth; the first trials' truth can come before its subscription matched)."""
    truths = [truth_of(client.decode(m)).onset_ns for m in client.messages(TOPIC_GROUND_TRUTH)]
    finals = [estimate_of(client.decode(m)) for m in client.messages(TOPIC_ESTIMATE)]
    return sum(
        not e.provisional and any(abs(e.onset_ns - t) <= MATCH_NS for t in truths) for e in finals
    )


def _every_channel_heard(client: FoxgloveClient, wanted: set[str]) -> bool:
    return wanted <= {m.topic for m in client.messages()}


def _estimates_drawn(client: FoxgloveClient) -> dict[int, tuple[dict, Received | None]]:
    """Final estimates as the view shows them: onset -> (its numbers, its picture)."""
    pictures = {m.log_time_ns: m for m in client.messages(ch.ESTIMATE)}
    out = {}
    for m in client.messages(ch.ESTIMATE_INFO):
        info = client.decode(m)
        if info["kind"] == "final":
            out[info["onset_ns"]] = (info, pictures.get(m.log_time_ns))
    return out


def _pixels(client: FoxgloveClient, item: Received) -> tuple[int, int, bytes]:
    image = client.decode(item)
    return image.width, image.height, bytes(image.data)


def _all_recorded_served(client: FoxgloveClient, recorded: dict[str, list[bytes]]) -> bool:
    """Whether the client got as many messages as the bag holds on each recorded topic, and
    every recorded ``/diagnostics`` message."""
    counts = Counter(m.topic for m in client.messages())
    if any(counts[topic] < len(recorded[topic]) for topic in RECORDED):
        return False
    served = {_cdr(m.payload) for m in client.messages(TOPIC_DIAGNOSTICS)}
    return set(recorded[TOPIC_DIAGNOSTICS]) <= served


def _cdr(payload: bytes) -> bytes:
    """A CDR payload as the wire carries it: padded with zeros to a multiple of 4 bytes.

    The recorder stores what it receives; a message it got from its own process (its own
    ``/diagnostics``) comes unpadded, and the same bytes published again arrive padded.
    """
    return payload + b"\0" * (-len(payload) % 4)


def _from_first_common(live: list[bytes], recorded: set[bytes]) -> list[bytes]:
    """The live payloads from the first one the bag holds on (the recorder may subscribe a
    little after the view does)."""
    first = next((i for i, p in enumerate(live) if p in recorded), len(live))
    return live[first:]


@pytest.mark.timeout(400)
def test_live_and_replayed_views_serve_the_same_channels_and_data(tap_model, tmp_path):
    bag = tmp_path / "tap_run"
    wanted = set(ch.view_channels("nuskin"))

    # -- live: record the tap graph while a client watches its view ---------------------------
    recorder = Command("record", str(bag))
    graph = live = None
    try:
        assert wait_for(lambda: recorder.printed("recording"), timeout=60), recorder.output()
        port = free_port()
        graph = Graph(
            "trials:=0",
            f"model:={tap_model}",
            f"port:={tmp_path / 'nuskin.pty'}",
            "view:=true",
            f"view_port:={port}",
        )
        live = FoxgloveClient(f"ws://127.0.0.1:{port}", connect_timeout_s=60)
        heard = wait_for(
            lambda: _every_channel_heard(live, wanted) and _finals(live) >= FINALS,
            timeout=120,
            step=0.5,
        )
        assert heard, (
            Counter(m.topic for m in live.messages()),
            live.statuses,
            "".join(graph.err)[-3000:],
        )
    finally:
        if live is not None:
            live.close()
        if graph is not None:
            graph.stop([(0.0, signal.SIGINT)])
        rc = recorder.interrupt()
    assert rc == 0, recorder.output()
    problems = stop_problems(graph.proc, "".join(graph.out), "".join(graph.err))
    assert not [p for p in problems if "foxglove_view" in p], problems
    with BagReader(bag) as reader:
        recorded = {
            t: [_cdr(r.data) for r in reader.records([t])] for t in (*RECORDED, TOPIC_DIAGNOSTICS)
        }
        recorded_truths = {
            truth_of(msg).onset_ns for _, msg in reader.messages([TOPIC_GROUND_TRUTH])
        }
        recorded_topics = {t: spec.count for t, spec in reader.topics.items()}
        recorded_estimates = {
            estimate_of(msg).onset_ns for _, msg in reader.messages([TOPIC_ESTIMATE])
        }
    assert recorded_topics.get(TOPIC_NUSKIN_PACKETS, 0) > 0, recorded_topics  # a packet bag,
    assert recorded_topics.get(TOPIC_EVENTS, 0) == 0, recorded_topics  # no decoded arrays
    assert all(recorded.values()), {t: len(v) for t, v in recorded.items()}

    # -- replay: the bag through `ext-sense replay BAG view:=true` ----------------------------
    port = free_port()
    replay = Command(
        "replay", str(bag), "--rate", "2", "--start-delay", "3", "view:=true", f"view_port:={port}"
    )
    again = None
    try:
        again = FoxgloveClient(f"ws://127.0.0.1:{port}", connect_timeout_s=60)
        played = wait_for(
            lambda: replay.printed("the bag is played") or replay.proc.poll() is not None,
            timeout=180,
            step=0.5,
        )
        assert played, replay.output()[-3000:]
        assert replay.proc.poll() is None, replay.output()[-3000:]
        # the player is done; the view may still be passing its last messages on under load
        assert wait_for(
            lambda: _every_channel_heard(again, wanted) and _all_recorded_served(again, recorded),
            timeout=30,
        ), Counter(m.topic for m in again.messages())
    finally:
        if again is not None:
            again.close()
        rc = replay.interrupt()
    assert rc == 0, replay.output()[-3000:]
    assert not [x for x in replay.output().splitlines() if any(c in x for c in CRASH_MARKERS)]

    # -- the same channels, each decoding on both sides ---------------------------------------
    live_channels, replay_channels = _signature(live), _signature(again)
    assert set(LIVE_ONLY) <= set(live_channels)
    assert {t: s for t, s in live_channels.items() if t not in LIVE_ONLY} == replay_channels
    assert set(replay_channels) == wanted
    for client in (live, again):
        for topic in wanted:
            decoded = client.decode(client.messages(topic)[0])
            assert decoded is not None, topic
        assert max(client.decode(m)["total_events_per_s"] for m in client.messages(ch.RATES)) > 0
        assert client.decode(client.messages(ch.TAXELS)[-1]).encoding == "rgb8"

    # -- the same data ------------------------------------------------------------------------
    for topic in RECORDED:
        replayed = [_cdr(m.payload) for m in again.messages(topic)]
        assert replayed == recorded[topic], (topic, len(replayed), len(recorded[topic]))
        seen_live = _from_first_common(
            [_cdr(m.payload) for m in live.messages(topic)], set(replayed)
        )
        assert seen_live, f"{topic}: nothing the live view sent is in the bag"
        assert set(seen_live) <= set(replayed), topic
    served = {_cdr(m.payload) for m in again.messages(TOPIC_DIAGNOSTICS)}
    assert set(recorded[TOPIC_DIAGNOSTICS]) <= served

    # an estimate is drawn with its trial's truth: compared where both views had that estimate
    # and its truth (the live client got them, and the bag holds them), since the view or the
    # recorder may match the truth or the estimate publisher only after the first trials (seen:
    # a bag with every truth but without the first two contacts' estimates; under CI load, the
    # first three: so six finals are watched and at least two compared)
    truths = {truth_of(live.decode(m)).onset_ns for m in live.messages(TOPIC_GROUND_TRUTH)}
    truths &= recorded_truths
    drawn_live, drawn_again = _estimates_drawn(live), _estimates_drawn(again)
    compared = [
        o
        for o in sorted(drawn_live)
        if o in recorded_estimates and any(abs(o - t) <= MATCH_NS for t in truths)
    ]
    assert len(compared) >= COMPARED, (sorted(drawn_live), sorted(truths))
    assert set(compared) <= set(drawn_again), (compared, sorted(drawn_again))
    for onset in compared:
        (info, picture), (info2, picture2) = drawn_live[onset], drawn_again[onset]
        assert info == info2, {k: (v, info2.get(k)) for k, v in info.items() if info2.get(k) != v}
        if picture is not None and picture2 is not None:
            assert _pixels(live, picture) == _pixels(again, picture2), onset
    assert any(drawn_live[o][1] is not None and drawn_again[o][1] is not None for o in compared)
    print(
        f"live view: {len(live.messages())} messages, replayed view: {len(again.messages())}; "
        f"{len(compared)} final estimates drawn alike; bag: "
        f"{ {Path(t).name: len(v) for t, v in recorded.items()} }"
    )
