"""One meaning of WARN, ERROR and the stall counts for every liveness status."""

from ext_sense_runtime.diagnostics import Level
from ext_sense_runtime.stalls import StallTracker


def test_a_stall_warns_then_errors_and_data_ends_it():
    stall = StallTracker(warn_ns=100, error_ns=500)
    assert stall.level(1_000) is Level.OK
    assert stall.begin(1_000)
    assert not stall.begin(1_050)  # one stall in progress, counted once
    assert stall.level(1_400) is Level.WARN
    assert stall.level(1_501) is Level.ERROR
    assert stall.end(1_700) == 700
    assert (stall.stalls, stall.longest_stall_ns, stall.level(1_700)) == (1, 700, Level.OK)
    assert stall.end(1_800) is None


def test_a_dropped_stall_is_counted_but_not_measured():
    stall = StallTracker(warn_ns=100, error_ns=500)
    stall.begin(0)
    stall.drop()
    assert (stall.stalls, stall.longest_stall_ns, stall.stalled) == (1, 0, False)
