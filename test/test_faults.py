"""Device faults through driver and window nodes: garbage bytes, port closed and reopened.

The nodes keep running, diagnostics say what happened, and a recording made meanwhile holds
every packet the driver published.
"""

from __future__ import annotations

import contextlib
import os
import time
import tty
from pathlib import Path

import numpy as np
import pytest
from rosutil import spinning, wait_for

pytestmark = [pytest.mark.ros, pytest.mark.slow]  # kills and restarts node processes

PACKETS = "/extsense/nuskin/packets"


def _params(**kw):
    from rclpy.parameter import Parameter

    return [Parameter(k, value=v) for k, v in kw.items()]


def _open_pty(link: Path) -> tuple[int, int]:
    master, slave = os.openpty()
    tty.setraw(slave)
    tmp = link.with_suffix(".new")
    if tmp.exists() or tmp.is_symlink():
        tmp.unlink()
    tmp.symlink_to(os.ttyname(slave))
    tmp.replace(link)
    return master, slave


def _burst(n_ms: int = 50) -> bytes:
    from ext_sense_drivers.nuskin.wire import encode_words

    taxel = np.tile(np.arange(1, 81), n_ms)
    return encode_words(taxel, np.full(taxel.size, 300))


def test_garbage_and_port_reopen_keep_nodes_alive_and_recording_complete(tmp_path):
    from ext_sense.nodes.recorder import RecorderNode
    from ext_sense_bags import BagReader
    from ext_sense_drivers.nodes.nuskin_driver import NuskinDriverNode
    from ext_sense_perception.nodes.contact_window import ContactWindowNode

    diagnostics: dict[str, dict[str, str]] = {}

    def listener(context):
        from diagnostic_msgs.msg import DiagnosticArray
        from rclpy.node import Node

        from ext_sense_runtime.qos import DIAGNOSTICS_QOS

        node = Node("diagnostics_listener", context=context)

        def on_diag(msg):
            for st in msg.status:
                diagnostics[st.name] = {kv.key: kv.value for kv in st.values}

        node.create_subscription(DiagnosticArray, "/diagnostics", on_diag, DIAGNOSTICS_QOS)
        return node

    link = tmp_path / "nuskin.pty"
    master, slave = _open_pty(link)
    bag = tmp_path / "bag"
    remap = ["--ros-args", "-r", f"packets:={PACKETS}"]
    try:
        with spinning(
            lambda context: NuskinDriverNode(
                context=context,
                parameter_overrides=_params(transport="serial", port=str(link)),
                cli_args=remap,
            ),
            lambda context: ContactWindowNode(context=context, cli_args=remap),
            lambda context: RecorderNode(
                context=context, parameter_overrides=_params(bag=str(bag), topics=[PACKETS])
            ),
            listener,
        ) as (_driver, window, recorder, _):
            time.sleep(1.5)
            os.write(master, _burst())
            assert wait_for(lambda: window.stage.counters.events >= 4000, 5.0)
            # garbage between words: the decoder resynchronises, counts, goes on
            os.write(master, b"\xff\x00\x13garbage\x88" * 20 + _burst())
            assert wait_for(lambda: window.stage.counters.events >= 8000, 5.0)
            # the device vanishes, then comes back on the same path
            os.close(master)
            os.close(slave)
            time.sleep(1.0)
            master, slave = _open_pty(link)
            for _ in range(100):
                time.sleep(0.1)
                os.write(master, _burst(5))
                if window.stage.counters.events >= 12000:
                    break
            assert window.stage.counters.events >= 12000
            time.sleep(0.5)
            assert wait_for(
                lambda: int(diagnostics.get("nuskin_driver: link", {}).get("connects", 0)) >= 2,
                5.0,
            ), diagnostics
            time.sleep(1.5)  # one more diagnostics period: counters after the last batch
            link_values = diagnostics["nuskin_driver: link"]
            assert int(link_values["disconnects"]) >= 1, link_values
            packets = diagnostics["contact_window: windows"]  # the window node decodes
            assert int(packets["packet_skipped_bytes"]) > 0, packets
            published = int(link_values["packets_published"])
            assert published > 0
            assert wait_for(lambda: recorder.received.get(PACKETS, 0) >= published, 5.0)
            assert "contact_window: windows" in diagnostics
    finally:
        for fd in (master, slave):
            with contextlib.suppress(OSError):
                os.close(fd)
    with BagReader(bag) as reader:
        assert reader.topics[PACKETS].count >= published
