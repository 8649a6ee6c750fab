"""Windows and features from rosbag2 bags against the simulator's ``dataset.npz`` path."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ext_sense_perception.data.bags import BagTopics, is_bag, window_set_from_bag
from ext_sense_perception.data.sources import from_sim_dataset, load_window_set
from ext_sense_perception.errors import PerceptionError
from ext_sense_perception.profiles import PAC_PERIOD_NS
from ext_sense_runtime.records import EventBlock
from ext_sense_runtime.stamps import MS, S
from ext_sense_sim.output.bag import write_bag

T0 = 1_700_000_000_000_000_000
EVENTS = "/extsense/nuskin/events"
PACKETS = "/extsense/nuskin/packets"
PACKET_TYPE = "ext_sense_msgs/msg/SensorPacket"
TRUTH = "/extsense/ground_truth"


def _sim_run(
    tmp_path_factory,
    scene_name: str,
    trials: int,
    trial_s: float | None = None,
    onset_s: list[float] | None = None,
) -> Path:
    from ext_sense_sim.run import run_scene
    from ext_sense_sim.scene import load_scene

    scene = load_scene(scene_name)
    if trial_s is not None:
        scene = dataclasses.replace(scene, trial_s=trial_s)
    if onset_s is not None:
        effects = tuple(
            (name, {**params, "onset_s": onset_s}) if name == "contact_impulse" else (name, params)
            for name, params in scene.effects
        )
        scene = dataclasses.replace(scene, effects=effects)
    out = tmp_path_factory.mktemp(scene_name)
    run_scene(scene, out, trials=trials, formats=("npz", "bag"))
    return out


@pytest.fixture(scope="module")
def nuskin_run(tmp_path_factory) -> Path:
    """A few simulated taps at the scene's own 0.3 s trial spacing."""
    return _sim_run(tmp_path_factory, "tap_rod30_nuskin", 5)


@pytest.fixture(scope="module")
def biotac_run(tmp_path_factory) -> Path:
    return _sim_run(tmp_path_factory, "tap_rod30_biotac", 4)


