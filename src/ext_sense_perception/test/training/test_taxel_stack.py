# ruff: noqa: N806
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from sklearn.base import clone
from sklearn.exceptions import NotFittedError
from sklearn.model_selection import GridSearchCV
from sklearn.svm import SVR

from ext_sense_perception.data.sources import from_sim_dataset
from ext_sense_perception.errors import PerceptionError
from ext_sense_perception.online.predictor import load_model
from ext_sense_perception.online.window import WindowConfig
from ext_sense_perception.online.windowers import EventWindower
from ext_sense_perception.training.bundle_io import save_bundle
from ext_sense_perception.training.fit import fit_model
from ext_sense_perception.training.models import make_estimator, make_pipeline
from ext_sense_perception.training.onnx_export import to_onnx_bytes
from ext_sense_perception.training.protocol import evaluate, features_for
from ext_sense_perception.training.taxel_stack import TaxelStackSVR
from ext_sense_runtime.records import EventBlock


def _session(model: bytes):
    import onnxruntime as ort

    opts = ort.SessionOptions()
    opts.intra_op_num_threads = 1
    return ort.InferenceSession(model, sess_options=opts, providers=["CPUExecutionProvider"])


def _agree(a: np.ndarray, b: np.ndarray) -> None:
    np.testing.assert_allclose(a, b, rtol=1e-4, atol=1e-6)


def _blocks(n: int = 90, n_channels: int = 5, d: int = 4, informative: int = 2, seed: int = 0):
    """Features where only one channel's block carries the target."""
    rng = np.random.default_rng(seed)
    y = rng.uniform(0.0, 0.3, n)
    X = rng.normal(size=(n, n_channels, d))
    X[:, informative, 0] = np.sin(10 * y) + 0.01 * rng.normal(size=n)
    X[:, informative, 1] = y * 5
    return X.reshape(n, -1), y


def test_stack_weighs_the_informative_channel_and_beats_one_svr_over_all():
    X, y = _blocks()
    Xt, yt = _blocks(seed=1)
    m = TaxelStackSVR(n_channels=5, C=1.0).fit(X, y)
    assert int(np.argmax(np.abs(m.coef_))) == 2
    assert m.coef_[2] > 0.5
    stacked = np.mean(np.abs(m.predict(Xt) - yt))
    pooled = np.mean(np.abs(SVR(C=1.0, epsilon=0.001).fit(X, y).predict(Xt) - yt))
    assert stacked < 0.5 * pooled
    P = m.channel_predictions(Xt)
    assert P.shape == (len(yt), 5)
    np.testing.assert_allclose(m.predict(Xt), P @ m.coef_ + m.intercept_)


def test_packed_prediction_matches_the_fitted_svrs():
    X, y = _blocks(n=60)
    Xt = np.concatenate([_blocks(n=150, seed=3)[0], np.full((1, 20), 50.0), np.zeros((1, 20))])
    m = TaxelStackSVR(n_channels=5).fit(X, y)
    blocks = Xt.reshape(len(Xt), 5, 4)
    direct = np.stack([s.predict(blocks[:, c]) for c, s in enumerate(m.svrs_)], axis=1)
    np.testing.assert_allclose(m.channel_predictions(Xt), direct, rtol=1e-9, atol=1e-12)


def test_channel_svrs_see_only_their_block():
    X, y = _blocks(n=40)
    m = TaxelStackSVR(n_channels=5).fit(X, y)
    X2 = X.copy()
    X2[:, 8:12] += 100.0  # channel 2's block
    changed = np.abs(m.channel_predictions(X2) - m.channel_predictions(X)).max(axis=0)
    assert changed[2] > 0
    np.testing.assert_array_equal(changed[[0, 1, 3, 4]], 0.0)


def test_is_a_scikit_learn_estimator_in_a_grid_search():
    X, y = _blocks(n=48)
    est = TaxelStackSVR(n_channels=5, inner_folds=2)
    assert clone(est).get_params() == est.get_params()
    search = GridSearchCV(est, {"C": [0.1, 1.0]}, cv=2, scoring="neg_mean_absolute_error")
    search.fit(X, y)
    assert search.best_params_["C"] in (0.1, 1.0)
    assert np.isfinite(search.predict(X)).all()


def test_bad_input_gives_clear_errors():
    X, y = _blocks(n=20)
    with pytest.raises(PerceptionError, match="'n_channels'"):
        TaxelStackSVR(n_channels=3).fit(X, y)  # 20 features
    with pytest.raises(PerceptionError, match="'n_channels'"):
        TaxelStackSVR(n_channels=0).fit(X, y)
    with pytest.raises(PerceptionError, match="'inner_folds'"):
        TaxelStackSVR(n_channels=5, inner_folds=1).fit(X, y)
    with pytest.raises(PerceptionError, match=r"'y' parameter .* inconsistent numbers of samples"):
        TaxelStackSVR(n_channels=5).fit(X, y[:-1])
    bad = X.copy()
    bad[0, 0] = np.nan
    with pytest.raises(PerceptionError, match=r"'X' or 'y' parameter .* X contains NaN"):
        TaxelStackSVR(n_channels=5).fit(bad, y)
    with pytest.raises(NotFittedError, match="not fitted"):
        TaxelStackSVR(n_channels=5).predict(X)
    m = TaxelStackSVR(n_channels=5).fit(X, y)
    with pytest.raises(PerceptionError, match="10 features, but TaxelStackSVR is expecting 20"):
        m.predict(X[:, :10])
    with pytest.raises(PerceptionError, match=r"'X' parameter .* X contains NaN"):
        m.predict(bad)


