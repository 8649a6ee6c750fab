from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ext_sense_perception.errors import PerceptionError
from ext_sense_perception.online.pac_windower import PacWindower
from ext_sense_perception.online.window import WindowConfig, bin_events, window_from_recording
from ext_sense_perception.online.windowers import EventWindower
from ext_sense_perception.profiles import PAC_PERIOD_NS
from ext_sense_runtime.enums import Sensor, Task
from ext_sense_runtime.records import EventBlock
from ext_sense_runtime.stamps import MS

EPOCH = 1_700_000_000_000_000_000  # epoch nanoseconds: must not lose precision anywhere


def _tap_stream(onset: int, rng: np.random.Generator, background_s: float = 1.0):
    """Sparse background events plus a dense burst at ``onset``."""
    bg = (
        np.sort(rng.integers(0, int(background_s * 1e9), 100))
        if background_s > 0
        else np.empty(0, np.int64)
    )
    burst = onset + np.sort(rng.integers(0, 30 * MS, 400))
    t = np.sort(np.concatenate([bg, burst])) + EPOCH
    tax = rng.integers(1, 81, len(t)).astype(np.uint16)
    pol = rng.choice(np.array([-1, 1], np.int8), len(t))
    return t.astype(np.int64), tax, pol


def _feed_in_batches(w: EventWindower, t, tax, pol, size: int = 50):
    out = []
    for i in range(0, len(t), size):
        out += w.feed(EventBlock.of(t[i : i + size], tax[i : i + size], pol[i : i + size]))
    return out


def test_event_windower_emits_provisional_then_final_windows_with_pre_onset():
    rng = np.random.default_rng(1)
    t, tax, pol = _tap_stream(500 * MS, rng)
    w = EventWindower()
    out = _feed_in_batches(w, t, tax, pol)
    out += w.advance(EPOCH + 2_000 * MS)
    onsets = {win.onset_ns for win in out}
    assert len(onsets) == 1
    onset = onsets.pop()
    assert abs(onset - (EPOCH + 500 * MS)) < 1 * MS
    posts = [win.post_onset_ns for win in out]
    assert posts == [25 * MS, 50 * MS, 100 * MS, 150 * MS, 250 * MS]
    assert [win.provisional for win in out] == [True] * 4 + [False]
    final = out[-1]
    assert final.data.shape == (80, 300)
    assert final.data.dtype == np.float32
    assert final.sample_period_ns == 1 * MS
    assert final.pre_onset_ns == 50 * MS
    # every event of the window is in it, signed
    inside = (t >= onset - 50 * MS) & (t < onset + 250 * MS)
    assert final.data.sum() == pytest.approx(float(pol[inside].sum()))
    assert np.abs(final.data).sum() >= 1
    assert w.counters.onsets == 1
    assert w.counters.windows == 1
    assert w.counters.provisional_windows == 4


def test_event_windower_batching_does_not_change_windows():
    rng = np.random.default_rng(2)
    t, tax, pol = _tap_stream(300 * MS, rng)
    a = EventWindower()
    b = EventWindower()
    wa = _feed_in_batches(a, t, tax, pol, size=7) + a.advance(EPOCH + 2_000 * MS)
    wb = _feed_in_batches(b, t, tax, pol, size=500) + b.advance(EPOCH + 2_000 * MS)
    assert [x.onset_ns for x in wa] == [x.onset_ns for x in wb]
    for x, y in zip(wa, wb, strict=True):
        np.testing.assert_array_equal(x.data, y.data)


def test_debounce_merges_bursts_closer_than_debounce():
    rng = np.random.default_rng(3)
    t1, tax1, pol1 = _tap_stream(200 * MS, rng, background_s=0.0)
    burst2 = t1[-100:] + 200 * MS  # a second burst 200 ms later: inside the 500 ms debounce
    t = np.concatenate([t1, burst2])
    tax = np.concatenate([tax1, tax1[-100:]])
    pol = np.concatenate([pol1, pol1[-100:]])
    w = EventWindower()
    out = _feed_in_batches(w, t, tax, pol) + w.advance(EPOCH + 3_000 * MS)
    assert w.counters.onsets == 1
    assert sum(not x.provisional for x in out) == 1
    w2 = EventWindower(WindowConfig.for_task("tap", "nuskin", debounce_ns=100 * MS))
    _feed_in_batches(w2, t, tax, pol)
    assert w2.counters.onsets == 2


def test_bad_taxels_are_counted_and_dropped():
    w = EventWindower()
    t = EPOCH + np.arange(5, dtype=np.int64)
    w.feed(EventBlock.of(t, np.array([0, 81, 5, 6, 65535], np.uint16), np.ones(5, np.int8)))
    assert w.counters.bad_taxel_events == 3


