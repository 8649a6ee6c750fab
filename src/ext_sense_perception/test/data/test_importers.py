from __future__ import annotations

import numpy as np
import pytest

from ext_sense_perception.data.importers import (
    load_sim_dataset,
    read_biotac_csv,
    read_capture_tact,
    read_csv_columns,
    read_paper_tact,
)
from ext_sense_perception.data.recordings import from_recording
from ext_sense_perception.data.sources import (
    from_food_poking,
    from_preprocessed_npz,
    from_sim_dataset,
    load_window_set,
)
from ext_sense_perception.errors import PerceptionError
from ext_sense_runtime.stamps import MS


def test_paper_tact_drops_markers_and_maps_polarity(tmp_path):
    p = tmp_path / "trial1_20.tact"
    p.write_text(
        "1 0 0 1617277544.00\n1 5 0 1617277544.123456\n0 41 0 1617277544.2\n1 80 0 "
        "1617277544.3\n0 0 0 1617277545.0\n"
    )
    ev = read_paper_tact(p)
    assert list(ev.taxel) == [5, 41, 80]
    assert list(ev.polarity) == [1, -1, 1]
    assert ev.t_ns.dtype == np.int64
    assert ev.t_ns[0] == 1_617_277_544_123_456_000


def test_paper_tact_without_markers_keeps_the_first_and_last_events(tmp_path):
    p = tmp_path / "temp_signal0.tact"
    p.write_text("1 1 1 1616591902.76\n0 24 1 1616591902.77\n1 80 1 1616591903.01\n")
    ev = read_paper_tact(p, markers=False)
    assert list(ev.taxel) == [1, 24, 80]
    assert list(ev.polarity) == [1, -1, 1]
    assert list(read_paper_tact(p).taxel) == [24]


def test_capture_tact_keeps_values_and_polarity_zero(tmp_path):
    p = tmp_path / "apple_zero_0.tact"
    p.write_text(
        "1 1 1 1617277544.85\n0 68 77 1617277544.86\n0 27 142 1617277544.87\n2 2 2 1617277548.53\n"
    )
    ev = read_capture_tact(p)
    assert list(ev.taxel) == [68, 27]
    assert list(ev.value) == [77, 142]
    assert list(ev.polarity) == [0, 0]
    assert ev.t_ns[1] - ev.t_ns[0] == 10 * MS


def test_missing_and_malformed_files(tmp_path):
    with pytest.raises(PerceptionError, match="existing file"):
        read_capture_tact(tmp_path / "nope.tact")
    bad = tmp_path / "bad.tact"
    bad.write_text("1 2 3\n4 5 6\n")
    with pytest.raises(PerceptionError, match="4 columns"):
        read_paper_tact(bad)
    bad.write_text("a b c d\n")
    with pytest.raises(PerceptionError, match="Malformed"):
        read_paper_tact(bad)
    with pytest.raises(PerceptionError, match="Cannot read dataset"):
        load_sim_dataset(tmp_path / "missing.npz")
    np.savez(tmp_path / "partial.npz", task=np.array("tap_localization"))
    with pytest.raises(PerceptionError, match="must hold"):
        load_sim_dataset(tmp_path / "partial.npz")


def test_paper_recording_with_essentials(tmp_path):
    tact = tmp_path / "trial1_30.tact"
    lines = ["1 0 0 100.0"]
    for k in range(50):
        lines.append(f"{k % 2} {1 + k % 80} 0 {100.5 + k * 0.001:.6f}")
    lines.append("0 0 0 200.0")
    tact.write_text("\n".join(lines) + "\n")
    ess = tmp_path / "trial1_30_essentials.csv"
    ess.write_text("t,label_y\n100.5,12.5\n100.52,20.0\n")
    ws = from_recording(tact, "tap", "nuskin", essentials=ess)
    assert ws.X.shape == (2, 80, 300)
    np.testing.assert_allclose(ws.y, [0.125, 0.2])
    # the first window holds every event (50 ms after 100.5 s), signed: 25 positive, 25 negative
    assert np.abs(ws.X[0]).sum() == 50
    assert ws.X[0].sum() == 0