def _inside(ws, d: dict, i: int, trial_ns: int) -> np.ndarray:
    """Window samples of trial ``i`` lying within its own trial's data (not a neighbour's)."""
    g = ws.geometry
    start = int(d["onset_ns"][i]) - g.pre_ns + np.arange(g.n_samples) * g.period_ns
    if g.sensor == "biotac":
        first = -(-(int(d["onset_ns"][i]) - g.pre_ns - int(d["pac_t0_ns"][i])) // g.period_ns)
        sample = first + np.arange(g.n_samples)  # the PAC sample each window sample holds
        return (sample >= 0) & (sample < d["pac"].shape[2])
    return (start >= 0) & (start + g.period_ns <= trial_ns)


def test_simulator_bag_matches_its_dataset_inside_each_trial(nuskin_run):
    ws, counts = window_set_from_bag(nuskin_run / "bag")
    ref = from_sim_dataset(nuskin_run / "dataset.npz")
    d = dict(np.load(nuskin_run / "dataset.npz"))
    assert (ws.task, ws.sensor, ws.geometry) == (ref.task, ref.sensor, ref.geometry)
    assert counts.windows == counts.labelled == counts.truths == 5
    assert counts.undecodable == counts.bad_messages == counts.missed_truths == 0
    np.testing.assert_array_equal(ws.y, ref.y)
    np.testing.assert_array_equal(ws.groups, ref.groups)
    np.testing.assert_array_equal(ws.rod_length_m, ref.rod_length_m)
    trial_ns = int(d["trial_ns"])
    for i in range(5):
        keep = _inside(ws, d, i, trial_ns)
        assert keep.sum() >= 290  # of 300 bins: the bag lays trials back to back
        np.testing.assert_array_equal(ws.X[i][:, keep], ref.X[i][:, keep])


def test_simulator_bag_features_equal_the_dataset_features(tmp_path_factory, tmp_path):
    """Trials 0.6 s apart, taps at least 55 ms in: no neighbour reaches a window (the window
    opens 50 ms before the tap, and the chatty taxels fire to the end of every trial), so the
    features are identical."""
    from ext_sense_perception import cli

    run = _sim_run(tmp_path_factory, "tap_rod30_nuskin", 4, trial_s=0.6, onset_s=[0.055, 0.065])
    outs = {}
    for name, data in (("bag", run / "bag"), ("npz", run / "dataset.npz")):
        outs[name] = tmp_path / f"{name}.npy"
        rc = _cli(cli, ["--data", str(data), "--features", "fft", "--out", str(outs[name])])
        assert rc == 0
    np.testing.assert_array_equal(np.load(outs["bag"]), np.load(outs["npz"]))
    np.testing.assert_array_equal(
        np.load(tmp_path / "bag.labels.npy"), np.load(tmp_path / "npz.labels.npy")
    )


def _cli(cli_module, argv: list[str]) -> int:
    import argparse

    parser = argparse.ArgumentParser()
    cli_module.register(parser.add_subparsers())
    args = parser.parse_args(["features", *argv])
    return args.func(args)


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_recorded_bag_gives_the_dataset_features_exactly(nuskin_run, tmp_path, storage):
    """A recorder-style bag (log time = arrival, truth before its data), both storages."""
    from ext_sense_perception import cli

    bag = tmp_path / "rec"
    write_bag(
        np.load(nuskin_run / "dataset.npz"), bag, t0_ns=T0, trial_period_ns=S, storage=storage
    )
    assert is_bag(bag)
    ws, counts = window_set_from_bag(bag)
    ref = from_sim_dataset(nuskin_run / "dataset.npz")
    np.testing.assert_array_equal(ws.X, ref.X)
    np.testing.assert_array_equal(ws.y, ref.y)
    assert counts.labelled == 5
    for name, data in (("bag", bag), ("npz", nuskin_run / "dataset.npz")):
        assert _cli(cli, ["--data", str(data), "--out", str(tmp_path / f"{name}.npy")]) == 0
    np.testing.assert_array_equal(np.load(tmp_path / "bag.npy"), np.load(tmp_path / "npz.npy"))
    # the single storage file works as well as the directory, and load_window_set dispatches
    single = next(p for p in bag.iterdir() if p.suffix in (".mcap", ".db3"))
    np.testing.assert_array_equal(load_window_set(single).X, ref.X)


def test_rate_reduction_on_a_bag_equals_the_dataset_path(nuskin_run, tmp_path):
    write_bag(np.load(nuskin_run / "dataset.npz"), tmp_path / "rec", t0_ns=T0, trial_period_ns=S)
    ws, _ = window_set_from_bag(tmp_path / "rec", rate_hz=500.0)
    ref = from_sim_dataset(nuskin_run / "dataset.npz", rate_hz=500.0)
    full = from_sim_dataset(nuskin_run / "dataset.npz")
    np.testing.assert_array_equal(ws.X, ref.X)
    assert np.abs(ws.X).sum() < np.abs(full.X).sum()


def test_detected_onsets_are_labelled_by_the_nearest_truth(nuskin_run, tmp_path):
    write_bag(np.load(nuskin_run / "dataset.npz"), tmp_path / "rec", t0_ns=T0, trial_period_ns=S)
    ws, counts = window_set_from_bag(tmp_path / "rec", onsets="detected")
    ref = from_sim_dataset(nuskin_run / "dataset.npz")
    assert counts.labelled == len(ws.y) >= 4
    assert counts.unmatched_windows + counts.labelled == counts.windows
    np.testing.assert_array_equal(ws.y, ref.y[ws.groups])


def test_biotac_bags_match_the_dataset(biotac_run, tmp_path):
    """Two sensors joined by sequence; the live windower puts every frame on one 2200 Hz grid,
    so a trial the simulator starts on another phase may be cut one sample (0.45 ms) apart."""
    ref = from_sim_dataset(biotac_run / "dataset.npz")
    d = dict(np.load(biotac_run / "dataset.npz"))
    ws, counts = window_set_from_bag(biotac_run / "bag")
    assert ws.X.shape == ref.X.shape
    assert ws.X.shape[1] == 2
    np.testing.assert_array_equal(ws.y, ref.y)
    assert counts.windows == 4
    assert counts.bad_messages == 0
    for i in range(4):
        keep = np.flatnonzero(_inside(ws, d, i, 0))[1:-1]  # edges: one grid's neighbour
        shifts = [s for s in (-1, 0, 1) if np.array_equal(ws.X[i][:, keep], ref.X[i][:, keep + s])]
        assert shifts, f"trial {i} differs by more than one sample"
    # on a grid-aligned timeline (trials 2200 samples apart, PAC from the origin) it is exact
    aligned = tmp_path / "aligned.npz"
    np.savez(aligned, **{**d, "pac_t0_ns": np.zeros(len(d["y"]), np.int64)})
    write_bag(np.load(aligned), tmp_path / "bb", t0_ns=T0, trial_period_ns=2200 * PAC_PERIOD_NS)
    ws2, _ = window_set_from_bag(tmp_path / "bb")
    ref2 = from_sim_dataset(aligned)
    for i in range(4):
        keep = _inside(ref2, {**d, "pac_t0_ns": np.zeros(4, np.int64)}, i, 0)
        np.testing.assert_array_equal(ws2.X[i][:, keep], ref2.X[i][:, keep])


# ---- malformed bags: clear errors, counted drops ------------------------------------------


def _expect_cli_error(tmp_path, data: Path, match: str) -> None:
    from ext_sense_perception import cli

    with pytest.raises(PerceptionError, match=match):
        window_set_from_bag(data)
    assert _cli(cli, ["--data", str(data), "--out", str(tmp_path / "x.npy")]) == 2


def test_not_a_bag_and_empty_bags(tmp_path, capsys):
    from ext_sense_bags import BagWriter

    junk = tmp_path / "junk.mcap"
    junk.write_bytes(b"\x89MCAP0\r\n" + bytes(range(200)))
    _expect_cli_error(tmp_path, junk, "readable bag")
    with pytest.raises(PerceptionError, match="readable bag"):
        window_set_from_bag(tmp_path / "missing.mcap")
    with BagWriter(tmp_path / "empty"):
        pass
    _expect_cli_error(tmp_path, tmp_path / "empty", "holds no messages")
    assert "ext-sense: error:" in capsys.readouterr().err


def test_bag_without_sensor_topic_or_with_a_wrong_type(tmp_path):
    from ext_sense_bags import BagWriter, ground_truth

    with BagWriter(tmp_path / "truth_only") as bag:
        bag.write(TRUTH, T0, ground_truth(T0, "tap_localization", 0, tap_position_m=0.1))
    _expect_cli_error(tmp_path, tmp_path / "truth_only", "no sensor topic")
    with BagWriter(tmp_path / "wrong") as bag:
        bag.write(EVENTS, T0, ground_truth(T0, "tap_localization", 0, tap_position_m=0.1))
    _expect_cli_error(tmp_path, tmp_path / "wrong", "must hold ext_sense_msgs/msg/TaxelEventBatch")
    with pytest.raises(
        PerceptionError, match="no nuskin messages on '/extsense/nuskin/packets' or '/other'"
    ):
        window_set_from_bag(tmp_path / "wrong", sensor="nuskin", topics=BagTopics(events="/other"))


def test_a_bag_whose_sensor_messages_all_fail_to_decode_is_refused(tmp_path):
    from ext_sense_bags import BagWriter, ground_truth

    bag = tmp_path / "undecodable"
    with BagWriter(bag) as b:
        b.write(TRUTH, T0, ground_truth(T0, "tap_localization", 0, tap_position_m=0.1))
        b.write_raw(
            EVENTS, T0 + 1, b"\x00\x01\x00\x00garbage", "ext_sense_msgs/msg/TaxelEventBatch"
        )
    # before: 1 all-zero window cut from the ground truth alone, and training went on
    with pytest.raises(
        PerceptionError, match=r"No message on '/extsense/nuskin/events' .* \(1 undecodable\)"
    ):
        window_set_from_bag(bag)


def test_bad_messages_are_counted_and_dropped(nuskin_run, tmp_path):
    from ext_sense_bags import BagReader, BagWriter, make_message

    src = tmp_path / "src"
    write_bag(np.load(nuskin_run / "dataset.npz"), src, t0_ns=T0, trial_period_ns=S)
    out = tmp_path / "bad"
    with BagReader(src) as a, BagWriter(out) as b:
        for rec in a.records():
            b.write_raw(rec.topic, rec.log_time_ns, rec.data, rec.msgtype)
        good = next(msg for _, msg in a.messages([PACKETS]))
        b.write_raw(PACKETS, T0 + 1, b"\x00\x01\x00\x00garbage", PACKET_TYPE)  # does not decode
        b.write(  # a read's end but no return time: the window stage drops it
            PACKETS,
            T0 + 2,
            make_message(
                PACKET_TYPE,
                encoding=good.encoding,
                encoding_options=good.encoding_options,
                read_end=np.array([0], np.uint32),
            ),
        )
    ws, counts = window_set_from_bag(out)
    ref = from_sim_dataset(nuskin_run / "dataset.npz")
    assert counts.undecodable == 1
    assert counts.bad_messages == 1
    np.testing.assert_array_equal(ws.X, ref.X)


def test_food_needs_truth_and_unlabelled_windows_for_features(nuskin_run, tmp_path):
    from ext_sense_bags import BagReader, BagWriter

    out = tmp_path / "no_truth"
    with BagReader(nuskin_run / "bag") as a, BagWriter(out) as b:
        for rec in a.records([PACKETS]):
            b.write_raw(rec.topic, rec.log_time_ns, rec.data, rec.msgtype)
    with pytest.raises(PerceptionError, match="give --task"):
        window_set_from_bag(out)
    with pytest.raises(PerceptionError, match="motion start"):
        window_set_from_bag(out, "food_identification")
    with pytest.raises(PerceptionError, match="need ground truth"):
        window_set_from_bag(out, "tap_localization", onsets="truth")
    with pytest.raises(PerceptionError, match="training needs ground truth"):
        window_set_from_bag(out, "tap_localization")
    ws, counts = window_set_from_bag(out, "tap_localization", require_labels=False)
    assert len(ws.y) == counts.windows >= 1
    assert np.isnan(ws.y).all()
    assert counts.truths == counts.labelled == 0


@settings(max_examples=60, deadline=None)
@given(
    times=st.lists(st.integers(0, 20 * MS), min_size=0, max_size=80),
    seed=st.integers(0, 2**16),
    rate=st.sampled_from([200.0, 1000.0, 4000.0]),
)
def test_refractory_across_batches_equals_the_whole_stream(times, seed, rate):
    from ext_sense_perception.data.bags import _Refractory
    from ext_sense_perception.data.refractory import refractory_mask

    rng = np.random.default_rng(seed)
    t = np.sort(np.asarray(times, dtype=np.int64)) + T0
    taxel = rng.integers(1, 5, len(t)).astype(np.uint16)
    cuts = np.sort(rng.integers(0, len(t) + 1, 3))
    thin = _Refractory(rate, 80)
    kept = []
    for lo, hi in zip(np.r_[0, cuts], np.r_[cuts, len(t)], strict=True):
        if hi <= lo:
            continue
        out = thin(EventBlock.of(t[lo:hi], taxel[lo:hi], np.ones(hi - lo, np.int8)))
        kept.append(out.t_ns)
    got = np.concatenate(kept) if kept else np.zeros(0, np.int64)
    want = t[refractory_mask(t, taxel, rate)]
    np.testing.assert_array_equal(np.sort(got), np.sort(want))


def test_cli_train_and_evaluate_read_bags_and_need_labels(nuskin_run, tmp_path):
    import argparse

    from ext_sense_bags import BagReader, BagWriter
    from ext_sense_perception import cli
    from ext_sense_perception.cli.options import load_pooled

    parser = argparse.ArgumentParser()
    cli.register(parser.add_subparsers())
    args = parser.parse_args(["evaluate", "--data", str(nuskin_run / "bag")])
    ws = load_pooled(args)
    assert (ws.task, ws.sensor, len(ws.y)) == ("tap_localization", "nuskin", 5)
    out = tmp_path / "no_truth"
    with BagReader(nuskin_run / "bag") as a, BagWriter(out) as b:
        b.set_custom_data("task", "tap_localization")
        for rec in a.records([PACKETS]):
            b.write_raw(rec.topic, rec.log_time_ns, rec.data, rec.msgtype)
    for command in ("evaluate", "train"):
        argv = [command, "--data", str(out), "--onsets", "detected", "--out", str(tmp_path / "m")]
        args = parser.parse_args(argv[:5] if command == "evaluate" else argv)
        assert args.func(args) == 2


def _tap_bags(tmp_path: Path) -> tuple[Path, Path]:
    """The same simulated taps twice: as the driver records them by default (receiver words in
    raw packets) and as its decoded arrays of those very packets (``decoded:=true``)."""
    from ext_sense_bags.messages import sensor_packet, taxel_event_batch

    from ext_sense_bags import BagWriter, ground_truth
    from ext_sense_drivers.nuskin.wire import encode_words
    from ext_sense_drivers.packets import NUSKIN_WORDS_V1, PacketPacker, make_decoder
    from ext_sense_drivers.transports.base import Chunk
    from ext_sense_sim.engine import Simulator
    from ext_sense_sim.scene import load_scene

    _, sig = next(Simulator(load_scene("tap_rod30_nuskin")).batches(4, 0))
    trial, ev = sig["events"]
    trial_ns = 400 * MS
    t = ev.t_ns + trial.astype(np.int64) * trial_ns + T0
    taxel, value = ev.taxel, ev.value
    order = np.argsort(t, kind="stable")
    t, taxel, value = t[order], taxel[order], value[order]
    packer, decoder = PacketPacker(NUSKIN_WORDS_V1), make_decoder(NUSKIN_WORDS_V1, "")
    with BagWriter(tmp_path / "packets") as raw, BagWriter(tmp_path / "decoded") as arrays:
        for start in range(T0, int(t[-1]) + MS, MS):  # one read, one packet per 1 ms
            k = slice(*np.searchsorted(t, [start, start + MS]))
            if t[k].size == 0:
                continue
            chunk = Chunk(encode_words(taxel[k], value[k]), start + MS)
            for p in packer.pack([(1, chunk)], link_down=False):
                raw.write(
                    "/extsense/nuskin/packets",
                    p.stamp_ns,
                    sensor_packet(p, "nuskin"),
                )
                e = decoder.decode(p).events
                first = int(e.t_ns.min())  # the driver stamps a batch with its first event
                batch = taxel_event_batch(first, e.taxel, e.polarity, e.value, e.t_ns - first)
                arrays.write(EVENTS, p.stamp_ns, batch)
        for i in range(4):
            onset = T0 + i * trial_ns + int(sig["labels"].onset_ns[i])
            for bag in (raw, arrays):
                truth = ground_truth(
                    onset, "tap_localization", i, tap_position_m=float(sig["labels"].y_m[i])
                )
                bag.write(TRUTH, onset, truth)
    return tmp_path / "packets", tmp_path / "decoded"


def test_a_packet_bag_gives_the_windows_of_its_decoded_arrays(tmp_path):
    """``ext-sense record`` keeps raw packets by default: training from such a bag decodes them
    with the drivers' library, and gets the windows the driver's decoded arrays give."""
    packets, decoded = _tap_bags(tmp_path)
    ws_p, counts = window_set_from_bag(packets)
    ws_d, _ = window_set_from_bag(decoded)
    assert counts.windows == counts.labelled == 4
    assert counts.bad_messages == 0
    assert ws_p.X.any()
    np.testing.assert_array_equal(ws_p.X, ws_d.X)
    np.testing.assert_array_equal(ws_p.y, ws_d.y)
