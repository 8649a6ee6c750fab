"""Training windows cut from the device's own byte stream, and the emulated link that carries it.

No ROS: the stream is laid out by ``ext_sense_sim.trial_plan.lay_out_stream`` (the same wire
effect and trial spacing ``sim_device`` streams live) and cut by
``ext_sense_perception.data.device_stream`` (the driver's decoder and arrival clock, then the
``contact_window`` node's ``WindowStage``).
"""

from __future__ import annotations

import os
import threading
import time

import numpy as np
import pytest

from ext_sense_perception.data.device_stream import (
    cut_stream,
    recut,
    stream_windows,
    window_set_from_stream,
)
from ext_sense_perception.errors import PerceptionError
from ext_sense_perception.online.stage import WindowStage
from ext_sense_perception.online.window import WindowConfig
from ext_sense_runtime.stamps import MS
from ext_sense_sim.links import PtyLink
from ext_sense_sim.scene import load_scene
from ext_sense_sim.trial_plan import lay_out_stream


@pytest.fixture(scope="module")
def laid():
    return lay_out_stream(load_scene("tap_rod30_nuskin"), seed=7, trials=6, period_s=1.0)


def _truths(laid):
    return laid.truths


def test_laid_out_stream_spaces_trials_and_stamps_onsets(laid):
    assert [g.trial for g in laid.truths] == list(range(6))
    times = np.array([t for t, _ in laid.writes])
    assert np.all(np.diff(times) >= 0)
    for g in laid.truths:  # the onset write lies inside its own trial's second
        assert g.trial * 1e9 < g.onset_ns < g.trial * 1e9 + 0.3e9
    assert all(0.0 < g.tap_position_m < 0.30 for g in laid.truths)