def test_biotac_csv_and_recording(tmp_path):
    csv = tmp_path / "trial1_20.csv"
    pac = 2000 + (np.arange(2000) % 7)
    csv.write_text(
        "pac,t\n" + "\n".join(f"{v},{1000 + i / 2200:.6f}" for i, v in enumerate(pac)) + "\n"
    )
    values, t_ns = read_biotac_csv(csv)
    assert values[:3].tolist() == [2000, 2001, 2002]
    assert t_ns.dtype == np.int64
    ess = tmp_path / "ess.csv"
    ess.write_text("orignal_index,label_y\n500,10\n1000,25\n")
    assert set(read_csv_columns(ess)) == {"orignal_index", "label_y"}
    ws = from_recording(csv, "tap", "biotac", essentials=ess)
    assert ws.X.shape[:2] == (2, 1)
    pre = (50 * MS) // 454_545
    assert ws.X[0, 0, pre] == pac[500]
    with pytest.raises(PerceptionError, match="'essentials'"):
        from_recording(csv, "tap", "biotac")


def test_preprocessed_npz(tmp_path):
    p = tmp_path / "nuskin_tool_20_4000hz.npz"
    np.savez(p, signals=np.ones((5, 80, 61)), labels=np.array([2.0, 4.0, 6.0, 8.0, 10.0]))
    ws = from_preprocessed_npz(p, "tap", "nuskin")
    assert ws.X.shape == (5, 80, 61)
    assert ws.geometry.period_ns == 5 * MS
    np.testing.assert_allclose(ws.y, [0.02, 0.04, 0.06, 0.08, 0.10])
    with pytest.raises(PerceptionError, match=r"'rate_hz'.*needs NUSkin events"):
        load_window_set(p, "tap", "nuskin", rate_hz=1000.0)
    p2 = tmp_path / "biotac_handover_rod.npz"
    np.savez(
        p2, signals=np.ones((4, 600)), labels=np.array([[1, 0.1], [0, 0.2], [1, 0.3], [0, 0.1]])
    )
    ws2 = from_preprocessed_npz(p2, "handover", "biotac")
    assert ws2.X.shape == (4, 1, 600)
    assert ws2.class_names == ("stable", "unstable")


def test_sim_dataset_windows_and_rate_reduction(tap_npz):
    ws = from_sim_dataset(tap_npz)
    assert ws.X.shape == (48, 80, 300)
    assert ws.is_regression
    assert ws.geometry.pre_ns == 50 * MS
    reduced = from_sim_dataset(tap_npz, rate_hz=50)
    assert np.abs(reduced.X).sum() < np.abs(ws.X).sum()
    short = ws.crop(50 * MS)
    assert short.X.shape == (48, 80, 100)
    with pytest.raises(PerceptionError, match="'post_ns'"):
        ws.crop(400 * MS)


@pytest.mark.real_data
def test_real_food_poking_captures(food_poking_dir):
    ws = from_food_poking(food_poking_dir)
    assert ws.excluded == ("empty_zero_0",)
    assert ws.class_names == ("apple", "tofu", "water", "watermelon")
    assert len(ws.y) == 44
    assert all((ws.y == c).sum() == 11 for c in ws.class_names)
    assert ws.X.shape == (44, 80, 300)
    # every trial has events after the arm starts moving
    assert (np.abs(ws.X).sum(axis=(1, 2)) > 100).all()


@pytest.mark.real_data
def test_one_real_capture_matches_the_directory_loader(food_poking_dir):
    one = from_recording(food_poking_dir / "apple_zero_1.tact", "food", "nuskin")
    assert one.X.shape == (1, 80, 300)
    assert one.y.tolist() == ["apple"]
    everything = from_food_poking(food_poking_dir)
    row = everything.X[everything.y == "apple"][1]  # apple_zero_0, apple_zero_1, apple_zero_10, ...
    np.testing.assert_array_equal(one.X[0], row)
