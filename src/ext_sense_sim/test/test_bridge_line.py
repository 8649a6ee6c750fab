"""The emulated BioTac bridge keeps streaming between trials, numbering as the bridge does."""

from __future__ import annotations

import numpy as np

from ext_sense_drivers.biotac.decoder import BridgeDecoder
from ext_sense_sim.bridge_line import FRAME_PERIOD_NS, MAX_CATCH_UP_FRAMES, BridgeLine
from ext_sense_sim.engine import Simulator
from ext_sense_sim.scene import load_scene
from ext_sense_sim.streaming import stream


def _trial_bytes() -> bytes:
    _, sig = next(Simulator(load_scene("handover_plate_biotac")).batches(2, 0))
    return b"".join(chunk for s in sig["wire"] for _, chunk in s.chunks())


def test_trials_and_rest_frames_run_on_in_each_sensors_sequence():
    now = [10**18]
    written: list[bytes] = []
    line = BridgeLine(written.append, lambda: now[0])
    data = _trial_bytes()
    line.prime(data)
    assert line.idle() > 0  # primed: the bridge streams before the first trial
    line.write(data)
    now[0] += 15 * FRAME_PERIOD_NS + 1
    assert line.idle() > 0
    decoder = BridgeDecoder()
    frames = decoder.feed(b"".join(written))
    for s in (0, 1):
        seq = frames.seq[frames.sensor_id == s].astype(np.int64)
        assert np.array_equal(seq, np.arange(seq.size))  # +1 per frame, rest frames included
    assert sum(decoder.counters.dropped_frames) == 0
    assert line.rest_frames == 2 * (1 + 15)
    rest = frames.words[-2:]  # the last rest frames repeat each sensor's last trial words
    trial = BridgeDecoder().feed(data)
    for k, s in enumerate((0, 1)):
        last = trial.words[trial.sensor_id == s][-1]
        assert np.array_equal(rest[k], last)


def test_a_long_pause_writes_at_most_the_catch_up_frames():
    now = [10**18]
    written: list[bytes] = []
    line = BridgeLine(written.append, lambda: now[0])
    line.prime(_trial_bytes())
    line.idle()
    now[0] += 10**9  # the stream thread was stopped for a second
    line.idle()
    frames = BridgeDecoder().feed(written[-1])
    assert frames.seq.size == 2 * MAX_CATCH_UP_FRAMES


def test_a_biotac_stream_never_falls_silent_between_trials():
    now = [10**18]
    written: list[tuple[int, bytes]] = []

    def sleep(s):
        now[0] += max(int(s * 1e9), 1000)

    stats = stream(
        load_scene("handover_plate_biotac"),
        lambda b: written.append((now[0], b)),
        seed=1,
        trials=2,
        period_s=1.0,
        clock=lambda: now[0],
        sleep=sleep,
    )
    assert stats.trials == 2
    times = np.array([t for t, _ in written])
    assert np.diff(times).max() <= 2 * FRAME_PERIOD_NS  # never silent for two frames
    assert times[-1] - times[0] >= 1.9e9  # through the last period too
    decoder = BridgeDecoder()
    decoder.feed(b"".join(b for _, b in written))
    assert sum(decoder.counters.dropped_frames) == 0
    assert stats.extra["rest_frames"] > 0
