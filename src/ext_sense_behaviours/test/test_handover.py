"""Handover state machine: opens only after N consecutive stable estimates; safe otherwise."""

from __future__ import annotations

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from ext_sense_behaviours.errors import BehaviourError
from ext_sense_behaviours.handover import (
    HandoverAction,
    HandoverConfig,
    HandoverMachine,
    HandoverState,
)
from ext_sense_runtime.records import Estimate
from ext_sense_runtime.stamps import MS


def est(p: float, provisional: bool = False, task: str = "handover_stability") -> Estimate:
    return Estimate(task, 0, provisional=provisional, stability_probability=p)


def run(machine: HandoverMachine, probabilities, provisional=None):
    machine.start(0)
    actions = []
    for i, p in enumerate(probabilities):
        prov = bool(provisional[i]) if provisional else False
        actions.append(machine.on_estimate(est(p, prov), (i + 1) * 100 * MS).action)
    return actions


def test_opens_after_n_consecutive_stable_estimates():
    machine = HandoverMachine(HandoverConfig(threshold=0.8, consecutive=3))
    actions = run(machine, [0.9, 0.95, 0.5, 0.9, 0.85, 0.99])
    assert actions == ["NONE", "NONE", "NONE", "NONE", "NONE", "OPEN_GRIPPER"]
    assert machine.state == HandoverState.RELEASING
    reasons = [d.reason for d in machine.log.entries]
    assert "streak reset to 0/3" in reasons[3]
    assert "for 3 consecutive estimates" in reasons[-1]


def test_provisional_never_counts_unless_configured():
    probs = [0.99] * 5
    machine = HandoverMachine(HandoverConfig(consecutive=2))
    actions = run(machine, probs, provisional=[True] * 5)
    assert "OPEN_GRIPPER" not in actions
    assert machine.state == HandoverState.HOLDING
    assert all("provisional" in d.reason for d in machine.log.entries[1:])
    machine = HandoverMachine(HandoverConfig(consecutive=2, accept_provisional=True))
    assert run(machine, probs, provisional=[True] * 5)[1] == "OPEN_GRIPPER"
    assert "provisional accepted" in machine.log.entries[2].reason


@pytest.mark.parametrize("bad", [math.nan, -0.1, 1.5])
def test_invalid_probability_resets_the_streak(bad):
    machine = HandoverMachine(HandoverConfig(consecutive=2))
    assert run(machine, [0.9, bad, 0.9]) == ["NONE", "NONE", "NONE"]
    assert "invalid P(stable)" in machine.log.entries[2].reason


def test_other_tasks_are_ignored():
    machine = HandoverMachine(HandoverConfig(consecutive=1))
    machine.start(0)
    d = machine.on_estimate(est(0.99, task="tap_localization"), 1)
    assert d.action == "NONE"
    assert "task 'tap_localization'" in d.reason


def test_safety_timeout_keeps_holding():
    machine = HandoverMachine(HandoverConfig(consecutive=2, timeout_ns=1000 * MS))
    machine.start(0)
    machine.on_estimate(est(0.9), 100 * MS)
    assert machine.on_tick(999 * MS) is None
    d = machine.on_tick(1000 * MS)
    assert d.state == "TIMED_OUT"
    assert d.action == "HOLD"
    assert "keep holding" in d.reason
    assert machine.on_estimate(est(0.99), 1100 * MS).action == "NONE"


def test_release_completes_or_faults():
    cfg = HandoverConfig(consecutive=1, release_timeout_ns=500 * MS)
    machine = HandoverMachine(cfg)
    machine.start(0)
    machine.on_estimate(est(0.9), 0)
    assert machine.on_gripper(False, 100 * MS) is None
    assert machine.on_gripper(True, 200 * MS).state == "RELEASED"
    machine = HandoverMachine(cfg)
    machine.start(0)
    machine.on_estimate(est(0.9), 0)
    d = machine.on_tick(500 * MS)
    assert d.state == "FAULT"
    assert "did not report open" in d.reason


