"""Arrival-jitter augmentation: deterministic, keeps every event, moves only times as modelled."""

from __future__ import annotations

import numpy as np
import pytest

from ext_sense_perception.errors import PerceptionError
from ext_sense_perception.training.arrival_jitter import (
    ReadDelay,
    augment,
    jitter_window,
    onset_shifted,
    read_groups,
    rechunk_writes,
    restamp,
    shift_window,
)
from ext_sense_runtime.stamps import MS

NO_DELAY = ReadDelay((0.0, 1.0), (0, 0))
LATE_5MS = ReadDelay((0.0, 1.0), (5 * MS, 5 * MS))


def _window(rng: np.random.Generator, n_channels: int = 8, n_samples: int = 60) -> np.ndarray:
    x = np.zeros((n_channels, n_samples), np.float32)
    x[:, 20:35] = rng.integers(0, 4, (n_channels, 15))  # a tap at bin 20 (the onset)
    x[:, 2:4] = rng.integers(0, 2, (n_channels, 2))
    return x


def test_restamp_is_deterministic_with_a_seed_and_keeps_order():
    t = np.sort(np.random.default_rng(0).integers(0, 50 * MS, 500))
    delay = ReadDelay((0.0, 0.5, 1.0), (50_000, 300_000, 4 * MS))
    a = restamp(t, delay, np.random.default_rng(3))
    b = restamp(t, delay, np.random.default_rng(3))
    np.testing.assert_array_equal(a, b)
    assert a.size == t.size
    assert np.all(np.diff(a) >= 0)
    # a word is stamped within its read: never later than the read that took it
    assert np.all(a <= t + 4 * MS + 1)


def test_a_read_takes_every_word_due_by_its_return():
    t = np.array([0, 1 * MS, 2 * MS, 10 * MS, 11 * MS], np.int64)
    ends, reads = read_groups(t, LATE_5MS, np.random.default_rng(0))
    # first read returns at 5 ms (0 + 5 ms) with the three words due by then
    np.testing.assert_array_equal(ends, [3, 5])
    np.testing.assert_array_equal(reads, [5 * MS, 15 * MS])


def test_no_delay_stamps_as_the_arrival_clock_does():
    """Reads at each word's time: words due together are spread back over the interval since
    the previous read (the driver's clock), never later than due, never before that read."""
    t = np.array([500_000, 1_500_000, 1_500_000, 2_250_000, 2_750_000], np.int64)
    got = restamp(t, NO_DELAY, np.random.default_rng(0))
    np.testing.assert_array_equal(got, [500_000, 1_000_000, 1_500_000, 2_250_000, 2_750_000])


def test_jitter_window_keeps_event_counts_per_channel():
    rng = np.random.default_rng(4)
    x = _window(rng)
    out = jitter_window(x, MS, 20, LATE_5MS, np.random.default_rng(5))
    assert out.dtype == x.dtype
    assert out.shape == x.shape
    np.testing.assert_array_equal(out.sum(axis=1), x.sum(axis=1))
    assert not np.array_equal(out, x)  # 5 ms late reads do move events
    # re-aligned on the re-stamped onset: the onset bin still holds the first tap events
    assert out[:, :20].sum() <= x[:, :20].sum() + 1e-6 + x[:, 20].sum()


def test_signed_counts_keep_their_sum():
    x = np.zeros((2, 30), np.float32)
    x[0, 10:14] = [3, -2, 1, -1]
    x[1, 12] = -4
    out = jitter_window(x, MS, 10, LATE_5MS, np.random.default_rng(0))
    np.testing.assert_array_equal(out.sum(axis=1), x.sum(axis=1))


def test_augment_is_deterministic_and_touches_only_the_fraction(tap_set):
    a = augment(tap_set, 0.5, seed=7, delay=LATE_5MS)
    b = augment(tap_set, 0.5, seed=7, delay=LATE_5MS)
    np.testing.assert_array_equal(a.X, b.X)
    np.testing.assert_array_equal(a.y, tap_set.y)
    np.testing.assert_array_equal(a.X.sum(axis=2), tap_set.X.sum(axis=2))
    changed = np.any(a.X != tap_set.X, axis=(1, 2))
    assert 0 < changed.sum() < len(tap_set.y)
    assert augment(tap_set, 0.0, seed=7) is tap_set


def test_augment_refuses_a_bad_fraction(tap_set):
    with pytest.raises(PerceptionError, match="'arrival_jitter' parameter must be in"):
        augment(tap_set, 1.5)


def test_rechunk_writes_keeps_every_byte_in_order():
    writes = [(i * 100_000, bytes([i % 256]) * 4) for i in range(200)]
    reads = rechunk_writes(writes, LATE_5MS, np.random.default_rng(0))
    assert b"".join(b for _, b in reads) == b"".join(b for _, b in writes)
    times = [t for t, _ in reads]
    assert times == sorted(times)
    assert len(reads) < len(writes)


