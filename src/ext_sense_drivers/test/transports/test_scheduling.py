"""The reader thread's scheduling: SCHED_FIFO when granted, a raised nice or nothing when not."""

from __future__ import annotations

import threading

import pytest

from ext_sense_drivers.transports.link_config import LinkConfig
from ext_sense_drivers.transports.reader import StreamReader
from ext_sense_drivers.transports.scheduling import (
    FALLBACK_NICE,
    Scheduling,
    raise_thread_priority,
)


def _refuse(*_: object) -> None:
    raise PermissionError(1, "Operation not permitted")


def test_zero_leaves_the_thread_alone():
    called = []
    got = raise_thread_priority(0, set_fifo=lambda *a: called.append(a))
    assert got == Scheduling("default", 0, 0)
    assert not called
    assert "left as is" in got.describe()


def test_fifo_granted_is_reported_as_granted():
    calls = []
    got = raise_thread_priority(50, tid=1234, set_fifo=lambda tid, p: calls.append((tid, p)))
    assert calls == [(1234, 50)]
    assert got.granted
    assert got.describe() == "SCHED_FIFO 50"


def test_fifo_refused_falls_back_to_a_raised_nice():
    niced = []
    got = raise_thread_priority(
        50,
        tid=7,
        set_fifo=_refuse,
        set_nice=lambda tid, n: niced.append((tid, n)),
        get_nice=lambda tid: 0,
    )
    assert niced == [(7, FALLBACK_NICE)]
    assert got.policy == "nice"
    assert got.value == FALLBACK_NICE
    assert not got.granted
    assert "SCHED_FIFO refused" in got.reason
    assert got.describe().startswith(f"SCHED_OTHER nice {FALLBACK_NICE} (asked SCHED_FIFO 50")


def test_nothing_permitted_still_returns_and_says_why():
    got = raise_thread_priority(50, tid=7, set_fifo=_refuse, set_nice=_refuse, get_nice=lambda t: 0)
    assert got.policy == "default"
    assert got.requested == 50
    assert "refused" in got.reason
    assert "nice left at 0" in got.reason


def test_a_nice_already_better_is_not_made_worse():
    niced = []
    got = raise_thread_priority(
        10, set_fifo=_refuse, set_nice=lambda t, n: niced.append(n), get_nice=lambda t: -15
    )
    assert not niced
    assert got.policy == "default"


def test_priority_above_99_is_clamped():
    calls = []
    raise_thread_priority(500, tid=1, set_fifo=lambda tid, p: calls.append(p))
    assert calls == [99]


def test_reader_thread_records_what_it_got_and_never_fails(monkeypatch):
    """Whatever this machine permits, the reader runs and says what it got."""
    import ext_sense_drivers.transports.reader as reader_mod

    seen = []

    def fake(priority: int) -> Scheduling:
        seen.append((priority, threading.current_thread().name))
        return Scheduling("default", 0, priority, "refused in this test")

    monkeypatch.setattr(reader_mod, "raise_thread_priority", fake)
    reader = LinkConfig(transport="serial", port="loop://", reader_priority=30).make_reader()
    assert isinstance(reader, StreamReader)
    assert reader.priority == 30
    reader.start()
    try:
        for _ in range(200):
            if reader.scheduling is not None:
                break
            threading.Event().wait(0.01)
        assert reader.scheduling == Scheduling("default", 0, 30, "refused in this test")
        # the starting (draining) thread 10 below, then the reader thread itself
        assert seen[0] == (20, threading.current_thread().name)
        assert seen[1][0] == 30
        assert seen[1][1].startswith("reader ")
        assert reader.drainer_scheduling == Scheduling("default", 0, 20, "refused in this test")
        assert reader.alive
    finally:
        reader.stop()


def test_bad_reader_priority_is_refused_by_the_config():
    with pytest.raises(Exception, match="'reader_priority' parameter must be in"):
        LinkConfig(transport="serial", port="loop://", reader_priority=120).make_reader()


def test_a_process_started_from_a_real_time_thread_runs_at_normal_priority():
    """Reset on fork: e.g. the simulator's trials-ahead child, started by the FIFO pacer."""
    import os
    import subprocess
    import sys

    out: dict[str, object] = {}

    def run() -> None:
        out["got"] = raise_thread_priority(20)
        out["child"] = subprocess.run(
            [sys.executable, "-c", "import os; print(os.sched_getscheduler(0))"],
            capture_output=True,
            text=True,
            check=True,
        ).stdout.strip()

    thread = threading.Thread(target=run)
    thread.start()
    thread.join()
    if not out["got"].granted:
        pytest.skip(f"SCHED_FIFO not granted here: {out['got'].describe()}")
    assert out["child"] == str(os.SCHED_OTHER)
