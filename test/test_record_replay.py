"""Record and replay without the ros2 CLI; deterministic offline replay of the graph's core."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import pytest
from ext_sense_bags.messages import sensor_packet
from rosutil import spinning, wait_for
from synthetic import MS, T0, CountingModel, stream_packets, tap_stream

from ext_sense_bags import BagReader, BagWriter, ground_truth, taxel_event_batch, type_hash

PACKETS = "/extsense/nuskin/packets"
TRUTH = "/extsense/ground_truth"


def _truths(bag: BagWriter, onsets_ms, t0_ns: int) -> None:
    bag.set_custom_data("task", "tap_localization")
    bag.set_custom_data("sensor", "nuskin")
    for i, onset in enumerate(onsets_ms):
        t = t0_ns + int(onset * MS)
        bag.write(TRUTH, t, ground_truth(t, "tap_localization", i, tap_position_m=0.01 * i))


def write_tap_bag(path: Path, onsets_ms=(100.0, 800.0, 1500.0), t0_ns=T0) -> None:
    """A bag of synthetic taps: the driver's packets (a read per 1 ms batch, "nothing read"
    while silent) and one ground truth per tap."""
    with BagWriter(path) as bag:
        _truths(bag, onsets_ms, t0_ns)
        batches = tap_stream(list(onsets_ms), max(onsets_ms) + 400.0, t0_ns=t0_ns, seed=3)
        for packet in stream_packets(batches):
            bag.write(PACKETS, packet.end_ns, sensor_packet(packet, "nuskin"))


def write_old_tap_bag(path: Path, onsets_ms=(100.0, 800.0, 1500.0), t0_ns=T0) -> None:
    """The same taps as a bag from before packets: 1 ms ``TaxelEventBatch`` messages."""
    with BagWriter(path) as bag:
        _truths(bag, onsets_ms, t0_ns)
        for b in tap_stream(list(onsets_ms), max(onsets_ms) + 400.0, t0_ns=t0_ns, seed=3):
            msg = taxel_event_batch(b.stamp_ns, b.taxel, b.polarity, b.value, b.offset_ns)
            bag.write("/extsense/nuskin/events", b.stamp_ns, msg)


def test_offline_replay_is_deterministic(tmp_path):
    from ext_sense.offline_replay import offline_estimates
    from ext_sense_perception.online.window import WindowConfig

    write_tap_bag(tmp_path / "bag")
    config = WindowConfig.for_task("tap_localization", "nuskin")

    def run():
        out = []
        for kind, item in offline_estimates(tmp_path / "bag", config, CountingModel()):
            if kind == "estimate":
                out.append({k: v for k, v in item._asdict().items() if k != "compute_latency_ns"})
        return out

    first, second = run(), run()
    finals = [e for e in first if not e["provisional"]]
    assert len(finals) == 3
    # a tap's simultaneous words leave the receiver one after another (10 us each): the
    # decoded onset is up to a ms before the synthetic one
    onsets_ms = [(e["onset_ns"] - T0) / MS for e in finals]
    assert all(abs(a - b) <= 1.0 for a, b in zip(onsets_ms, [100, 800, 1500], strict=True))
    assert len(first) == len(second)
    for a, b in zip(first, second, strict=True):
        assert a.keys() == b.keys()
        for key in a:
            if hasattr(a[key], "tolist"):
                assert a[key].tolist() == b[key].tolist()
            else:
                assert a[key] == b[key] or (a[key] != a[key] and b[key] != b[key])  # NaN


def test_offline_cli_prints_summary_last(tmp_path, monkeypatch):
    from sim_models import write_card

    from ext_sense import cli
    from ext_sense_perception.online import predictor

    write_tap_bag(tmp_path / "bag")
    # the task's default model, found by name along the model search path
    monkeypatch.setenv("EXT_SENSE_MODELS", str(tmp_path / "models"))
    write_card(tmp_path / "models" / "tap_localization_nuskin")
    monkeypatch.setattr(predictor, "load_model", lambda path, backend: CountingModel())
    out_json = tmp_path / "est.json"
    import contextlib
    import io

    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        rc = cli.main(["replay", str(tmp_path / "bag"), "--offline", "--json", str(out_json)])
    assert rc == 0
    lines = buf.getvalue().strip().splitlines()
    assert lines[-1].startswith("summary: taps=3 mae_cm=")
    assert sum(line.startswith("tap ") for line in lines) == 3
    assert out_json.is_file()


@pytest.mark.ros
def test_record_then_replay_flat_out_loses_nothing(tmp_path):
    from rclpy.node import Node
    from rclpy.parameter import Parameter

    from ext_sense.nodes.bag_player import BagPlayerNode
    from ext_sense.nodes.recorder import RecorderNode
    from ext_sense_drivers.nodes.link_node import packet_message
    from ext_sense_msgs.msg import ContactGroundTruth, SensorPacket
    from ext_sense_runtime.qos import GROUND_TRUTH_QOS, SENSOR_STREAM_QOS
    from ext_sense_runtime.stamps import fill_stamp

    src = tmp_path / "recorded"
    holder = {}

    def publisher(context):
        node = Node("source", context=context)
        holder["packets"] = node.create_publisher(SensorPacket, PACKETS, SENSOR_STREAM_QOS)
        holder["truth"] = node.create_publisher(ContactGroundTruth, TRUTH, GROUND_TRUTH_QOS)
        return node

    with spinning(
        publisher,
        lambda context: RecorderNode(
            context=context,
            parameter_overrides=[Parameter("bag", value=str(src))],
        ),
    ) as (node, recorder):
        assert wait_for(lambda: node.count_subscribers(PACKETS) >= 1, 5.0)
        batches = stream_packets(tap_stream([100.0], 500.0, seed=5))
        gt = ContactGroundTruth(task="tap_localization", trial=0, tap_position_m=0.1)
        fill_stamp(gt.header.stamp, T0)
        holder["truth"].publish(gt)
        for packet in batches:
            holder["packets"].publish(packet_message(packet, "nuskin"))
            time.sleep(0.0002)
        assert wait_for(lambda: recorder.received.get(PACKETS) == len(batches), 5.0)
        # the hash rclpy reports for the live publisher equals the one in the bag
        info = node.get_publishers_info_by_topic(PACKETS)
        reported = str(info[0].topic_type_hash)
        assert wait_for(lambda: recorder.received.get(TRUTH) == 1, 3.0)
    with BagReader(src) as bag:
        topics = bag.topics
    assert topics[PACKETS].count == len(batches)
    assert topics[PACKETS].type_hash == reported == type_hash("ext_sense_msgs/msg/SensorPacket")
    assert topics[TRUTH].count == 1

    # replay flat out into a second recorder: every message arrives, byte for byte
    copy = tmp_path / "copy"
    with spinning(
        lambda context: RecorderNode(
            context=context, parameter_overrides=[Parameter("bag", value=str(copy))]
        ),
        lambda context: BagPlayerNode(
            context=context,
            parameter_overrides=[
                Parameter("bag", value=str(src)),
                Parameter("rate", value=0.0),
                Parameter("start_delay_s", value=1.0),
            ],
        ),
    ) as (recorder2, player):
        assert wait_for(player.finished.is_set, 10.0)
        assert not player.error
        assert wait_for(lambda: recorder2.received.get(PACKETS) == len(batches), 5.0)
    with BagReader(src) as a, BagReader(copy) as b:
        left = [r.data for r in a.records([PACKETS])]
        right = [r.data for r in b.records([PACKETS])]
    assert left == right


@pytest.mark.ros
@pytest.mark.slow  # starts the record and replay commands as processes
def test_record_and_replay_commands(tmp_path):
    """The CLI ends to end: replay a bag flat out while ``ext-sense record`` records it."""
    src = tmp_path / "src"
    write_tap_bag(src, onsets_ms=(100.0,))
    out = tmp_path / "rec"
    exe = [sys.executable, "-m", "ext_sense.cli"]
    rec = subprocess.Popen(
        [*exe, "record", str(out), "--topics", PACKETS, TRUTH, "--duration", "6"],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    try:
        time.sleep(1.5)
        play = subprocess.run(
            [*exe, "replay", str(src), "--flat-out", "--start-delay", "1.0"],
            capture_output=True,
            text=True,
            timeout=30,
        )
        assert play.returncode == 0, play.stderr
        assert "msg/s" in play.stdout
        rec_out, _ = rec.communicate(timeout=20)
    finally:
        if rec.poll() is None:
            rec.kill()
            rec.wait()
    assert rec.returncode == 0, rec_out
    with BagReader(src) as a, BagReader(out) as b:
        assert b.topics[PACKETS].count == a.topics[PACKETS].count
        assert b.topics[TRUTH].count == 1


@pytest.mark.ros
@pytest.mark.slow  # starts the record and replay commands as processes
def test_ctrl_c_ends_record_and_replay_with_exit_0_and_no_traceback(tmp_path):
    """SIGINT to the process group, twice as a terminal and an impatient user send it."""
    import os
    import signal

    src = tmp_path / "src"
    write_tap_bag(src, onsets_ms=(100.0, 20_000.0))  # 20 s at recorded pace
    exe = [sys.executable, "-m", "ext_sense.cli"]
    commands = {
        "record": [*exe, "record", str(tmp_path / "rec"), "--topics", PACKETS, TRUTH],
        "replay": [*exe, "replay", str(src), "--start-delay", "0"],
    }
    for name, command in commands.items():
        proc = subprocess.Popen(
            command,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            start_new_session=True,
        )
        time.sleep(4.0)  # rclpy imported, spinning
        assert proc.poll() is None, proc.communicate()
        os.killpg(proc.pid, signal.SIGINT)
        time.sleep(0.2)
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGINT)
        out, err = proc.communicate(timeout=20)
        assert proc.returncode == 0, (name, out, err)
        assert "Traceback" not in err, (name, err)
        assert "KeyboardInterrupt" not in err, (name, err)
        if name == "record":
            assert out.splitlines()[-1].startswith("recorded ")
            with BagReader(tmp_path / "rec") as bag:  # closed: footer and metadata written
                assert set(bag.topics) <= {PACKETS, TRUTH}
        else:
            assert out.splitlines()[-1].startswith("stopped after ")
