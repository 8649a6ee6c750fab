# ruff: noqa: N806
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ext_sense_perception.data.sources import from_sim_dataset
from ext_sense_perception.errors import PerceptionError
from ext_sense_perception.online.model_card import read_card
from ext_sense_perception.online.predictor import load_model
from ext_sense_perception.online.window import WindowConfig
from ext_sense_perception.online.windowers import EventWindower
from ext_sense_perception.training.bundle_io import save_bundle
from ext_sense_perception.training.fit import fit_anytime, fit_model
from ext_sense_runtime.records import EventBlock
from ext_sense_runtime.stamps import MS


def _agree(a: np.ndarray, b: np.ndarray, rtol: float = 1e-4, atol: float = 1e-6) -> None:
    np.testing.assert_allclose(a, b, rtol=rtol, atol=atol)


@pytest.fixture(scope="module")
def tap_bundle(tap_npz: Path, tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, object]:
    ws = from_sim_dataset(tap_npz)
    trained = fit_model(ws, "fft", "svm_rbf")
    anytime = fit_anytime(ws, "fft", "svm_rbf", (50 * MS, 100 * MS))
    out = save_bundle(trained, tmp_path_factory.mktemp("tapmodel"), anytime)
    return out, ws


@pytest.fixture(scope="module")
def food_bundle(food_npz: Path, tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, object]:
    ws = from_sim_dataset(food_npz)
    out = save_bundle(fit_model(ws, "fft", "svm"), tmp_path_factory.mktemp("foodmodel"))
    return out, ws


def test_bundle_files_and_card(tap_bundle):
    out, _ws = tap_bundle
    for name in ("model.onnx", "model.joblib", "model_card.json"):
        assert (out / name).is_file()
    card = json.loads((out / "model_card.json").read_text())
    for key in (
        "task",
        "sensor",
        "features",
        "model",
        "rate_hz",
        "window",
        "metrics",
        "data_hash",
        "class_names",
        "id",
    ):
        assert key in card
    assert card["task"] == "tap_localization"
    assert read_card(out).window.post_ns == 250 * MS
    assert card["anytime_post_ms"] == [50.0, 100.0]
    assert card["metrics"]["residual_std_m"] > 0


def test_tap_model_learns_and_backends_agree(tap_bundle):
    out, ws = tap_bundle
    onnx = load_model(out, "onnx")
    skl = load_model(out, "sklearn")
    X = ws.X.reshape(len(ws.X), -1)
    a, _ = onnx.raw_predict(X)
    b, _ = skl.raw_predict(X)
    _agree(a, b)
    assert np.mean(np.abs(b - ws.y)) < 0.5 * np.mean(
        np.abs(ws.y - ws.y.mean())
    )  # learned something
    est = onnx.predict(ws.X[0])
    assert est.task == "tap_localization"
    assert est.tap_position_std_m == pytest.approx(onnx.position_std_m)
    assert est.class_index == -1
    assert np.isnan(est.stability_probability)
    assert est.compute_latency_ns > 0


def test_classifier_probabilities_agree_and_sum_to_one(food_bundle):
    out, ws = food_bundle
    onnx = load_model(out, "onnx")
    skl = load_model(out, "sklearn")
    X = ws.X.reshape(len(ws.X), -1)
    _la, pa = onnx.raw_predict(X)
    _lb, pb = skl.raw_predict(X)
    _agree(pa, pb, rtol=1e-4, atol=1e-5)
    np.testing.assert_allclose(pa.sum(axis=1), 1.0, atol=1e-5)
    est = skl.predict(ws.X[3])
    assert est.class_names == ("apple", "tofu", "water")
    assert est.class_label == est.class_names[est.class_index]
    assert len(est.class_probabilities) == 3


