"""The ``biotac_driver`` node over a pty: two sensors, garbage, one unplug and replug."""

from __future__ import annotations

import contextlib
import os
import time
import tty

import numpy as np
import pytest

from ext_sense_drivers.biotac.bridge import encode_frame
from ext_sense_drivers.biotac.words import encode_values

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
    from ext_sense_msgs.msg import BioTacFrame
    from ext_sense_runtime.qos import DIAGNOSTICS_QOS, SENSOR_STREAM_QOS

    bridge = FakeBridge(str(tmp_path / "ttyBIOTAC"))
    bridge.plug()
    ctx = Context()
    rclpy.init(context=ctx)
    node = probe = None
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
        got: list[BioTacFrame] = []
        diags: list[DiagnosticArray] = []
        probe.create_subscription(BioTacFrame, "frames", got.append, SENSOR_STREAM_QOS)
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
        if node is not None:
            node.destroy_node()
        if probe is not None:
            probe.destroy_node()
        rclpy.try_shutdown(context=ctx)
        with contextlib.suppress(OSError):
            bridge.unplug()

    assert len(got) > n_before
    for m in got:
        assert m.sensor_id in SENSORS
        assert m.header.frame_id == f"biotac_{m.sensor_id}"
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
        stamps = [m.header.stamp.sec * 10**9 + m.header.stamp.nanosec for m in msgs]
        assert all(t > 0 for t in stamps)
    c = node.decoder.counters
    assert c.crc_failures + c.skipped_bytes > 0  # the garbage burst was counted, not fatal
    statuses = {st.name: st for d in diags for st in d.status}
    assert "biotac_driver: link" in statuses
    assert "biotac_driver: sensor 3 frames" in statuses
    keys = {kv.key for kv in statuses["biotac_driver: decode"].values}
    assert {"crc_failures", "sensor_0_dropped_frames", "sensor_3_parity_errors"} <= keys
