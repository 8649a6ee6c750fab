"""The decision log the behaviours keep: bounded, every decision passed to the sink."""

from __future__ import annotations


def test_decision_log_is_bounded():
    from ext_sense_behaviours.decisions import DecisionLog
    from ext_sense_behaviours.handover import HandoverAction, HandoverState

    seen = []
    log = DecisionLog(seen.append, max_entries=5)
    for i in range(12):
        log.record(i, HandoverState.HOLDING, HandoverAction.NONE, f"n{i}")
    assert [d.reason for d in log.entries] == [f"n{i}" for i in range(7, 12)]
    assert len(seen) == 12