def test_feed_rejects_mismatched_arrays_and_float_times():
    w = EventWindower()
    ones = np.ones(3, np.uint16)
    with pytest.raises(PerceptionError, match="one length"):
        w.feed(EventBlock(np.zeros(3, np.int64), np.ones(2, np.uint16), np.ones(3, np.int8), ones))
    with pytest.raises(PerceptionError, match="integer nanoseconds"):
        w.feed(EventBlock(np.zeros(3), ones, np.ones(3, np.int8), ones))
    # the record's own constructor refuses the same arrays before they reach a windower
    with pytest.raises(ValueError, match="one length"):
        EventBlock.of(np.zeros(3, np.int64), np.ones(2, np.uint16), np.ones(3, np.int8))
    with pytest.raises(ValueError, match="integer nanoseconds"):
        EventBlock.of(np.zeros(3), ones, np.ones(3, np.int8))


def test_flush_closes_pending_window_as_truncated():
    rng = np.random.default_rng(4)
    t, tax, pol = _tap_stream(100 * MS, rng, background_s=0.0)
    w = EventWindower(WindowConfig.for_task("tap", "nuskin", anytime_post_ns=()))
    assert _feed_in_batches(w, t, tax, pol) == []
    out = w.flush()
    assert len(out) == 1
    assert out[0].truncated
    assert not out[0].provisional
    assert w.counters.truncated_windows == 1
    assert w.flush() == []


def test_external_onset_for_food_window_two_to_eight_seconds():
    cfg = WindowConfig.for_task(Task.FOOD_IDENTIFICATION, Sensor.NUSKIN)
    assert cfg.profile.onset_source == "external"
    assert (cfg.pre_ns, cfg.post_ns) == (-2000 * MS, 8000 * MS)
    w = EventWindower(cfg)
    motion = EPOCH + 1_000 * MS
    assert w.mark_onset(motion)
    assert not w.mark_onset(motion + 10 * MS)  # debounced
    t = motion + np.array([1_000, 2_500, 7_900, 8_100], dtype=np.int64) * MS
    out = w.feed(
        EventBlock.of(t, np.array([1, 2, 3, 4], np.uint16), np.array([1, 1, -1, 1], np.int8))
    )
    out += w.advance(motion + 9_000 * MS)
    final = [x for x in out if not x.provisional]
    assert len(final) == 1
    win = final[0]
    assert win.start_ns == motion + 2_000 * MS
    assert win.data.shape == (80, 600)
    # only the events at 2.5 s and 7.9 s fall inside [2 s, 8 s)
    assert win.data[1].sum() == 1
    assert win.data[2].sum() == -1
    assert win.data[0].sum() == 0
    assert win.data[3].sum() == 0


def test_window_config_validation_names_parameter():
    with pytest.raises(PerceptionError, match="'post_ns'"):
        WindowConfig.for_task("tap", "nuskin", post_ns=-5)
    with pytest.raises(PerceptionError, match="'anytime_post_ns'"):
        WindowConfig.for_task("tap", "nuskin", anytime_post_ns=(300 * MS,))
    with pytest.raises(PerceptionError, match="'onset_source'"):
        WindowConfig.for_task("tap", "nuskin", onset_source="magic")
    with pytest.raises(PerceptionError, match="'task'"):
        WindowConfig.for_task("juggling", "nuskin")
    with pytest.raises(PerceptionError, match="'sensor'"):
        WindowConfig.for_task("tap", "camera")
    with pytest.raises(PerceptionError, match="nuskin"):
        EventWindower(WindowConfig.for_task("tap", "biotac"))


def _pac_stream(n_sensors: int = 2, seconds: float = 2.0, burst_at: int = 2200, seed: int = 0):
    rng = np.random.default_rng(seed)
    n = int(2200 * seconds)
    x = 2000 + rng.normal(0, 2, (n_sensors, n))
    k = np.arange(300)
    x[:, burst_at : burst_at + 300] += 300 * np.sin(k * 0.7) * np.exp(-k / 80)
    return x