@pytest.fixture
def tap_set():
    from ext_sense_perception.data.window_set import WindowSet
    from ext_sense_perception.online.model_input import Geometry

    rng = np.random.default_rng(0)
    X = np.stack([_window(rng) for _ in range(10)])  # noqa: N806
    return WindowSet(
        task="tap_localization",
        sensor="nuskin",
        X=X,
        y=np.linspace(0.01, 0.29, 10),
        geometry=Geometry(8, 60, MS, 20 * MS),
        class_names=(),
        groups=np.arange(10),
        rod_length_m=np.full(10, 0.3),
        source="test",
        data_hash="0",
    )


@pytest.mark.parametrize(
    ("task", "asked", "applied"),
    [
        ("handover", None, 0.5),
        ("handover", 0.0, None),
        ("tap", None, 0.25),
        ("tap", 0.0, None),
        ("tap", 0.3, 0.3),
        ("food", None, None),
    ],
)
def test_the_recipe_augments_by_the_task_default_unless_told(
    tap_set, monkeypatch, task, asked, applied
):
    from ext_sense_perception.training import recipe as recipe_module

    seen = []

    def augment_spy(ws, fraction, seed):
        seen.append(fraction)
        return ws

    def fit_stops(ws, *args, **kwargs):
        raise StopIteration  # the fit itself is not what this checks

    monkeypatch.setattr(recipe_module, "augment", augment_spy)
    monkeypatch.setattr(recipe_module, "fit_model", fit_stops)
    ws = tap_set._replace(task=task)
    with pytest.raises(StopIteration):
        recipe_module.fit_recipe(ws, recipe_module.Recipe(arrival_jitter=asked))
    assert seen == ([] if applied is None else [applied])


@pytest.fixture(scope="module")
def handover_stream():
    from ext_sense_sim.scene import load_scene
    from ext_sense_sim.trial_plan import lay_out_stream

    return lay_out_stream(load_scene("handover_rod_nuskin"), seed=5, trials=6, period_s=1.0)


def test_late_reads_add_a_cut_of_the_same_trials_each(handover_stream):
    from ext_sense_perception.data.device_stream import window_set_from_stream
    from ext_sense_perception.online.window import WindowConfig
    from ext_sense_perception.training.arrival_jitter import (
        MEASURED_READ_DELAY,
        late_read_window_set,
    )

    config = WindowConfig.for_task("handover_stability", "nuskin")
    writes, truths = handover_stream.writes, handover_stream.truths
    ideal, counts = window_set_from_stream(writes, truths, config)
    ws, got_counts = late_read_window_set(writes, truths, config, late_reads=2, seed=3)
    assert got_counts == counts
    n = len(ideal.y)
    assert n >= 5
    assert len(ws.y) == 3 * n  # every trial found again by both late readers
    np.testing.assert_array_equal(ws.X[:n], ideal.X)  # the ideal cut comes first, unchanged
    np.testing.assert_array_equal(ws.groups, np.tile(ideal.groups, 3))
    np.testing.assert_array_equal(ws.y, np.tile(ideal.y, 3))
    assert ws.data_hash == f"{ideal.data_hash}+2late"
    # a late reader moves events between bins, and each late cut draws its own reads
    assert not np.array_equal(ws.X[n : 2 * n], ideal.X)
    assert not np.array_equal(ws.X[n : 2 * n], ws.X[2 * n :])
    again, _ = late_read_window_set(writes, truths, config, late_reads=2, seed=3)
    np.testing.assert_array_equal(again.X, ws.X)
    # cut side by side in two processes: the same windows
    side, side_counts = late_read_window_set(writes, truths, config, late_reads=2, seed=3, n_jobs=2)
    np.testing.assert_array_equal(side.X, ws.X)
    np.testing.assert_array_equal(side.groups, ws.groups)
    assert side_counts == counts
    # no late reads: the ideal cut alone
    none, _ = late_read_window_set(writes, truths, config, late_reads=0)
    np.testing.assert_array_equal(none.X, ideal.X)
    assert MEASURED_READ_DELAY.delay_ns[-1] > 1_000_000  # the default is a late reader


def test_late_reads_refuse_a_negative_count(handover_stream):
    from ext_sense_perception.online.window import WindowConfig
    from ext_sense_perception.training.arrival_jitter import late_read_window_set

    config = WindowConfig.for_task("handover_stability", "nuskin")
    with pytest.raises(PerceptionError, match="'late_reads' parameter must be at least 0"):
        late_read_window_set(handover_stream.writes, handover_stream.truths, config, -1)