def test_fault_while_holding_is_safe():
    machine = HandoverMachine()
    machine.start(0)
    d = machine.on_fault("No answer from Robotiq slave 9", 5)
    assert d.state == "FAULT"
    assert d.action == "HOLD"
    assert "holding safe" in d.reason
    assert machine.on_estimate(est(1.0), 6).action == "NONE"


def test_status_after_an_ambiguous_error_records_the_real_finger_state():
    # the open command went out, then the link failed: outcome unknown until a status read
    machine = HandoverMachine(HandoverConfig(consecutive=1))
    machine.start(0)
    assert machine.on_estimate(est(0.9), 1).action == "OPEN_GRIPPER"
    d = machine.on_fault("Reply CRC mismatch", 2)
    assert d.state == "FAULT"
    assert "outcome unknown" in d.reason
    assert machine.awaiting_status
    assert machine.on_status_after_fault(False, False, "moving", 3) is None  # still moving
    d = machine.on_status_after_fault(True, True, "at requested position, gPO=0", 4)
    assert d.state == "RELEASED"
    assert "open command was carried out" in d.reason
    assert not machine.awaiting_status
    assert machine.on_status_after_fault(True, True, "again", 5) is None  # read once


def test_status_after_a_fault_with_the_object_held_stays_in_fault():
    machine = HandoverMachine(HandoverConfig(consecutive=1))
    machine.start(0)
    machine.on_estimate(est(0.9), 1)
    machine.on_fault("No answer from Robotiq slave 9", 2)
    d = machine.on_status_after_fault(False, True, "holding an object, gPO=150", 3)
    assert (d.state, d.action) == ("FAULT", "HOLD")
    assert "still held" in d.reason
    assert "gPO=150" in d.reason
    assert machine.start(4).state == "FAULT"  # still only an operator reset leaves it


def test_only_an_explicit_reset_leaves_fault():
    machine = HandoverMachine(HandoverConfig(consecutive=1))
    machine.start(0)
    machine.on_fault("gFLT=0x0e", 1)
    assert machine.start(2).state == "FAULT"
    assert machine.on_tick(10**12) is None
    assert machine.reset(3).state == "IDLE"
    assert machine.start(4).state == "HOLDING"
    assert machine.on_estimate(est(0.9), 5).action == "OPEN_GRIPPER"


def test_sink_sees_every_decision():
    seen = []
    machine = HandoverMachine(HandoverConfig(consecutive=2), sink=seen.append)
    run(machine, [0.9, 0.9])
    assert seen == machine.log.entries
    assert len(seen) == 3
    assert "streak 1/2" in str(seen[1])


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"threshold": 0.0}, "'threshold' parameter must be in"),
        ({"consecutive": 0}, "'consecutive' parameter must be >= 1"),
        ({"timeout_ns": 0}, "'timeout_ns' parameter must be > 0"),
    ],
)
def test_config_checked(kwargs, match):
    with pytest.raises(BehaviourError, match=match):
        HandoverConfig(**kwargs)


@given(
    st.lists(st.tuples(st.floats(0, 1), st.booleans()), min_size=0, max_size=40),
    st.integers(1, 5),
    st.floats(0.05, 1.0),
)
def test_property_opens_exactly_when_the_last_n_counted_estimates_are_stable(seq, n, threshold):
    machine = HandoverMachine(HandoverConfig(threshold=threshold, consecutive=n))
    machine.start(0)
    counted: list[float] = []
    for i, (p, prov) in enumerate(seq):
        d = machine.on_estimate(est(p, prov), i + 1)
        if machine.state != HandoverState.HOLDING and d.action != "OPEN_GRIPPER":
            break
        if not prov:
            counted.append(p)
        should_open = len(counted) >= n and all(q >= threshold for q in counted[-n:])
        assert (d.action == HandoverAction.OPEN_GRIPPER.name) == should_open
        if should_open:
            assert all(q >= threshold for q in counted[-n:])
            break
