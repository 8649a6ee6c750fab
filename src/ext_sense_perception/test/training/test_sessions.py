"""Sessions, label sets, scoring and calibration on synthetic windows (fast, no real data)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from ext_sense.cli import main
from ext_sense_perception.data.sessions import (
    Session,
    SessionInfo,
    load_session,
    metadata_file,
    pooled,
    read_info,
    write_info,
)
from ext_sense_perception.errors import PerceptionError
from ext_sense_perception.online.label_set import restrict
from ext_sense_perception.online.model_card import read_card
from ext_sense_perception.online.predictor import load_model
from ext_sense_perception.profiles import Anchor, capture_profile
from ext_sense_perception.training.calibration import (
    calibrate,
    training_windows,
    with_calibration,
)
from ext_sense_perception.training.scoring import (
    expected_calibration_error,
    score_classes,
    score_positions,
)


def test_restrict_zeroes_other_classes_and_renormalises():
    p = np.array([[0.5, 0.3, 0.2], [0.1, 0.0, 0.9], [0.0, 0.0, 1.0]])
    r = restrict(p, ("a", "b", "c"), ("a", "b"))
    assert np.allclose(r[0], [0.625, 0.375, 0.0])
    assert np.allclose(r[1], [1.0, 0.0, 0.0])
    assert np.allclose(r[2], [0.5, 0.5, 0.0])  # nothing left: even among the allowed
    assert np.array_equal(restrict(p, ("a", "b", "c"), ()), p)
    with pytest.raises(PerceptionError, match="no class of the model"):
        restrict(p, ("a", "b", "c"), ("z",))


def test_expected_calibration_error():
    assert expected_calibration_error(np.array([0.95, 0.95]), np.array([True, True])) == (
        pytest.approx(0.05)
    )
    assert expected_calibration_error(np.array([0.9, 0.6]), np.array([False, True])) == (
        pytest.approx(0.5 * 0.9 + 0.5 * 0.4)
    )
    assert np.isnan(expected_calibration_error(np.array([]), np.array([], bool)))


def test_score_classes_lists_unknown_classes_apart():
    proba = np.array([[0.8, 0.2], [0.3, 0.7], [0.6, 0.4], [0.5, 0.5]])
    rec = score_classes(
        np.array(["a", "b", "b", "kiwi"]), proba, ("a", "b"), names=["w0", "w1", "w2", "w3"]
    )
    assert rec["n_windows"] == 3
    assert rec["value"] == pytest.approx(2 / 3)
    assert rec["confusion"] == [[1, 0], [1, 1]]
    assert rec["unknown"] == [{"window": "w3", "label": "kiwi"}]
    assert rec["per_class"]["b"] == {"n": 2, "recall": 0.5, "precision": 1.0}
    only_b = score_classes(np.array(["b", "b"]), proba[1:3], ("a", "b"), ("b",))
    assert only_b["value"] == 1.0
    assert only_b["label_set"] == ["b"]


def test_score_positions_interval_coverage():
    rec = score_positions(np.array([0.1, 0.2, 0.3]), np.array([0.1, 0.25, 0.3]), 0.01)
    assert rec["value"] == pytest.approx(0.05 / 3)
    assert rec["calibration"]["coverage"] == pytest.approx(2 / 3)


def test_session_metadata_round_trip_and_bad_files(tmp_path, food_npz):
    data = tmp_path / "day2.npz"
    data.write_bytes(Path(food_npz).read_bytes())
    info = SessionInfo("day2", "2026-11-20", "nuskin", "NUSkin-07", "Panda+2F-140", ("apple",))
    assert write_info(data, info) == tmp_path / "day2.npz.session.json"
    assert read_info(data) == info
    session = load_session(data)
    assert session.info.labels == ("apple",)
    assert set(session.windows.session_of) == {"day2"}
    metadata_file(data).write_text(json.dumps({"name": "x", "colour": "red"}))
    with pytest.raises(PerceptionError, match="colour"):
        read_info(data)
    metadata_file(data).write_text("{not json")
    with pytest.raises(PerceptionError, match="Cannot read session metadata"):
        read_info(data)
    write_info(data, SessionInfo("day2", sensor="biotac"))
    with pytest.raises(
        PerceptionError, match=r"the field 'sensor' must be the data's 'nuskin'\. Got 'biotac'"
    ):
        load_session(data)


def test_pooled_needs_distinct_names_and_like_windows(food_npz, tap_npz):
    a = load_session(food_npz)
    b = a._replace(info=SessionInfo("other"), windows=a.windows._replace(sessions=None))
    both = pooled([a, b])
    assert len(both.y) == 2 * len(a.windows.y)
    assert len(np.unique(both.groups)) == 2 * len(np.unique(a.windows.groups))
    with pytest.raises(PerceptionError, match="names must differ"):
        pooled([a, a])
    with pytest.raises(PerceptionError, match="task"):
        pooled([a, load_session(tap_npz)._replace(info=SessionInfo("tap"))])


def test_capture_profiles_per_anchor():
    assert capture_profile("arm_motion").pre_ns == 0
    assert capture_profile(Anchor.CAPTURE_START).onset_source == "external"
    assert capture_profile("contact").onset_source == "signal"
    with pytest.raises(PerceptionError, match="'anchor' parameter must be one of"):
        Anchor.parse("lunch")


def test_anchor_is_refused_for_sources_with_their_own_onsets(food_npz, capsys):
    args = ["train", "--data", str(food_npz), "--anchor", "contact", "--out", "/nonexistent/x"]
    assert main(args) == 2
    assert "holds its own onsets" in capsys.readouterr().err


@pytest.fixture(scope="module")
def food_bundle_with_windows(food_npz: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("bundle") / "food"
    assert main(["train", "--data", str(food_npz), "--out", str(out)]) == 0
    return out


def test_bundle_keeps_its_training_windows(food_bundle_with_windows, food_npz):
    card = read_card(food_bundle_with_windows)
    kept = training_windows(food_bundle_with_windows, card)
    original = load_session(food_npz).windows
    assert np.array_equal(kept.X, original.X)
    assert np.array_equal(kept.y, original.y)
    assert card.sessions == ("dataset",)


def test_calibrate_refits_with_weighted_trials_and_restricts_live_decisions(
    food_bundle_with_windows, food_npz, tmp_path
):
    session = load_session(food_npz)
    pick = np.flatnonzero(session.windows.y != "water")[:4]
    calib = Session(
        SessionInfo("day2", labels=("apple", "tofu")), "day2", session.windows.subset(pick)
    )
    card = calibrate(food_bundle_with_windows, calib, tmp_path / "cal", weight=3)
    assert card.n_train == read_card(food_bundle_with_windows).n_train + 3 * 4
    assert card.label_set == ("apple", "tofu")
    assert card.calibration["weight"] == 3
    model = load_model(tmp_path / "cal")
    labels = {model.predict(w).class_label for w in session.windows.X[:20]}
    assert labels <= {"apple", "tofu"}  # never water: not on this session's plate


def test_calibration_refuses_what_cannot_be_fitted(food_bundle_with_windows, food_npz):
    base = training_windows(food_bundle_with_windows)
    ws = load_session(food_npz).windows
    with pytest.raises(PerceptionError, match="'weight' parameter must be >= 1"):
        with_calibration(base, ws, 0)
    kiwi = ws.subset(np.array([0]))._replace(y=np.array(["kiwi"]), class_names=("kiwi",))
    with pytest.raises(PerceptionError, match="single window"):
        with_calibration(base, kiwi, 1)
    short = ws.crop(4_000_000_000)  # food windows start 2 s after the onset
    with pytest.raises(PerceptionError, match="geometry"):
        with_calibration(base, short, 2)


def test_calibrating_a_bundle_without_its_windows_says_retrain(
    food_bundle_with_windows, food_npz, tmp_path, capsys
):
    old = tmp_path / "old"
    old.mkdir()
    for f in food_bundle_with_windows.iterdir():
        if f.is_file() and f.name != "training_windows.npz":
            (old / f.name).write_bytes(f.read_bytes())
    args = ["calibrate", str(old), "--data", str(food_npz), "--out", str(tmp_path / "n")]
    assert main(args) == 2
    assert "Retrain it with ext-sense train" in capsys.readouterr().err


def test_training_refuses_a_class_of_one_window(food_npz, tmp_path, capsys):
    from ext_sense_perception.training.cross_session import without_single_windows
    from ext_sense_perception.training.recipe import train_bundle

    ws = load_session(food_npz).windows
    one = ws.subset(np.arange(len(ws.y)))._replace(y=ws.y.copy())
    one.y[0] = "kiwi"
    one = one._replace(class_names=tuple(sorted(set(one.y.tolist()))))
    with pytest.raises(PerceptionError, match=r"\['kiwi'\] have a single window"):
        train_bundle(one, tmp_path / "b")
    kept, dropped = without_single_windows(one)
    assert dropped == ["kiwi"]
    assert "kiwi" not in kept.class_names
    assert len(kept.y) == len(ws.y) - 1


def test_score_a_tap_bundle_gives_mae_and_interval_coverage(tap_npz, tmp_path, capsys):
    bundle = tmp_path / "tap"
    train = ["train", "--data", str(tap_npz), "--anytime-ms", "none", "--out", str(bundle)]
    assert main(train) == 0
    out = tmp_path / "score.json"
    assert main(["score", str(bundle), "--data", str(tap_npz), "--json", str(out)]) == 0
    rec = json.loads(out.read_text())
    assert rec["metric"] == "mae_m"
    assert rec["n_windows"] == 48
    assert 0 < rec["value"] < 0.05  # its own training taps: a few cm at most
    assert rec["calibration"]["nominal"] == 0.95
    assert 0.5 <= rec["calibration"]["coverage"] <= 1.0
    assert "95% interval" in capsys.readouterr().out
