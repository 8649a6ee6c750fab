"""A packet bag replayed offline gives the live run's windows and estimates, bit for bit.

The live tap graph runs (simulated NUSkin on a pty, driver publishing raw packets, the window
node decoding them) while ``ext-sense record`` records the packets, the ground truth and the
estimates. The bag is then replayed offline twice (``offline_estimates``: the window stage and
model the nodes run, the packets decoded by the same library decoder): both replays and the
live run give the same estimates, every field but the live-only ones (compute latency, and the
degraded flag the live node derives from arrival times, not from the bytes).

Live and replay follow one time rule, ``WindowStage``'s: a window closes when the packets carry
the stream past its end (the driver's "nothing read" packets, on its own cadence, do while the
sensor is silent), never on the window node's clock, so nothing a live window holds can differ
from the replay's. The recorder's packet subscription can match the driver's publisher after
the window node's did; only what the bag holds is compared.
"""

from __future__ import annotations

import math
import os
import re
import signal
import time

import pytest
from sim_models import finish_graph, spawn, train_sim_model

pytestmark = [pytest.mark.ros, pytest.mark.slow, pytest.mark.timeout(400)]

PACKETS = "/extsense/nuskin/packets"
TRUTH = "/extsense/ground_truth"
ESTIMATE = "/extsense/contact_estimate"
PROVISIONAL = "/extsense/contact_estimate/provisional"
WINDOW = "/extsense/contact_window"
LIVE_ONLY = ("compute_latency_ns", "degraded", "degraded_reason")
"""Estimate fields that depend on when things happened live, not on the recorded bytes."""


FIRST_SEQ = re.compile(r"first packet on \S+: seq (\d+)")


def _comparable(estimate) -> dict:
    """The fields the bytes decide; NaN as None (NaN never equals itself)."""
    return {
        k: None if isinstance(v, float) and math.isnan(v) else v
        for k, v in estimate._asdict().items()
        if k not in LIVE_ONLY
    }


