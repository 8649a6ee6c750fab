"""Integer-nanosecond sample times of BioTac frames."""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest

from ext_sense_drivers.biotac.clock import (
    FRAME_PERIOD_NS,
    PAC_PERIOD_NS,
    FrameClock,
    pac_offset_ns,
    pac_offsets_ns,
    pac_times_ns,
    transmission_ns,
)
from ext_sense_drivers.biotac.errors import BioTacError


def test_offsets_are_nanoseconds():
    # The public ROS 1 driver got this unit wrong; 1/2200 s is 454545.45 ns.
    offsets = pac_offsets_ns()
    assert offsets.dtype == np.int64
    assert offsets.shape == (22,)
    assert offsets[0] == 0
    assert offsets[1] == 454_545
    assert offsets[2] == 909_091  # 909090.9 rounds up
    assert offsets[21] == 9_545_455
    # The 22 samples fill exactly one 10 ms frame: sample 22 is the next frame's sample 0.
    assert pac_offset_ns(22) == FRAME_PERIOD_NS == 10_000_000
    assert PAC_PERIOD_NS == 454_545


def test_offsets_exact_to_half_a_nanosecond_over_long_runs():
    for i in [*range(0, 100), 2199, 2200, 10**6 + 3]:
        exact = Fraction(i * 10**9, 2200)
        assert abs(pac_offset_ns(i) - exact) <= Fraction(1, 2)
    # Frame-relative offsets plus whole frames equal the global rounding: no accumulated error.
    k = np.arange(1000)[:, None]
    assert (
        k * FRAME_PERIOD_NS + pac_offsets_ns() == pac_offsets_ns(22_000).reshape(1000, 22)
    ).all()


def test_pac_times_shape():
    t = pac_times_ns(np.array([0, 10_000_000], dtype=np.int64))
    assert t.shape == (2, 22)
    assert t[1, 0] == 10_000_000
    assert (np.diff(t.ravel()) > 0).all()


@pytest.mark.parametrize(("i", "rate"), [(-1, 2200), (1, 0)])
def test_offset_rejects_bad_arguments(i, rate):
    with pytest.raises(BioTacError, match="must be"):
        pac_offset_ns(i, rate)


def test_frame_clock_recovers_first_sample_times_within_the_bound():
    rng = np.random.default_rng(7)
    period, lead = FRAME_PERIOD_NS, FRAME_PERIOD_NS + 1_000_000
    t0 = 5_000_000_000
    n = 2000
    true_first = t0 + np.arange(n) * period
    # Latency: lead + 0..3 ms of jitter, a 20 ms stall now and then.
    jitter = rng.integers(0, 3_000_000, n)
    jitter[rng.random(n) < 0.01] += 20_000_000
    arrival = true_first + lead + jitter
    clock = FrameClock(period, lead, window=200)
    stamps = np.array([clock.update(int(a)) for a in arrival])
    err = stamps - true_first
    # Never early; late by at most the smallest jitter in the window (after the first window).
    assert (err >= 0).all()
    win_min = np.array([jitter[max(0, k - 199) : k + 1].min() for k in range(n)])
    assert (err == win_min).all()
    assert err[200:].max() < 200_000


def test_frame_clock_follows_gaps_and_restarts():
    clock = FrameClock(FRAME_PERIOD_NS, lead_ns=0)
    assert clock.update(1_000) == 1_000
    assert clock.update(10_001_000) == 1_000 + FRAME_PERIOD_NS
    # Three frames missing: the next one is frame 5.
    assert clock.update(50_001_000, gap=3) == 1_000 + 5 * FRAME_PERIOD_NS
    assert clock.frame_index == 5
    assert clock.update(900_000_000, restart=True) == 900_000_000
    assert clock.frame_index == 0


def test_frame_clock_rejects_bad_parameters():
    with pytest.raises(BioTacError, match="'frame_period_ns'"):
        FrameClock(0)
    with pytest.raises(BioTacError, match="'window'"):
        FrameClock(window=0)


def test_transmission_time():
    assert transmission_ns(96, 1_000_000) == 960_000
    assert transmission_ns(96, 115_200) == 8_333_334
