"""The real Panda food-poking bags replayed through the arm adapter into the food behaviour.

Contact detection must fire on the first state message whose external-force norm reaches
10 N (never later than one message after it), and never on the traces that stayed below it;
the NUSkin capture of each trial must line up with the bag in time.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from franka_replay import FrankaTrace, ReplayArm, read_franka_bag

from ext_sense_behaviours.errors import BehaviourError
from ext_sense_behaviours.execution import FoodProbe
from ext_sense_behaviours.food import FoodConfig, FoodMachine, FoodState, StopReason
from ext_sense_drivers.nuskin.tact import read_tact

pytestmark = pytest.mark.real_data


@pytest.fixture(scope="module")
def traces(food_poking_dir: Path) -> dict[str, FrankaTrace]:
    bags = sorted(food_poking_dir.glob("*.bag"))
    assert len(bags) == 45
    return {bag.stem: read_franka_bag(bag) for bag in bags}


def replay(trace: FrankaTrace, config: FoodConfig) -> tuple[FoodMachine, ReplayArm]:
    arm = ReplayArm(trace.states())
    machine = FoodMachine(config)
    probe = FoodProbe(machine, arm)
    probe.start()
    while machine.state == FoodState.LOWERING and arm.index + 1 < len(trace.t_ns):
        probe.step(int(trace.stamp_ns[arm.index + 1]))
    return machine, arm


def test_bags_hold_franka_state_at_about_30_hz(traces):
    for name, trace in traces.items():
        assert len(trace.t_ns) > 80, name
        rate = (len(trace.t_ns) - 1) / ((trace.t_ns[-1] - trace.t_ns[0]) / 1e9)
        assert 25 < rate < 35, (name, rate)
        assert np.all(np.diff(trace.t_ns) > 0)
        # header stamps precede arrival by a few tens of ms
        assert 0 <= np.median(trace.t_ns - trace.stamp_ns) < 60e6, name


def test_contact_fires_within_one_message_of_the_first_sample_over_10_n(traces):
    fired = 0
    for name, trace in traces.items():
        machine, arm = replay(trace, FoodConfig(stop_height_m=0.0))  # detection only
        over = np.flatnonzero(trace.force_norm_n >= 10.0)
        stop_index = arm.first_index("stop")
        if over.size == 0:
            assert stop_index is None, f"{name}: fired below 10 N"
            assert machine.detector.fired_at is None
            continue
        fired += 1
        assert stop_index is not None, f"{name}: no contact although |F| reached 10 N"
        assert 0 <= stop_index - int(over[0]) <= 1, (name, stop_index, int(over[0]))
        assert machine.result is None
        assert machine.state == FoodState.COLLECTING
        assert machine.log.entries[-1].reason.startswith("contact: |F|=")
    # apple 11 of 11 and 7 of the 11 watermelons reached 10 N; water, tofu, empty never did.
    assert fired == 18


def test_traces_without_contact_stop_at_the_preset_height(traces):
    for name, trace in traces.items():
        if trace.force_norm_n.max() >= 10.0:
            continue
        machine, arm = replay(trace, FoodConfig(stop_height_m=0.1045))
        assert arm.first_index("stop") is not None, name
        assert machine.stop_reason == StopReason.PRESET_HEIGHT, name


def test_nuskin_capture_lines_up_with_the_bag(traces, food_poking_dir):
    start_offsets, stop_offsets, rate_ratios = [], [], []
    for name, trace in traces.items():
        tact = read_tact(food_poking_dir / f"{name}.tact")
        t0, t1 = trace.t_ns[0] / 1e9, trace.t_ns[-1] / 1e9
        start_offsets.append(tact.start_s - t0)
        stop_offsets.append(tact.stop_s - t1)
        # every NUSkin word lies within the bag's span (10 ms stamp resolution + 50 ms slack)
        assert tact.t_s.min() >= t0 - 0.06, name
        assert tact.t_s.max() <= t1 + 0.06, name
        over = np.flatnonzero(trace.force_norm_n >= 10.0)
        if over.size:
            contact_s = trace.t_ns[over[0]] / 1e9
            before = np.count_nonzero((tact.t_s >= contact_s - 1.0) & (tact.t_s < contact_s))
            baseline = np.count_nonzero(tact.t_s < tact.start_s + 0.5) / 0.5
            rate_ratios.append(before / baseline)
    start_offsets, stop_offsets = np.array(start_offsets), np.array(stop_offsets)
    # the capture starts and stops with the bag: within 50 ms at both ends, every trial
    assert np.all(np.abs(start_offsets) <= 0.05), start_offsets
    assert np.all(np.abs(stop_offsets) <= 0.05), stop_offsets
    # and the fork's entry into the food shows in the taxels in the second before 10 N
    assert len(rate_ratios) == 18
    assert min(rate_ratios) > 1.1, rate_ratios


def test_missing_bag_and_topic(tmp_path, food_poking_dir):
    with pytest.raises(BehaviourError, match="does not exist"):
        read_franka_bag(tmp_path / "absent.bag")
    with pytest.raises(BehaviourError, match="has no topic '/nope'"):
        read_franka_bag(food_poking_dir / "apple_zero_0.bag", topic="/nope")
    corrupt = tmp_path / "corrupt.bag"
    corrupt.write_bytes(b"#ROSBAG V2.0\n" + b"\x00" * 64)
    with pytest.raises(BehaviourError, match="Cannot read FrankaState"):
        read_franka_bag(corrupt)