def test_every_trial_gets_one_labelled_window_holding_every_word(laid):
    ws, counts = window_set_from_stream(laid.writes, _truths(laid))
    n_words = sum(len(b) for _, b in laid.writes) // 4
    assert counts.words == n_words
    assert (counts.labelled, counts.unmatched_windows, counts.missed_trials) == (6, 0, 0)
    assert list(ws.groups) == list(range(6))
    np.testing.assert_allclose(ws.y, [g.tap_position_m for g in laid.truths])
    cfg = WindowConfig.for_task("tap_localization", "nuskin")
    assert ws.X.shape == (6, 80, (cfg.pre_ns + cfg.post_ns) // cfg.period_ns)
    assert ws.geometry.period_ns == cfg.period_ns
    # receiver words carry no polarity: every event counts +1, as in the live windows
    assert ws.X.min() >= 0
    assert ws.X.sum() > 0.5 * n_words


def test_windows_equal_the_window_stage_fed_by_hand(laid):
    """The stream path is the node's core: the same reads through WindowStage give the same."""
    from types import SimpleNamespace

    from ext_sense_drivers.nuskin.driver_config import DriverConfig
    from ext_sense_drivers.transports.base import Chunk

    writes = [w for w in laid.writes if w[0] < 2 * 10**9]  # two trials, one read per write
    wins, _, _ = stream_windows(writes, read_period_ns=1)
    decode = DriverConfig(baud=4_000_000).make_stream()
    stage = WindowStage(WindowConfig.for_task("tap_localization", "nuskin"))
    got = []
    for t, b in writes:
        block = decode.feed(Chunk(b, t))
        if block.t_ns.size:
            first = int(block.t_ns[0])
            msg = SimpleNamespace(
                header=SimpleNamespace(
                    stamp=SimpleNamespace(sec=first // 10**9, nanosec=first % 10**9)
                ),
                offset_ns=block.t_ns - first,
                taxel=block.taxel,
                polarity=block.polarity,
                value=block.value,
            )
            got.extend(stage.on_events(msg))
        got.extend(stage.advance(t))
    got.extend(stage.flush())
    finals = [w for w in got if not w.provisional]
    assert len(finals) == len(wins) == 2
    for a, b in zip(finals, wins, strict=True):
        assert a.onset_ns == b.onset_ns
        np.testing.assert_array_equal(a.data, b.data)


def test_truths_on_another_clock_match_nothing(laid):
    far = [g._replace(onset_ns=g.onset_ns + 10**12) for g in _truths(laid)]
    with pytest.raises(PerceptionError, match="none matched"):
        window_set_from_stream(laid.writes, far)


def test_bad_read_period_is_refused(laid):
    with pytest.raises(PerceptionError, match="read_period_ns"):
        stream_windows(laid.writes[:10], read_period_ns=0)


def test_pty_link_delivers_a_burst_larger_than_the_pty_buffer():
    link = PtyLink(max_backlog_s=2.0)
    received = bytearray()
    stop = threading.Event()
    fd = os.open(link.path, os.O_RDONLY | os.O_NONBLOCK)

    def reader() -> None:
        while not stop.is_set() or link.backlog_bytes:
            try:
                received.extend(os.read(fd, 65536))
            except BlockingIOError:
                time.sleep(0.001)

    thread = threading.Thread(target=reader)
    thread.start()
    try:
        data = bytes(range(256)) * 256  # 64 KiB at once: a pty holds about 4 KiB
        assert link.write(data) == len(data)
        deadline = time.monotonic() + 10
        while len(received) < len(data) and time.monotonic() < deadline:
            time.sleep(0.01)
    finally:
        stop.set()
        thread.join(timeout=5)
        os.close(fd)
        link.close()
    assert bytes(received) == data
    assert link.dropped_bytes == 0


def test_pty_link_drops_and_counts_stale_bytes_when_nobody_reads():
    link = PtyLink(max_backlog_s=0.05)
    try:
        sent = 0
        for _ in range(8):
            sent += link.write(b"\x20\x40\x80\xe0" * 2048)  # 8 KiB each
        deadline = time.monotonic() + 5
        while link.backlog_bytes and time.monotonic() < deadline:
            time.sleep(0.01)
        assert link.backlog_bytes == 0
        assert 0 < link.dropped_bytes < sent  # the pty itself keeps a few KiB
    finally:
        link.close()


def test_pty_link_refuses_a_bad_backlog():
    from ext_sense_sim.errors import SceneError

    with pytest.raises(SceneError, match="max_backlog_s"):
        PtyLink(max_backlog_s=0)


def test_jittered_reads_keep_every_word_and_refuse_bad_jitter(laid):
    _, counts = window_set_from_stream(laid.writes, _truths(laid), read_jitter=0.9, seed=3)
    assert counts.words == sum(len(b) for _, b in laid.writes) // 4
    assert counts.labelled == 6
    with pytest.raises(PerceptionError, match="read_jitter"):
        stream_windows(laid.writes[:10], read_jitter=1.5)


def test_recut_at_the_detected_onsets_gives_the_stage_windows(laid):
    cfg = WindowConfig.for_task("tap_localization", "nuskin")
    cut = cut_stream(laid.writes, cfg, keep_events=True)
    assert cut.events.size == cut.words == sum(len(b) for _, b in laid.writes) // 4
    assert np.all(np.diff(cut.events.t_ns) >= 0)
    onsets = np.array([w.onset_ns for w in cut.windows])
    again = recut(cut.events, onsets, cfg)
    np.testing.assert_array_equal(again, np.stack([w.data for w in cut.windows]))
    assert cut_stream(laid.writes[:50], cfg).events.size == 0  # events only when asked for


def test_recut_moves_the_grid_against_the_events(laid):
    cfg = WindowConfig.for_task("tap_localization", "nuskin")
    cut = cut_stream(laid.writes, cfg, keep_events=True)
    onsets = np.array([w.onset_ns for w in cut.windows])
    base = recut(cut.events, onsets, cfg)
    later = recut(cut.events, onsets, cfg, cfg.period_ns)  # one whole bin: the series moves
    np.testing.assert_array_equal(later[:, :, :-1], base[:, :, 1:])
    mixed = recut(cut.events, onsets, cfg, np.array([0, cfg.period_ns] * 3))
    np.testing.assert_array_equal(mixed[0::2], base[0::2])
    np.testing.assert_array_equal(mixed[1::2], later[1::2])
    with pytest.raises(PerceptionError, match="shifts_ns"):
        recut(cut.events, onsets, cfg, np.zeros(2, np.int64))
    with pytest.raises(PerceptionError, match="nuskin"):
        recut(cut.events, onsets, WindowConfig.for_task("tap_localization", "biotac"))


def test_estimate_moves_follow_the_onset_shift(laid):
    """A shifted onset is the events stamped the other way: the moves are those estimates'."""
    from ext_sense_perception.training.window_shift import estimate_moves

    cfg = WindowConfig.for_task("tap_localization", "nuskin")
    cut = cut_stream(laid.writes, cfg, keep_events=True)
    onsets = np.array([w.onset_ns for w in cut.windows])
    centre = (np.arange(cfg.n_samples()) + 0.5) * cfg.period_ns * 1e-9

    def mean_time(x: np.ndarray) -> np.ndarray:
        per_bin = x.reshape(len(x), cfg.n_taxels, -1).sum(axis=1)
        return per_bin @ centre / per_bin.sum(axis=1)

    shifts = [-2 * MS, 500_000, 2 * MS]
    moves = estimate_moves(mean_time, cut.events, onsets, cfg, shifts)
    assert sorted(moves) == shifts
    base = mean_time(np.stack([w.data for w in cut.windows]).reshape(6, -1))
    for shift in shifts:
        stamped = cut.events._replace(t_ns=cut.events.t_ns - shift)  # the clock moved instead
        again = mean_time(recut(stamped, onsets, cfg).reshape(6, -1))
        np.testing.assert_allclose(moves[shift], np.abs(again - base), rtol=1e-9)
        assert np.all(moves[shift] > 0)
