"""The ``biotac_driver`` node over a pty: two sensors, garbage, one unplug and replug."""

from __future__ import annotations

import contextlib
import os
import time
import tty

import numpy as np
import pytest

from ext_sense_drivers.biotac.encoder import encode_frame
from ext_sense_drivers.biotac.words import encode_values
from ext_sense_runtime.stamps import stamp_to_ns

SENSORS = (0, 3)
LOST_WHILE_UNPLUGGED = 30


def values_for(sensor, seq):
    """Deterministic 44 word values of a frame, so every message can be checked exactly."""
    return (np.arange(44) * 31 + seq * 7 + sensor * 500) % 4096


def frame_bytes(sensor, seq):
    words = encode_values(values_for(sensor, seq))
    if seq % 10 == 3:
        words[2] ^= 0x0100  # PAC sample 1 fails parity in these frames
    return encode_frame(seq, sensor, words)


def stamp_ns(m):
    return m.stamp_ns if hasattr(m, "stamp_ns") else stamp_to_ns(m.header.stamp)


class FramesOf(list):
    """The frames of the driver's packets, decoded as they arrive with the library decoder."""

    def __init__(self):
        super().__init__()
        self.decoder = None
        self.frame_ids = set()

    def on_packet(self, msg):
        from ext_sense_drivers.packets import BioTacPacketDecoder, packet_of

        packet = packet_of(msg)
        if self.decoder is None:
            self.decoder = BioTacPacketDecoder(packet.encoding, packet.options)
        self.frame_ids.add(packet.frame_id)
        self.extend(self.decoder.decode(packet).frames)


def assert_stamps_within(msgs, t_start_ns, t_end_ns):
    """Stamps are ROS-time ns of the first PAC sample: the clock model puts each one between
    (some frame's arrival - lead) and the frame's own arrival - lead, so inside the test's run."""
    lead_ns = 10_000_000 + 960_000  # frame span + 96 bytes at the default 1 Mbaud
    for m in msgs:
        assert t_start_ns - lead_ns - 1_000_000 <= stamp_ns(m) <= t_end_ns


def assert_stamps_never_decrease(msgs):
    """Per sensor, stamps in sequence order never go back. They need not strictly increase:
    from a source faster than 100 frames/s (a replay faster than 9600 bytes/s per sensor) the
    clock model stamps each frame at its arrival - lead, so frames that one read completed share
    a stamp, and how many do depends on how often the reader thread got the CPU."""
    for s in {m.sensor_id for m in msgs}:
        stamps = [stamp_ns(m) for m in msgs if m.sensor_id == s]
        assert stamps == sorted(stamps), f"sensor {s}: a stamp went back"


class FakeBridge:
    """A pty whose slave sits behind a fixed symlink path, like a udev name."""

    def __init__(self, link):
        self.link = link
        self.master = self.slave = -1
        self.seq = 0

    def plug(self):
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)  # no line discipline on the bytes, whoever opens it
        with contextlib.suppress(FileNotFoundError):
            os.unlink(self.link)
        os.symlink(os.ttyname(self.slave), self.link)

    def unplug(self):
        os.close(self.master)
        os.close(self.slave)
        self.master = self.slave = -1

    def send_frames(self, garbage=b""):
        data = garbage + b"".join(frame_bytes(s, self.seq) for s in SENSORS)
        self.seq = (self.seq + 1) % 65536
        with contextlib.suppress(OSError):
            os.write(self.master, data)


