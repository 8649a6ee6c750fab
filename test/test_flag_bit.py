"""The NUSkin flag bit survives every hop: receiver bytes -> driver -> packet -> bag -> CSV.

Issue #15: the default decode wrote polarity 0 for every word and no column held the bit, so a
wire bit was discarded. Now the driver's packets carry the words as received, the recorder's raw
CDR carries them into the bag, the library decoder gives each event's bit (``flag``), and the
event CSV writes it in its own column, whatever the polarity choice makes of it (default
``ignore``: polarity 0). Bags of decoded arrays keep the bit in ``TaxelEventBatch.flag``.
"""

from __future__ import annotations

import io
import os
import time

import numpy as np
import pytest

rclpy = pytest.importorskip("rclpy")

from ext_sense_bags.messages import taxel_event_batch  # noqa: E402

from ext_sense_bags import BagReader, BagWriter  # noqa: E402
from ext_sense_drivers.nuskin.events_csv import CSV_HEADER, write_rows  # noqa: E402
from ext_sense_drivers.nuskin.wire import encode_words  # noqa: E402

TOPIC = "/extsense/nuskin/events"
PACKETS = "/extsense/nuskin/packets"
TAXEL = [3, 41, 80, 7, 12]
VALUE = [7, 1023, 0, 512, 99]
FLAG = [1, 0, 1, 1, 0]


def _csv_of_bag(bag_dir) -> list[str]:
    from ext_sense_drivers.packets import make_decoder

    out = io.StringIO()
    out.write(CSV_HEADER + "\n")
    n = 0
    decoder = None
    with BagReader(bag_dir) as reader:
        for _, msg in reader.messages([PACKETS]):
            if decoder is None:
                decoder = make_decoder(str(msg.encoding), str(msg.encoding_options))
            decoded = decoder.decode(msg)
            ev = decoded.events
            if ev.size:  # the link's opening packet holds no word
                n += write_rows(out, n, ev.polarity, ev.taxel, ev.value, decoded.flag)
    return out.getvalue().splitlines()


@pytest.mark.ros
def test_a_set_flag_bit_survives_driver_message_bag_and_csv(tmp_path):
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import Parameter

    from ext_sense_drivers.nodes.nuskin_driver import NuskinDriverNode
    from ext_sense_drivers.transports.base import LinkState
    from ext_sense_msgs.msg import SensorPacket
    from ext_sense_runtime.qos import SENSOR_STREAM_QOS

    master, slave = os.openpty()
    link = tmp_path / "nuskin.pty"
    link.symlink_to(os.ttyname(slave))
    context = rclpy.Context()
    rclpy.init(context=context)
    driver = probe = None
    bag = BagWriter(tmp_path / "bag").open()
    try:
        driver = NuskinDriverNode(
            context=context, parameter_overrides=[Parameter("port", value=str(link))]
        )
        probe = rclpy.create_node("probe", context=context)
        # as the recorder does: the serialized message, written unchanged into the bag
        raw: list[bytes] = []
        probe.create_subscription(SensorPacket, "packets", raw.append, SENSOR_STREAM_QOS, raw=True)
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(driver)
        executor.add_node(probe)

        def spin_until(predicate, timeout_s=8.0):
            end = time.monotonic() + timeout_s
            while time.monotonic() < end and not predicate():
                executor.spin_once(timeout_sec=0.01)
            return predicate()

        assert spin_until(lambda: driver.reader.state == LinkState.CONNECTED)
        os.write(master, encode_words(TAXEL, VALUE, FLAG))
        assert spin_until(lambda: _words(raw) >= len(TAXEL))
        for data in raw:
            bag.write_raw(PACKETS, time.time_ns(), data, "ext_sense_msgs/msg/SensorPacket")
    finally:
        bag.close()
        for node in (driver, probe):
            if node is not None:
                node.destroy_node()
        rclpy.try_shutdown(context=context)
        os.close(master)
        os.close(slave)

    lines = _csv_of_bag(tmp_path / "bag")
    assert lines[0] == "word,polarity,taxel,value,flag"
    expected = [
        f"{k},0,{t},{v},{f}" for k, (t, v, f) in enumerate(zip(TAXEL, VALUE, FLAG, strict=True))
    ]
    assert lines[1:] == expected  # polarity 'ignore' (0), the bit as it was sent


def _words(raw: list[bytes]) -> int:
    """Receiver words in the raw packets (4 bytes each)."""
    from rclpy.serialization import deserialize_message

    from ext_sense_msgs.msg import SensorPacket

    return sum(len(deserialize_message(r, SensorPacket).data) // 4 for r in raw)


def test_bag_batches_built_with_a_flag_keep_it_and_without_one_leave_it_empty(tmp_path):
    with BagWriter(tmp_path / "bag") as bag:
        bag.write(TOPIC, 1, taxel_event_batch(0, TAXEL, [0] * 5, VALUE, [0] * 5, flag=FLAG))
        bag.write(TOPIC, 2, taxel_event_batch(5, [9], [1], [3], [0]))
    with BagReader(tmp_path / "bag") as reader:
        msgs = [m for _, m in reader.messages([TOPIC])]
    assert np.asarray(msgs[0].flag).tolist() == FLAG
    assert np.asarray(msgs[1].flag).size == 0  # a source without the bit: empty, not zeros


@pytest.mark.parametrize(("flag", "match"), [([1, 0], "one length"), ([0, 2, 1, 1, 0], "0 or 1")])
def test_bag_batches_refuse_a_bad_flag(flag, match):
    from ext_sense_bags.errors import BagError

    with pytest.raises(BagError, match=match):
        taxel_event_batch(0, TAXEL, [0] * 5, VALUE, [0] * 5, flag=flag)