def test_the_folds_keep_each_trial_whole_when_a_set_holds_copies(tap_set):
    from sklearn.model_selection import KFold, StratifiedKFold

    from ext_sense_perception.training.protocol import whole_trial_folds

    cv = KFold(4, shuffle=True, random_state=0)
    assert whole_trial_folds(cv, tap_set, 0) is cv  # a trial per window: the splitter as is
    copies = tap_set._replace(
        X=np.concatenate([tap_set.X] * 3),
        y=np.tile(tap_set.y, 3),
        groups=np.tile(tap_set.groups, 3),
    )
    for ws, splitter in (
        (copies, cv),
        (
            copies._replace(y=np.tile(np.array(["a", "b"] * 5), 3), class_names=("a", "b")),
            StratifiedKFold(3, shuffle=True, random_state=0),
        ),
    ):
        folds = whole_trial_folds(splitter, ws, 0)
        assert len(folds) == splitter.get_n_splits()
        seen = np.concatenate([test for _, test in folds])
        assert sorted(seen.tolist()) == list(range(len(ws.y)))  # each window tested once
        for train, test in folds:
            assert not set(ws.groups[train]) & set(ws.groups[test])
    # and the plain splitter would have split trials: what the grouped folds prevent
    leaky = [set(copies.groups[tr]) & set(copies.groups[te]) for tr, te in cv.split(copies.X)]
    assert any(leaky)


def test_shift_window_by_whole_bins_moves_the_series():
    x = _window(np.random.default_rng(1))
    np.testing.assert_array_equal(shift_window(x, 0, MS), x)
    later = shift_window(x, 3 * MS, MS)  # the window starts 3 bins later: events 3 bins earlier
    np.testing.assert_array_equal(later[:, :-3], x[:, 3:])
    assert not later[:, -3:].any()  # nothing comes in past the end
    earlier = shift_window(x, -3 * MS, MS)
    np.testing.assert_array_equal(earlier[:, 3:], x[:, :-3])
    assert earlier.dtype == x.dtype


def test_shift_window_by_part_of_a_bin_splits_its_events():
    x = np.zeros((2, 10), np.float32)
    x[0, 5], x[1, 5] = 4, -4  # four events (and four negative ones) spread evenly in bin 5
    half = shift_window(x, MS // 2, MS)  # the first two fall a bin earlier
    np.testing.assert_array_equal(half[:, 4:6], [[2, 2], [-2, -2]])
    quarter = shift_window(x, -MS // 4, MS)  # the window starts earlier: the last one moves on
    np.testing.assert_array_equal(quarter[:, 5:7], [[3, 1], [-3, -1]])
    assert shift_window(x, 7 * MS, MS).sum() == 0  # moved out of the window altogether


def test_onset_shifted_adds_copies_of_each_trial(tap_set):
    out = onset_shifted(tap_set, 2, max_shift_ns=2 * MS, seed=4)
    n = len(tap_set.y)
    assert len(out.y) == 3 * n
    np.testing.assert_array_equal(out.X[:n], tap_set.X)  # the windows as cut come first
    np.testing.assert_array_equal(out.groups, np.tile(tap_set.groups, 3))
    np.testing.assert_array_equal(out.y, np.tile(tap_set.y, 3))
    assert out.data_hash == "0+2shifted"
    assert np.any(out.X[n:] != np.tile(tap_set.X, (2, 1, 1)))
    # by at most 2 ms: the tap (bins 20..34) stays inside 18..36, the early events (2..3) in 0..6
    assert not out.X[n:, :, 37:].any()
    assert not out.X[n:, :, 7:18].any()
    again = onset_shifted(tap_set, 2, max_shift_ns=2 * MS, seed=4)
    np.testing.assert_array_equal(again.X, out.X)
    assert onset_shifted(tap_set, 0) is tap_set
    assert onset_shifted(tap_set._replace(sensor="biotac"), 2) is not None
    assert len(onset_shifted(tap_set._replace(sensor="biotac"), 2).y) == n
    with pytest.raises(PerceptionError, match="'onset_shifts' parameter must be >= 0"):
        onset_shifted(tap_set, -1)
    with pytest.raises(PerceptionError, match="'max_shift_ns' parameter must be > 0"):
        onset_shifted(tap_set, 1, max_shift_ns=0)


@pytest.mark.parametrize(
    ("task", "features", "asked", "kernel"),
    [
        ("tap", "fft", None, "gauss"),
        ("tap", "fft", "box", "box"),
        ("tap", "baseline", None, "gauss"),
        ("tap", "est", None, None),  # no bins
        ("handover", "fft", None, None),
        ("handover", "fft", "gauss", "gauss"),
    ],
)
def test_the_recipe_bins_by_the_task_kernel_unless_told(tap_set, task, features, asked, kernel):
    from ext_sense_perception.training.recipe import Recipe, resolve

    ws = tap_set._replace(task=task)
    choice = resolve(ws, Recipe(features=features, bin_kernel=asked))
    assert choice.feature_params.get("bin_kernel") == kernel
    biotac = resolve(ws._replace(sensor="biotac"), Recipe(features=features, bin_kernel=asked))
    assert "bin_kernel" not in biotac.feature_params


def test_the_recipe_trains_on_shifted_copies_when_asked(tap_set, monkeypatch):
    from ext_sense_perception.training import recipe as recipe_module

    seen = []

    def fit_stops(ws, *args, **kwargs):
        seen.append(len(ws.y))
        raise StopIteration

    monkeypatch.setattr(recipe_module, "fit_model", fit_stops)
    for copies in (0, 2):
        with pytest.raises(StopIteration):
            recipe_module.fit_recipe(tap_set, recipe_module.Recipe(onset_shifts=copies))
    assert seen == [10, 30]