@pytest.mark.ros
def test_two_sensors_unplug_replug(tmp_path):
    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import Parameter

    from ext_sense_drivers.nodes.biotac_driver import BioTacDriverNode
    from ext_sense_msgs.msg import SensorPacket
    from ext_sense_runtime.qos import DIAGNOSTICS_QOS, SENSOR_STREAM_QOS

    bridge = FakeBridge(str(tmp_path / "ttyBIOTAC"))
    bridge.plug()
    ctx = Context()
    rclpy.init(context=ctx)
    node = probe = None
    t_start_ns = time.time_ns()
    try:
        node = BioTacDriverNode(
            context=ctx,
            parameter_overrides=[
                Parameter("port", value=bridge.link),
                Parameter("expected_sensors", value=list(SENSORS)),
                Parameter("reconnect_initial_s", value=0.05),
                Parameter("reconnect_max_s", value=0.2),
            ],
        )
        probe = rclpy.create_node("probe", context=ctx)
        got = FramesOf()
        diags: list[DiagnosticArray] = []
        probe.create_subscription(SensorPacket, "packets", got.on_packet, SENSOR_STREAM_QOS)
        probe.create_subscription(DiagnosticArray, "/diagnostics", diags.append, DIAGNOSTICS_QOS)
        ex = SingleThreadedExecutor(context=ctx)
        ex.add_node(node)
        ex.add_node(probe)

        def run(until, timeout_s, send=True):
            end = time.monotonic() + timeout_s
            next_send = time.monotonic()
            while time.monotonic() < end and not until():
                if send and time.monotonic() >= next_send:
                    garbage = b"\x00\xaa\x55\x07junk" if bridge.seq == 25 else b""
                    bridge.send_frames(garbage)
                    next_send += 0.01
                ex.spin_once(timeout_sec=0.002)

        def seen(sensor, after_seq=-1):
            return any(m.sensor_id == sensor and m.sequence > after_seq for m in got)

        run(lambda: node.reader.connects >= 1 and all(seen(s, 40) for s in SENSORS), 8.0)
        assert all(seen(s, 40) for s in SENSORS), f"frames before unplug: {len(got)}"
        n_before = len(got)

        bridge.unplug()
        run(lambda: node.reader.disconnects >= 1, 5.0, send=False)
        assert node.reader.disconnects >= 1
        bridge.seq += LOST_WHILE_UNPLUGGED  # the bridge kept counting while unplugged
        resume_seq = bridge.seq
        bridge.plug()
        run(lambda: all(seen(s, resume_seq + 20) for s in SENSORS), 8.0)
        assert all(seen(s, resume_seq + 20) for s in SENSORS), "no frames after replug"
        assert node.reader.connects >= 2
        run(lambda: any(st.name.endswith("decode") for d in diags for st in d.status), 3.0)
    finally:
        t_end_ns = time.time_ns()
        if node is not None:
            node.destroy_node()
        if probe is not None:
            probe.destroy_node()
        rclpy.try_shutdown(context=ctx)
        with contextlib.suppress(OSError):
            bridge.unplug()

    assert len(got) > n_before
    assert got.frame_ids == {"biotac"}  # one link carries every sensor slot
    for m in got:
        assert m.sensor_id in SENSORS
        assert m.pac_sample_period_ns == 454_545
        v = values_for(m.sensor_id, m.sequence)
        mask = (1 << 2) if m.sequence % 10 == 3 else 0
        assert m.invalid_word_mask == mask
        pac = v[0::2].copy()
        if mask:
            pac[1] = 0
        assert m.pac.tolist() == pac.tolist()  # raw samples, never averaged
        assert m.electrodes.tolist() == v[1:38:2].tolist()
        assert (m.pdc, m.tac, m.tdc) == (v[39], v[41], v[43])
    for s in SENSORS:
        msgs = [m for m in got if m.sensor_id == s]
        seqs = [m.sequence for m in msgs]
        assert seqs == sorted(seqs)
        after = [m for m in msgs if m.sequence >= resume_seq]
        assert after[0].dropped_frames >= LOST_WHILE_UNPLUGGED
        # Counters are cumulative and monotonic per sensor.
        for field in ("dropped_frames", "parity_errors", "error_replies"):
            series = [getattr(m, field) for m in msgs]
            assert series == sorted(series)
        assert msgs[-1].parity_errors >= sum(1 for q in seqs if q % 10 == 3)
    assert_stamps_within(got, t_start_ns, t_end_ns)
    assert_stamps_never_decrease(got)
    c = node.decoder.counters
    assert c.crc_failures + c.skipped_bytes > 0  # the garbage burst was counted, not fatal
    statuses = {st.name: st for d in diags for st in d.status}
    assert "biotac_driver: link" in statuses
    assert "biotac_driver: sensor 3 frames" in statuses
    keys = {kv.key for kv in statuses["biotac_driver: decode"].values}
    assert {"crc_failures", "sensor_0_dropped_frames", "sensor_3_parity_errors"} <= keys


@pytest.mark.ros
def test_file_replay_publishes_every_frame_once(tmp_path):
    import rclpy
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import Parameter

    from ext_sense_drivers.nodes.biotac_driver import BioTacDriverNode
    from ext_sense_msgs.msg import SensorPacket
    from ext_sense_runtime.qos import SENSOR_STREAM_QOS

    n_seq = 150
    stream = b"".join(frame_bytes(s, q) for q in range(n_seq) for s in SENSORS)
    stream = stream[:1000] + b"\xaa\x55garbage" + stream[1000:]
    path = tmp_path / "capture.bin"
    path.write_bytes(stream + frame_bytes(0, n_seq)[:40])  # cut-off frame at the end
    ctx = Context()
    rclpy.init(context=ctx)
    node = probe = None
    t_start_ns = time.time_ns()
    try:
        node = BioTacDriverNode(
            context=ctx,
            parameter_overrides=[
                Parameter("transport", value="file"),
                Parameter("file_path", value=str(path)),
                Parameter("file_bytes_per_s", value=50_000.0),
            ],
        )
        probe = rclpy.create_node("probe", context=ctx)
        got = FramesOf()
        probe.create_subscription(SensorPacket, "packets", got.on_packet, SENSOR_STREAM_QOS)
        ex = SingleThreadedExecutor(context=ctx)
        ex.add_node(node)
        ex.add_node(probe)
        end = time.monotonic() + 10.0
        while time.monotonic() < end and node.decoder.counters.truncated == 0:
            ex.spin_once(timeout_sec=0.005)
        # spin_once runs one callback: keep spinning until the queued messages are delivered.
        last = {s: n_seq - 1 for s in SENSORS}
        end = time.monotonic() + 10.0
        while time.monotonic() < end and not all(
            any(m.sensor_id == s and m.sequence == q for m in got[-4:]) for s, q in last.items()
        ):
            ex.spin_once(timeout_sec=0.005)
    finally:
        t_end_ns = time.time_ns()
        if node is not None:
            node.destroy_node()
        if probe is not None:
            probe.destroy_node()
        rclpy.try_shutdown(context=ctx)
    c = node.decoder.counters
    assert c.truncated == 1
    assert c.frames == 2 * n_seq - 1  # the frame the garbage was pushed into is lost
    assert c.crc_failures >= 1
    assert c.dropped_frames == (1, 0, 0, 0, 0)
    assert node.frames_decoded == c.frames
    # The replay starts before the probe is matched, so the first messages may miss it; every
    # one that arrives is unique, in order, and the last ones carry the final counters.
    assert len(got) > 20
    for s in SENSORS:
        msgs = [m for m in got if m.sensor_id == s]
        seqs = [m.sequence for m in msgs]
        assert seqs == sorted(set(seqs))
        assert seqs[-1] == n_seq - 1
        assert msgs[-1].dropped_frames == c.dropped_frames[s]
        assert msgs[-1].parity_errors == c.parity_errors[s]
    assert_stamps_within(got, t_start_ns, t_end_ns)
    assert_stamps_never_decrease(got)