def test_backends_agree_on_extreme_inputs(tap_bundle, food_bundle):
    for out, _ in (tap_bundle, food_bundle):
        onnx = load_model(out, "onnx")
        skl = load_model(out, "sklearn")
        n = onnx.geometry.n_channels * onnx.geometry.n_samples
        extremes = np.stack(
            [np.zeros(n), np.full(n, 1e4), np.full(n, -1e4), np.tile([1e4, -1e4], n // 2)]
        ).astype(np.float32)
        a = onnx.raw_predict(extremes)
        b = skl.raw_predict(extremes)
        idx = 1 if a[1] is not None else 0
        _agree(np.asarray(a[idx], float), np.asarray(b[idx], float), rtol=1e-4, atol=1e-5)


@settings(max_examples=15, deadline=None)
@given(st.integers(0, 2**32 - 1), st.sampled_from([1, 5, 50, 1000]), st.floats(0.0, 1.0))
def test_backends_agree_on_random_windows(tap_bundle, seed, scale, density):
    out, _ = tap_bundle
    rng = np.random.default_rng(seed)
    x = (rng.integers(-scale, scale + 1, 80 * 300) * (rng.random(80 * 300) < density)).astype(
        np.float32
    )
    a, _ = load_model(out, "onnx").raw_predict(x[None])
    b, _ = load_model(out, "sklearn").raw_predict(x[None])
    _agree(a, b)


def test_anytime_models_serve_provisional_windows(tap_bundle, tap_npz):
    out, _ = tap_bundle
    model = load_model(out, "onnx")
    assert [m.post_onset_ns for m in model.anytime] == [50 * MS, 100 * MS]
    data = np.load(tap_npz)
    sel = data["ev_trial"] == 0
    t = data["ev_t_ns"][sel]
    order = np.argsort(t)
    w = EventWindower(
        WindowConfig.for_task("tap", "nuskin", anytime_post_ns=(25 * MS, 50 * MS, 120 * MS))
    )
    windows = w.feed(
        EventBlock.of(t[order], data["ev_taxel"][sel][order], data["ev_polarity"][sel][order])
    ) + w.advance(10**12)
    assert [x.post_onset_ns for x in windows] == [25 * MS, 50 * MS, 120 * MS, 250 * MS]
    with pytest.raises(PerceptionError, match="post_onset_ns"):
        model.predict(windows[0])  # 25 ms: shorter than every model
    assert model.model_for(windows[1]).post_onset_ns == 50 * MS
    assert model.model_for(windows[2]).post_onset_ns == 100 * MS
    assert model.model_for(windows[3]) is model
    for win in windows[1:]:
        est = model.predict(win)
        assert np.isfinite(est.tap_position_m)
        assert est.provisional == win.provisional
        assert est.post_contact_used_ns <= win.post_onset_ns


def test_nan_window_rejected(tap_bundle):
    out, ws = tap_bundle
    model = load_model(out, "onnx")
    x = ws.X[0].copy()
    x[3, 7] = np.nan
    with pytest.raises(PerceptionError, match="finite"):
        model.predict(x)
    x[3, 7] = np.inf
    with pytest.raises(PerceptionError, match="finite"):
        model.predict(x)


def test_missing_and_corrupt_files_give_clear_errors(tap_bundle, tmp_path):
    out, _ = tap_bundle
    with pytest.raises(PerceptionError, match="card missing"):
        load_model(tmp_path)
    with pytest.raises(PerceptionError, match="'backend'"):
        load_model(out, "tensorrt")
    broken = tmp_path / "broken"
    broken.mkdir()
    card = json.loads((out / "model_card.json").read_text())
    del card["anytime_post_ms"]  # a bundle without anytime models
    (broken / "model_card.json").write_text(json.dumps(card))
    with pytest.raises(PerceptionError, match="ONNX model missing"):
        load_model(broken, "onnx")
    (broken / "model.onnx").write_bytes(b"not an onnx model")
    with pytest.raises(PerceptionError, match="corrupt"):
        load_model(broken, "onnx")
    with pytest.raises(PerceptionError, match="scikit-learn model missing"):
        load_model(broken, "sklearn")
    (broken / "model.joblib").write_bytes(b"garbage")
    with pytest.raises(PerceptionError, match="corrupt"):
        load_model(broken, "sklearn")
    (broken / "model_card.json").write_text("{not json")
    with pytest.raises(PerceptionError, match=r"card .* is not readable JSON"):
        load_model(broken, "onnx")


def test_biotac_model_roundtrip(biotac_npz, tmp_path):
    ws = from_sim_dataset(biotac_npz)
    assert ws.X.shape[1] == 1
    out = save_bundle(fit_model(ws, "fft", "svm_rbf"), tmp_path / "bt")
    a, _ = load_model(out, "onnx").raw_predict(ws.X.reshape(len(ws.X), -1))
    b, _ = load_model(out, "sklearn").raw_predict(ws.X.reshape(len(ws.X), -1))
    _agree(a, b)


@pytest.mark.slow  # trains an MLP, EST and autoencoder bundle (about 15 s)
@pytest.mark.parametrize(
    ("features", "model"), [("baseline", "mlp"), ("est", "svm_linear"), ("autoencoder", "svm_rbf")]
)
def test_other_feature_sets_export_and_agree(handover_npz, tmp_path, features, model):
    ws = from_sim_dataset(handover_npz)
    params = {"ae_max_iter": 10} if features == "autoencoder" else {}
    out = save_bundle(fit_model(ws, features, model, feature_params=params), tmp_path / "m")
    onnx = load_model(out, "onnx")
    skl = load_model(out, "sklearn")
    X = ws.X.reshape(len(ws.X), -1)
    _agree(onnx.raw_predict(X)[1], skl.raw_predict(X)[1], rtol=1e-4, atol=1e-5)
    est = onnx.predict(ws.X[0])
    assert 0.0 <= est.stability_probability <= 1.0
    assert est.stability_probability == pytest.approx(
        est.class_probabilities[est.class_names.index("stable")]
    )
