"""The window node's wake-up deadlines for a quiet stream."""

from __future__ import annotations

from ext_sense_perception.online.deadline import (
    MARGIN_NS,
    next_wake_ns,
    stall_change_ns,
    window_due_wall_ns,
)
from ext_sense_perception.online.liveness import StreamLiveness
from ext_sense_runtime.stamps import MS


class FakeClock:
    def __init__(self) -> None:
        self.now = 1_000 * MS

    def __call__(self) -> int:
        return self.now


def _liveness(clock: FakeClock) -> StreamLiveness:
    return StreamLiveness("/events", 1000.0, 100 * MS, 500 * MS, 100 * MS, clock=clock)


def test_a_window_is_due_when_the_stream_clock_reaches_its_end_plus_slack():
    # data of stream time 40 ms arrived at host 1000 ms; the window ends at 250 ms
    assert window_due_wall_ns(1000 * MS, 40 * MS, 250 * MS, MS // 2) == 1210 * MS + MS // 2


def test_nothing_pending_and_no_stream_to_watch_means_no_wake():
    kw = dict(data_wall_ns=5 * MS, data_stream_ns=5 * MS, slack_ns=0, timeout_ns=500 * MS)
    assert next_wake_ns(due_ns=None, pending=False, stall_ns=None, **kw) is None
    assert (
        next_wake_ns(
            data_wall_ns=None,
            data_stream_ns=None,
            due_ns=None,
            pending=False,
            slack_ns=0,
            timeout_ns=1,
            stall_ns=None,
        )
        is None
    )


def test_the_earliest_of_window_end_timeout_and_stall_wins():
    kw = dict(data_wall_ns=1000 * MS, data_stream_ns=40 * MS, slack_ns=0, timeout_ns=500 * MS)
    assert next_wake_ns(due_ns=250 * MS, pending=True, stall_ns=None, **kw) == 1210 * MS
    assert next_wake_ns(due_ns=250 * MS, pending=True, stall_ns=1100 * MS, **kw) == 1100 * MS
    # a window far ahead (food: 8 s): the stream timeout comes first
    assert next_wake_ns(due_ns=9000 * MS, pending=True, stall_ns=None, **kw) == 1500 * MS
    # BioTac: windows close on frames only; pending windows still time out
    assert next_wake_ns(due_ns=None, pending=True, stall_ns=None, **kw) == 1500 * MS


def test_stall_deadlines_follow_the_liveness_thresholds():
    clock = FakeClock()
    live = _liveness(clock)
    assert stall_change_ns(live, streaming=True) is None  # nothing arrived yet
    live.on_message(stamp_ns=7 * MS, wall_ns=7 * MS)
    arrived = clock.now
    assert stall_change_ns(live, streaming=False) is None  # silence is normal
    warn_at = stall_change_ns(live, streaming=True)
    assert warn_at == arrived + 100 * MS + MARGIN_NS
    clock.now = warn_at
    live.update(streaming=True)
    assert live.stalled  # the deadline lands after the threshold, not on it
    error_at = stall_change_ns(live, streaming=True)
    assert error_at == arrived + 500 * MS + MARGIN_NS
    clock.now = error_at
    assert stall_change_ns(live, streaming=True) is None  # ERROR reached: wait for data