def test_registered_for_regression_only_and_per_channel_features(tap_npz):
    est, grid = make_estimator("taxel_svr", regression=True)
    assert isinstance(est, TaxelStackSVR)
    assert pytest.approx(1.0) == est.C  # C 100 on cm labels
    assert pytest.approx(0.001) == est.epsilon  # 0.1 cm
    assert list(grid) == ["C"]
    with pytest.raises(PerceptionError, match=r"taxel_svr.*regression"):
        make_estimator("taxel_svr", regression=False)
    ws = from_sim_dataset(tap_npz)
    for channels, expected in ((None, 80), ("left", 40), ("taxel:7", 1), ("ids:1,5,9", 3)):
        pipe, _ = make_pipeline(features_for(ws, "fft", channels=channels), "taxel_svr", True)
        assert pipe.named_steps["model"].n_channels == expected
    with pytest.raises(PerceptionError, match=r"per-channel blocks.*'activity'"):
        make_pipeline(features_for(ws, "activity"), "taxel_svr", True)


@pytest.fixture(scope="module")
def fitted(tap_npz: Path):
    """Pipelines on all channels and on one finger, with their ONNX sessions."""
    ws = from_sim_dataset(tap_npz)
    X = ws.X.reshape(len(ws.y), -1)
    out = {}
    for channels in (None, "right"):
        pipe, _ = make_pipeline(features_for(ws, "fft", channels=channels), "taxel_svr", True)
        pipe.fit(X, ws.y)
        out[channels] = (pipe, _session(to_onnx_bytes(pipe, X.shape[1])))
    return ws, X, out


def test_onnx_matches_native_on_training_windows_and_learns(fitted):
    ws, X, pipes = fitted
    for pipe, sess in pipes.values():
        native = pipe.predict(X)
        _agree(sess.run(None, {"window": X.astype(np.float32)})[0][:, 0], native)
        assert np.mean(np.abs(native - ws.y)) < 0.6 * np.mean(np.abs(ws.y - ws.y.mean()))


def test_onnx_matches_native_on_extreme_windows(fitted):
    _ws, X, pipes = fitted
    n = X.shape[1]
    extremes = np.stack(
        [
            np.zeros(n),
            np.full(n, 1e4),
            np.full(n, -1e4),
            np.tile([1e4, -1e4], n // 2),
            np.full(n, 1e-6),
        ]
    ).astype(np.float32)
    for pipe, sess in pipes.values():
        _agree(sess.run(None, {"window": extremes})[0][:, 0], pipe.predict(extremes))


@settings(max_examples=20, deadline=None)
@given(st.integers(0, 2**32 - 1), st.sampled_from([1, 5, 50, 1000]), st.floats(0.0, 1.0))
def test_onnx_matches_native_on_random_windows(fitted, seed, scale, density):
    _ws, X, pipes = fitted
    rng = np.random.default_rng(seed)
    n = X.shape[1]
    x = (rng.integers(-scale, scale + 1, (3, n)) * (rng.random((3, n)) < density)).astype(
        np.float32
    )
    for pipe, sess in pipes.values():
        _agree(sess.run(None, {"window": x})[0][:, 0], pipe.predict(x))


def test_bundle_train_export_and_online_windows_agree(tap_npz, tmp_path):
    ws = from_sim_dataset(tap_npz)
    trained = fit_model(ws, "fft", "taxel_svr")
    out = save_bundle(trained, tmp_path / "m")
    card = json.loads((out / "model_card.json").read_text())
    assert card["model"] == "taxel_svr"
    assert card["onnx"]
    assert card["metrics"]["cv_mae_m"] > 0
    onnx = load_model(out, "onnx")
    skl = load_model(out, "sklearn")
    data = np.load(tap_npz)
    for trial in range(3):  # windows cut online from the simulator-format events
        sel = data["ev_trial"] == trial
        order = np.argsort(data["ev_t_ns"][sel])
        w = EventWindower(WindowConfig.for_task("tap", "nuskin"))
        windows = w.feed(
            EventBlock.of(
                data["ev_t_ns"][sel][order],
                data["ev_taxel"][sel][order],
                data["ev_polarity"][sel][order],
            )
        ) + w.advance(10**12)
        final = [x for x in windows if not x.provisional]
        assert len(final) == 1
        a, b = onnx.predict(final[0]), skl.predict(final[0])
        _agree(np.array([a.tap_position_m]), np.array([b.tap_position_m]))
        assert a.tap_position_std_m > 0
    X = ws.X.reshape(len(ws.y), -1)
    _agree(onnx.raw_predict(X)[0], skl.raw_predict(X)[0])


def test_protocol_runs_with_channel_selection(tap_npz):
    ws = from_sim_dataset(tap_npz)
    feats = features_for(ws, "fft", channels="ids:1,4,7,10,13")  # taxels the taps drive
    res = evaluate(ws, feats, "taxel_svr", k=2, progress=False)
    assert res.metric == "mae_m"
    assert res.k == 2
    assert np.all(np.isfinite(res.scores))
    assert res.best_params[0] == {"model__C": pytest.approx(1.0)}