def test_pac_windower_detects_burst_and_keeps_pre_onset():
    x = _pac_stream()
    w = PacWindower(n_sensors=2)
    out = []
    for i in range(0, x.shape[1], 22):
        out += w.feed(EPOCH + i * PAC_PERIOD_NS, x[:, i : i + 22])
    final = [o for o in out if not o.provisional]
    assert len(final) == 1
    win = final[0]
    onset_index = (win.onset_ns - EPOCH) / PAC_PERIOD_NS
    assert 2200 <= onset_index <= 2203
    assert win.data.shape == (2, (50 * MS + 250 * MS) // PAC_PERIOD_NS)
    pre = (50 * MS) // PAC_PERIOD_NS
    first = round(onset_index) - pre
    np.testing.assert_allclose(
        win.data[:, :10], x[:, first : first + 10].astype(np.float32), atol=1e-3
    )
    assert len(out) == 5


def test_pac_windower_fills_gaps_and_holds_invalid_samples():
    x = _pac_stream(n_sensors=1, seconds=6.0, burst_at=10_000)  # burst far after the fed frames
    w = PacWindower()
    w.feed(EPOCH, x[:, :22])
    w.feed(EPOCH + 44 * PAC_PERIOD_NS, x[:, 44:66])  # one frame lost
    assert w.counters.gap_samples == 22
    valid = np.ones((1, 22), bool)
    valid[0, 3] = False
    w.feed(EPOCH + 66 * PAC_PERIOD_NS, x[:, 66:88], valid=valid)
    assert w.counters.invalid_samples == 1
    assert w.counters.onsets == 0


def test_pac_windower_rejects_nan_and_changed_period():
    w = PacWindower()
    with pytest.raises(PerceptionError, match="finite"):
        w.feed(EPOCH, np.array([1.0, np.nan]))
    w.feed(EPOCH, np.full(22, 2000.0))
    with pytest.raises(PerceptionError, match="'period_ns'"):
        w.feed(EPOCH + 22 * PAC_PERIOD_NS, np.full(22, 2000.0), period_ns=1000)
    with pytest.raises(PerceptionError, match="shape"):
        w.feed(EPOCH, np.zeros((3, 22)))


def test_window_from_recording_matches_online_window():
    rng = np.random.default_rng(5)
    t, tax, pol = _tap_stream(400 * MS, rng)
    w = EventWindower()
    online = next(
        x
        for x in _feed_in_batches(w, t, tax, pol) + w.advance(EPOCH + 2_000 * MS)
        if not x.provisional
    )
    offline = window_from_recording(w.config, online.onset_ns, events=EventBlock.of(t, tax, pol))
    np.testing.assert_array_equal(online.data, offline.data)
    assert offline.post_onset_ns == online.post_onset_ns


@settings(max_examples=60, deadline=None)
@given(
    st.lists(
        st.tuples(st.integers(0, 10_000_000), st.integers(0, 90), st.sampled_from([-1, 0, 1])),
        max_size=60,
    ),
    st.integers(1, 40),
)
def test_bin_events_conserves_signed_counts(events, n_bins):
    t = np.array([e[0] for e in events], np.int64) + EPOCH
    tax = np.array([e[1] for e in events], np.int64)
    pol = np.array([e[2] for e in events], np.int8)
    bin_ns = 250_000
    counts = bin_events(EventBlock.of(t, tax, pol), EPOCH, n_bins, bin_ns)
    inside = (t - EPOCH < n_bins * bin_ns) & (tax >= 1) & (tax <= 80)
    expected = np.where(pol[inside] < 0, -1, 1).sum() if inside.any() else 0
    assert counts.shape == (80, n_bins)
    assert counts.sum() == expected


def test_empty_and_single_event_windows():
    cfg = WindowConfig.for_task("tap", "nuskin")
    empty = window_from_recording(
        cfg, EPOCH, events=EventBlock.of(np.empty(0, np.int64), np.empty(0, np.uint16))
    )
    assert empty.data.shape == (80, 300)
    assert not empty.data.any()
    one = window_from_recording(
        cfg, EPOCH, events=EventBlock.of(np.array([EPOCH], np.int64), np.array([7], np.uint16))
    )
    assert one.data.sum() == 1
    assert one.data[6, 50] == 1  # 50 ms of pre-onset at 1 ms bins


@settings(max_examples=60, deadline=None)
@given(
    st.lists(
        st.tuples(
            st.integers(-2_000_000, 12_000_000), st.integers(0, 90), st.sampled_from([-1, 0, 1])
        ),
        max_size=80,
    ),
    st.integers(1, 40),
)
def test_bin_events_matches_per_event_reference(events, n_bins):
    t = np.array([e[0] for e in events], np.int64) + EPOCH
    tax = np.array([e[1] for e in events], np.int64)
    pol = np.array([e[2] for e in events], np.int8)
    bin_ns = 250_000
    expected = np.zeros((80, n_bins), np.float32)
    for ti, k, p in zip(t.tolist(), tax.tolist(), pol.tolist(), strict=True):
        b = (ti - EPOCH) // bin_ns
        if 1 <= k <= 80 and 0 <= b < n_bins:
            expected[k - 1, b] += -1.0 if p < 0 else 1.0
    got = bin_events(EventBlock.of(t, tax, pol), EPOCH, n_bins, bin_ns)
    assert got.dtype == np.float32
    np.testing.assert_array_equal(got, expected)


def test_joining_the_buffer_at_cuts_changes_no_window_and_stays_bounded(monkeypatch):
    # taps 700 ms apart fed in 1 ms chunks, as packets come: each tap's five cuts
    rng = np.random.default_rng(5)
    onsets = [(300 + 700 * i) * MS for i in range(9)]
    parts = [_tap_stream(o, rng, background_s=0.0) for o in onsets]
    t = np.concatenate([p[0] for p in parts])
    order = np.argsort(t, kind="stable")
    t, tax, pol = (np.concatenate([p[i] for p in parts])[order] for i in range(3))

    def run(w: EventWindower) -> list:
        out, sizes = [], []
        edges = np.searchsorted(t, EPOCH + np.arange(0, 7_000 * MS, MS))
        for lo, hi in itertools.pairwise(edges):
            if hi > lo:
                out += w.feed(EventBlock.of(t[lo:hi], tax[lo:hi], pol[lo:hi]))
                sizes.append(sum(c.size for c in w._chunks))
        return out + w.flush(), max(sizes)

    joined, most = run(EventWindower())
    monkeypatch.setattr(EventWindower, "_compact", lambda self: None)
    chunked, _ = run(EventWindower())
    assert len(joined) == len(chunked) >= 5 * (len(onsets) - 1)  # the last one is flushed
    for x, y in zip(joined, chunked, strict=True):
        assert (x.onset_ns, x.post_onset_ns, x.provisional) == (
            y.onset_ns,
            y.post_onset_ns,
            y.provisional,
        )
        np.testing.assert_array_equal(x.data, y.data)
    assert most <= 3 * 400  # about two taps' bursts at most: joining drops what is behind


def test_a_window_reaching_back_before_the_first_input_is_degraded_as_joined_mid_stream():
    """A consumer that joins while the rod rings sees a contact's tail as an onset (measured
    live: +184 ms, 14 cm off): a window beginning before the first data fed is degraded, so
    its estimate is not scored as a normal one; the next contact's window is whole and not."""
    rng = np.random.default_rng(5)
    t, tax, pol = _tap_stream(300 * MS, rng)
    second = EPOCH + 1_300 * MS + np.sort(rng.integers(0, 30 * MS, 400))
    t2 = np.concatenate([t, second])
    tax2 = np.concatenate([tax, rng.integers(1, 81, 400).astype(np.uint16)])
    pol2 = np.concatenate([pol, np.ones(400, np.int8)])
    joined = t2 >= EPOCH + 310 * MS  # the consumer's first data: 10 ms into the first burst
    w = EventWindower()
    out = _feed_in_batches(w, t2[joined], tax2[joined], pol2[joined])
    out += w.advance(EPOCH + 3_000 * MS)
    finals = [x for x in out if not x.provisional]
    assert len(finals) == 2
    late, whole = finals
    assert late.onset_ns >= EPOCH + 310 * MS  # the tail taken for an onset
    assert late.degraded
    assert late.degraded_reason.startswith("joined mid-stream")
    assert f"{(int(t2[joined][0]) - late.start_ns) / MS:.0f} ms" in late.degraded_reason
    assert all(x.degraded for x in out if x.onset_ns == late.onset_ns)  # provisional ones too
    assert not whole.degraded
    assert whole.degraded_reason == ""
    assert w._first_ns == int(t2[joined][0])
    assert w.counters.joined_mid_stream_windows == 5  # 4 provisional and the final

    # from the stream's start, the same contacts give whole windows
    w = EventWindower()
    out = _feed_in_batches(w, t2, tax2, pol2) + w.advance(EPOCH + 3_000 * MS)
    assert [x.degraded for x in out] == [False] * 10
    assert w.counters.joined_mid_stream_windows == 0


def test_a_pac_window_reaching_back_before_the_first_frame_is_degraded():
    cfg = WindowConfig.for_task(Task.TAP_LOCALIZATION, Sensor.BIOTAC)
    rng = np.random.default_rng(6)
    n = int(1.5e9 // PAC_PERIOD_NS)
    x = 2000.0 + rng.normal(0, 2, n)
    burst = int(0.02e9 // PAC_PERIOD_NS)  # 20 ms into the stream: the pre-onset part is missing
    x[burst : burst + 200] += 400 * np.sin(np.arange(200) * 0.7)
    w = PacWindower(cfg)
    out = []
    for i in range(0, n, 22):
        out += w.feed(EPOCH + i * PAC_PERIOD_NS, x[i : i + 22])
    finals = [win for win in out if not win.provisional]
    assert len(finals) == 1
    assert finals[0].degraded
    assert "joined mid-stream" in finals[0].degraded_reason
