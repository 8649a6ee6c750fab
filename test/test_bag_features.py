"""A packet bag played through the graph into ``RecorderNode``: the same windows as the bag itself.

The simulator's bag is the packet bag the graphs play; playing and recording it must lose nothing.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from rosutil import spinning, wait_for

PACKETS = "/extsense/nuskin/packets"
TRUTH = "/extsense/ground_truth"


@pytest.mark.ros
def test_recorded_bag_windows_equal_the_dataset_windows(tmp_path):
    from rclpy.parameter import Parameter

    from ext_sense.nodes.bag_player import BagPlayerNode
    from ext_sense.nodes.recorder import RecorderNode
    from ext_sense_bags import BagReader
    from ext_sense_perception.data.bags import window_set_from_bag
    from ext_sense_sim.run import run_scene
    from ext_sense_sim.scene import load_scene

    # trials 0.6 s apart, so no neighbouring trial reaches a window and the match is exact
    scene = dataclasses.replace(load_scene("tap_rod30_nuskin"), trial_s=0.6)
    run_scene(scene, tmp_path / "sim", trials=3, formats=("npz", "bag"))
    packets = tmp_path / "sim" / "bag"
    with BagReader(packets) as bag:
        sent = {t: s.count for t, s in bag.topics.items() if t in (PACKETS, TRUTH)}
    recorded = tmp_path / "recorded"
    with spinning(
        lambda context: RecorderNode(
            context=context,
            parameter_overrides=[
                Parameter("bag", value=str(recorded)),
                Parameter("topics", value=[PACKETS, TRUTH]),
            ],
        ),
        lambda context: BagPlayerNode(
            context=context,
            parameter_overrides=[
                Parameter("bag", value=str(packets)),
                Parameter("rate", value=1.0),  # flat out overruns the best-effort depth
                Parameter("start_delay_s", value=1.0),
            ],
        ),
    ) as (recorder, player):
        assert wait_for(player.finished.is_set, 15.0)
        assert not player.error
        assert wait_for(lambda: recorder.received == sent, 5.0), (recorder.received, sent)
    ws, counts = window_set_from_bag(recorded)
    ref, _ = window_set_from_bag(packets)
    assert counts.labelled == counts.truths == 3
    assert counts.undecodable == counts.bad_messages == 0
    np.testing.assert_array_equal(ws.X, ref.X)
    np.testing.assert_array_equal(ws.y, ref.y)