def test_packet_bag_replays_offline_bit_identical_to_the_live_run(tmp_path):
    from ext_sense.offline_replay import offline_estimates
    from ext_sense_bags import BagReader
    from ext_sense_perception.online.predictor import load_model
    from ext_sense_perception.online.window import WindowConfig
    from ext_sense_runtime.records import estimate_of
    from ext_sense_runtime.stamps import stamp_to_ns

    model_dir, _ = train_sim_model(tmp_path, "tap_rod30_nuskin", "tap_localization", 40)
    bag = tmp_path / "live"
    recorder = spawn("record", str(bag), "--topics", PACKETS, TRUTH, ESTIMATE, PROVISIONAL, WINDOW)
    try:
        time.sleep(3.0)  # rclpy imported, subscriptions up before the graph's first packet
        assert recorder.poll() is None, recorder.communicate()
        graph = spawn(
            "run",
            "tap_localization",
            "trials:=6",
            f"model:={model_dir}",
            "seed:=5",
            f"port:=/tmp/ext_sense_packets_{os.getpid()}.pty",
        )
        out, err = finish_graph(graph, 150)
        assert graph.returncode == 0, err[-3000:]
        time.sleep(1.0)  # the last estimate reaches the recorder
    finally:
        if recorder.poll() is None:
            os.killpg(recorder.pid, signal.SIGINT)
        rec_out, rec_err = recorder.communicate(timeout=30)
    assert recorder.returncode == 0, rec_err[-3000:]

    with BagReader(bag) as reader:
        stamps = {
            int(msg.seq): stamp_to_ns(msg.header.stamp) for _, msg in reader.messages([PACKETS])
        }
        seqs = list(stamps)
        finals = [(rec.log_time_ns, estimate_of(msg)) for rec, msg in reader.messages([ESTIMATE])]
        anytime = [
            (rec.log_time_ns, estimate_of(msg)) for rec, msg in reader.messages([PROVISIONAL])
        ]
        answered = sorted(finals + anytime, key=lambda pair: pair[0])
        live = [e for _, e in answered]
        windows = [
            (stamp_to_ns(msg.header.stamp), bool(msg.provisional), rec.log_time_ns)
            for rec, msg in reader.messages([WINDOW])
        ]
    # lossless: the recorder has every packet the driver published from the first it got (its
    # subscription may match the driver's publisher after the first packets went out)
    assert seqs
    assert seqs == list(range(seqs[0], seqs[0] + len(seqs))), seqs[:20]

    # the window node may subscribe after the driver's first packets (the recorder, started
    # first, has them): replay from the packet the live node started with, as it logs
    joined = FIRST_SEQ.search(err)
    assert joined, err[-3000:]
    from_seq = max(int(joined.group(1)), seqs[0])
    model = load_model(model_dir, "onnx")
    config = WindowConfig(model.card.profile, "nuskin")

    def replay() -> list[dict]:
        return [
            _comparable(item)
            for kind, item in offline_estimates(bag, config, model, from_seq)
            if kind == "estimate"
        ]

    first, second = replay(), replay()
    assert first == second

    def key(e: dict) -> tuple:
        return (e["onset_ns"], e["post_contact_used_ns"], e["provisional"])

    # The recorder's packet subscription may match the driver's publisher after the window
    # node's did, even in the middle of a tap: the bag then lacks bytes the live node had, and
    # the replay cannot know the taps before it (it detected one 231 ms late, on a tap's tail,
    # in 1 of 3 runs) nor the start of a window that begins before the bag (a window whose
    # first 15 ms were not in it gave another tap position). From the first onset the replay
    # shares with the live node whose window and onset burst the bag holds, both have the same
    # bytes and detector state: everything from there is compared.
    live_onsets = {onset for onset, _, _ in windows}
    if seqs[0] > int(joined.group(1)):  # the bag starts after the live node's first packet
        bag_from = stamps[from_seq]
        covered = {
            o for o in live_onsets if o - config.pre_ns - config.activity_window_ns >= bag_from
        }
    else:  # the replay reads every packet the live node read
        covered = live_onsets
    shared = sorted(covered & {e["onset_ns"] for e in first})
    assert shared, (sorted(live_onsets)[:5], sorted({e["onset_ns"] for e in first})[:5])
    compared_from = shared[0]
    assert compared_from == min(covered), "a live onset the bag holds whole was not replayed"
    first = [e for e in first if e["onset_ns"] >= compared_from]
    live_c = [_comparable(e) for e in live if e.onset_ns >= compared_from]
    assert sum(not e["provisional"] for e in live_c) >= 3, (out, rec_out)
    # the final estimates alone on the estimate topic, the anytime ones on their own
    assert not any(e.provisional for _, e in finals)
    assert anytime
    assert all(e.provisional for _, e in anytime)

    # every estimate the live run made and the recorder got, the replay made too, field for field
    replayed = {key(e): e for e in first}
    missing = [key(e) for e in live_c if key(e) not in replayed]
    onsets = sorted({e["onset_ns"] for e in first})
    near = [(m[0], min(onsets, key=lambda o, m=m: abs(o - m[0])) - m[0]) for m in missing[:5]]
    bag_until = stamps[seqs[-1]]
    assert not missing, (
        missing[:5],
        near,
        [bag_until - m[0] for m in missing[:5]],  # the bag's last packet after the onset
        len(onsets),
        seqs[0],
        from_seq,
        err[-1500:],
    )
    differ = [
        (key(b), {f: (replayed[key(b)][f], b[f]) for f in b if replayed[key(b)][f] != b[f]})
        for b in live_c
        if replayed[key(b)] != b
    ]
    assert not differ, (differ[:3], err[-2000:])
    # and it made no other, but for windows the recorder heard before the inference node had
    # its model (the recorder's subscriptions may also match the graph's publishers after the
    # first tap: nothing before the first window it heard counts)
    answered_keys = {key(e) for e in live_c}
    extra = [e for e in first if key(e) not in answered_keys]
    published = {(onset, prov): t for onset, prov, t in windows}
    unanswered = {(e["onset_ns"], e["provisional"]) for e in extra}
    assert unanswered <= published.keys()  # windows the live node cut, as the replay did
    assert all(published[w] <= answered[0][0] for w in unanswered)  # before inference was up
    assert len(extra) <= 10, extra  # at most the first two taps' provisional and final windows
    print(
        f"packet replay: {len(live_c)} live estimates compared and equal, from onset "
        f"{sorted(live_onsets).index(compared_from) + 1} of {len(live_onsets)}; bag from seq "
        f"{seqs[0]}, live node from seq {joined.group(1)}; {len(extra)} replayed only"
    )
