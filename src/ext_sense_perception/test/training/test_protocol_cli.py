# ruff: noqa: N806
from __future__ import annotations

import json

import numpy as np
import pytest

from ext_sense.cli import main as ext_sense
from ext_sense_perception.data.sources import from_sim_dataset
from ext_sense_perception.errors import PerceptionError
from ext_sense_perception.online.predictor import load_model
from ext_sense_perception.training.protocol import evaluate, features_for


def test_protocol_regression_is_seeded_and_scores_every_split(tap_npz):
    ws = from_sim_dataset(tap_npz)
    a = evaluate(ws, features_for(ws, "fft"), "svm_rbf", k=3, seed=1, progress=False)
    b = evaluate(ws, features_for(ws, "fft"), "svm_rbf", k=3, seed=1, progress=False)
    assert a.metric == "mae_m"
    assert a.k == 3
    np.testing.assert_allclose(a.scores, b.scores)
    assert len(a.y_true) == 3 * 5  # 10% of 48 rounds up to 5 per split
    # better than always guessing the mean
    assert a.mean < np.mean(np.abs(ws.y - ws.y.mean()))
    assert all("model__C" in p for p in a.best_params)


def test_protocol_classification_confusion_counts_every_test_window(handover_npz):
    ws = from_sim_dataset(handover_npz)
    r = evaluate(ws, features_for(ws, "fft"), "svm", k=4, progress=False)
    assert r.metric == "accuracy"
    assert r.confusion.shape == (2, 2)
    assert r.confusion.sum() == len(r.y_true) == 4 * 4
    assert 0.0 <= r.mean <= 1.0
    assert r.mean == pytest.approx(np.mean(r.y_true == r.y_pred))


def test_protocol_rejects_tiny_sets(tap_npz):
    ws = from_sim_dataset(tap_npz).subset(np.arange(5))
    with pytest.raises(PerceptionError, match="at least 8"):
        evaluate(ws, features_for(ws, "fft"), "svm_rbf", k=2, progress=False)


def test_cli_train_evaluate_features(tap_npz, tmp_path, capsys):
    out = tmp_path / "model"
    rc = ext_sense(
        [
            "train",
            "--task",
            "tap_localization",
            "--sensor",
            "nuskin",
            "--data",
            str(tap_npz),
            "--out",
            str(out),
            "--anytime-ms",
            "100",
        ]
    )
    assert rc == 0
    model = load_model(out)
    assert model.card.features == "fft"
    assert model.card.model == "svm_rbf"
    assert [m.post_onset_ns for m in model.anytime] == [100_000_000]
    js = tmp_path / "eval.json"
    rc = ext_sense(
        [
            "evaluate",
            "--task",
            "tap_localization",
            "--sensor",
            "nuskin",
            "--data",
            str(tap_npz),
            "--k",
            "2",
            "--json",
            str(js),
            "--no-progress",
            "--post-ms",
            "100",
        ]
    )
    assert rc == 0
    rec = json.loads(js.read_text())
    for key in (
        "task",
        "sensor",
        "features",
        "model",
        "rate_hz",
        "window_post_ms",
        "metric",
        "mean",
        "std",
        "k",
        "train_s",
        "infer_p50_ms_sklearn",
        "infer_p99_ms_sklearn",
        "infer_p50_ms_onnx",
        "infer_p99_ms_onnx",
        "decision_latency_ms",
    ):
        assert key in rec
    assert rec["window_post_ms"] == 100
    assert rec["k"] == 2
    assert rec["decision_latency_ms"] >= 100
    npy = tmp_path / "f.npy"
    rc = ext_sense(
        [
            "features",
            "--task",
            "tap_localization",
            "--sensor",
            "nuskin",
            "--data",
            str(tap_npz),
            "--features",
            "baseline",
            "--channels",
            "left",
            "--out",
            str(npy),
        ]
    )
    assert rc == 0
    F = np.load(npy)
    assert F.shape == (48, 40 * 60)
    assert np.load(tmp_path / "f.labels.npy").shape == (48,)


def test_cli_errors_are_clear(tmp_path, capsys):
    rc = ext_sense(
        [
            "train",
            "--task",
            "tap_localization",
            "--sensor",
            "nuskin",
            "--data",
            str(tmp_path / "none.npz"),
            "--out",
            str(tmp_path / "m"),
        ]
    )
    assert rc == 2
    assert "Cannot read" in capsys.readouterr().err
    rc = ext_sense(
        [
            "features",
            "--task",
            "tap",
            "--sensor",
            "nuskin",
            "--data",
            str(tmp_path),
            "--out",
            str(tmp_path / "x.npy"),
        ]
    )
    assert rc == 2
    assert "is not a food-poking capture folder" in capsys.readouterr().err


@pytest.mark.slow  # the whole quick report (about 7 s)
def test_report_quick_writes_tables_and_plots(tmp_path, make_tap_dataset):
    from ext_sense_perception.reporting.report import build_report

    small = make_tap_dataset(tmp_path / "small.npz", n=20, seed=3)
    md = build_report([small], tmp_path / "rep", k=2, quick=True, gru_params={"max_epochs": 3})
    text = md.read_text()
    for heading in ("Features and models", "Decision latency", "Sampling rate", "Two fingers"):
        assert heading in text
    assert "95% PI coverage" in text
    gru_line = next(line for line in text.splitlines() if line.startswith("| baseline | gru |"))
    from ext_sense_perception.training.gru import torch_available

    if not torch_available():
        assert "skipped: torch" in gru_line
    else:
        assert " cm |" in gru_line
    pngs = sorted(p.name for p in (tmp_path / "rep").glob("*.png"))
    assert len(pngs) == 3
    records = json.loads((tmp_path / "rep" / "report.json").read_text())
    assert {r["post_ms"] for r in records} >= {25.0, 250.0}
    latency = {(r["model"], r["post_ms"]) for r in records if r["study"] == "decision_latency"}
    assert {("svm_rbf", 25.0), ("svm_linear", 25.0), ("svm_linear", 150.0)} <= latency
    assert (
        "| post-contact window ms | score | 95% PI coverage | PI half-width cm | svm_linear score |"
        in text
    )


def test_protocol_classification_probabilities_are_calibrated_per_split(handover_npz):
    ws = from_sim_dataset(handover_npz)
    r = evaluate(ws, features_for(ws, "fft"), "svm_rbf", k=2, progress=False)
    assert r.proba.shape == (len(r.y_true), 2)
    np.testing.assert_allclose(r.proba.sum(axis=1), 1.0, atol=1e-9)


def test_cli_handover_default_uses_2ms_bins_and_stability_probability(handover_npz, tmp_path):
    out = tmp_path / "handover"
    args = [
        "train",
        "--task",
        "handover_stability",
        "--sensor",
        "nuskin",
        "--data",
        str(handover_npz),
    ]
    assert ext_sense([*args, "--out", str(out), "--anytime-ms", "none"]) == 0
    model = load_model(out)
    assert model.card.feature_params["bin_ns"] == 2_000_000
    assert model.anytime == ()
    est = model.predict(from_sim_dataset(handover_npz).X[0])
    assert est.class_names == ("stable", "unstable")
    assert 0.0 <= est.stability_probability <= 1.0
