# ruff: noqa: N806
"""GRU(16) + MLP: the ONNX graph torch's exporter makes from given weights against a NumPy
reference, and a trained model through ONNX Runtime against torch and through a saved bundle."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from sklearn.exceptions import NotFittedError

from ext_sense_perception.data.sources import from_sim_dataset
from ext_sense_perception.errors import PerceptionError
from ext_sense_perception.features.transformer import BaselineFeatures
from ext_sense_perception.online.predictor import load_model
from ext_sense_perception.training.bundle_io import save_bundle
from ext_sense_perception.training.fit import fit_model
from ext_sense_perception.training.gru import GRUEstimator, GRUNet, torch_available
from ext_sense_perception.training.onnx_export import to_onnx_bytes

HAVE_TORCH = torch_available()
needs_torch = pytest.mark.skipif(
    not HAVE_TORCH,
    reason="torch is not installed (optional extra: pip install -r requirements/train.txt); "
    "the GRU training tests skip",
)
C, T, H = 6, 9, 16


def random_net(
    seed: int, n_channels: int = C, n_steps: int = T, classes=None, reverse: bool = False
) -> GRUNet:
    rng = np.random.default_rng(seed)

    def u(*shape: int, s: float = 0.5) -> np.ndarray:
        return rng.uniform(-s, s, shape).astype(np.float32)

    n_out = 1 if classes is None else len(classes)
    return GRUNet(
        w_ih=u(3 * H, n_channels),
        w_hh=u(3 * H, H),
        b_ih=u(3 * H),
        b_hh=u(3 * H),
        layers=((u(16, H), u(16)), (u(8, 16), u(8)), (u(n_out, 8), u(n_out))),
        n_channels=n_channels,
        n_steps=n_steps,
        y_mean=0.15 if classes is None else 0.0,
        y_scale=0.07 if classes is None else 1.0,
        classes=None if classes is None else np.asarray(classes),
        reverse=reverse,
    )


def reference_forward(net: GRUNet, x: np.ndarray) -> np.ndarray:
    """The network in float64 from torch's GRU equations (gate rows r, z, n).

    ``reverse``: the steps are read last to first.
    """
    w_ih, w_hh, b_ih, b_hh = (np.asarray(a, np.float64) for a in net[:4])
    n = len(x)
    seq = np.asarray(x, np.float64).reshape(n, net.n_channels, net.n_steps).transpose(2, 0, 1)
    if net.reverse:
        seq = seq[::-1]
    h = np.zeros((n, net.hidden))
    k = net.hidden

    def sigmoid(v: np.ndarray) -> np.ndarray:
        return 0.5 * (1.0 + np.tanh(0.5 * v))

    for xt in seq:
        gi = xt @ w_ih.T + b_ih
        gh = h @ w_hh.T + b_hh
        r = sigmoid(gi[:, :k] + gh[:, :k])
        z = sigmoid(gi[:, k : 2 * k] + gh[:, k : 2 * k])
        cand = np.tanh(gi[:, 2 * k :] + r * gh[:, 2 * k :])
        h = (1.0 - z) * cand + z * h
    y = h
    for i, (w, b) in enumerate(net.layers):
        y = y @ np.asarray(w, np.float64).T + np.asarray(b, np.float64)
        if i < len(net.layers) - 1:
            y = np.maximum(y, 0.0)
    return y


def check_net(net: GRUNet) -> None:
    """Raise a PerceptionError when an array of ``net`` has the wrong shape."""
    h, c = net.hidden, net.n_channels
    want = {
        "w_ih": (3 * h, c),
        "w_hh": (3 * h, h),
        "b_ih": (3 * h,),
        "b_hh": (3 * h,),
    }
    for name, shape in want.items():
        got = tuple(np.shape(getattr(net, name)))
        if got != shape:
            raise PerceptionError(
                f"The GRU weight {name!r} must have shape {shape}. Got {got} instead."
            )
    n_in = h
    for i, (w, b) in enumerate(net.layers):
        if np.ndim(w) != 2 or np.shape(w)[1] != n_in or np.shape(b) != (np.shape(w)[0],):
            raise PerceptionError(
                f"MLP layer {i} must be (out, {n_in}) with bias (out,). Got "
                f"{np.shape(w)} and {np.shape(b)} instead."
            )
        n_in = np.shape(w)[0]
    if not net.layers:
        raise PerceptionError("The 'layers' of a GRUNet must hold at least one layer.")
    if net.classes is not None and len(net.classes) != n_in:
        raise PerceptionError(
            f"The last layer must have one output per class ({len(net.classes)}). "
            f"Got {n_in} instead."
        )


def from_net(net: GRUNet) -> GRUEstimator:
    """A fitted estimator from given weights."""
    check_net(net)
    est = GRUEstimator(
        regression=net.classes is None,
        n_channels=int(net.n_channels),
        hidden=net.hidden,
        reverse_time=bool(net.reverse),
    )
    est.net_ = net
    if net.classes is not None:
        est.classes_ = np.asarray(net.classes)
    est.n_features_in_ = int(net.n_channels) * int(net.n_steps)
    est.onnx_ = est._export()
    return est


def _session(model_bytes: bytes):
    import onnxruntime as ort

    return ort.InferenceSession(model_bytes, providers=["CPUExecutionProvider"])


def _agree(a: np.ndarray, b: np.ndarray, scale: float = 1.0) -> None:
    np.testing.assert_allclose(a, b, rtol=1e-4, atol=1e-6 * scale)


def _exported(net: GRUNet):
    """An ONNX Runtime session of the graph torch exports for ``net``."""
    return _session(from_net(net).onnx_)


@needs_torch
@settings(max_examples=25, deadline=None)
@given(
    seed=st.integers(0, 2**16),
    reverse=st.booleans(),
    x=arrays(
        np.float32,
        (4, C * T),
        elements=st.one_of(
            st.floats(-3, 3, width=32),
            st.sampled_from([0.0, 1e4, -1e4, 1e-6, -50.0, 50.0]),
        ),
    ),
)
def test_onnx_regression_matches_numpy_reference(seed, reverse, x):
    net = random_net(seed, reverse=reverse)
    out = _exported(net).run(None, {"features": x})[0]
    ref = reference_forward(net, x) * net.y_scale + net.y_mean
    assert out.shape == (4, 1)
    _agree(out, ref, scale=net.y_scale)


@needs_torch
@settings(max_examples=15, deadline=None)
@given(
    seed=st.integers(0, 2**16),
    scale=st.sampled_from([1e-3, 1.0, 30.0, 1e4]),
    reverse=st.booleans(),
)
def test_onnx_classifier_matches_numpy_reference(seed, scale, reverse):
    net = random_net(seed, classes=["apple", "tofu", "water"], reverse=reverse)
    x = (np.random.default_rng(seed).normal(0, 1, (6, C * T)) * scale).astype(np.float32)
    (proba,) = _exported(net).run(None, {"features": x})
    logits = reference_forward(net, x)
    e = np.exp(logits - logits.max(axis=1, keepdims=True))
    ref = e / e.sum(axis=1, keepdims=True)
    _agree(proba, ref)


@needs_torch
def test_pipeline_export_chains_features_scaler_and_gru():
    """Features -> scaler -> GRU (weights given) in one ONNX graph, against the reference."""
    from sklearn.pipeline import Pipeline
    from sklearn.preprocessing import StandardScaler

    rng = np.random.default_rng(1)
    n_ch, n_samples = 4, 40
    feats = BaselineFeatures(
        n_channels=n_ch, n_samples=n_samples, period_ns=250_000, bin_ns=5_000_000
    )
    X = rng.poisson(0.5, (30, n_ch * n_samples)).astype(np.float64) * rng.choice([-1, 1], 1)
    F = feats.fit(X[:1]).transform(X)
    scaler = StandardScaler().fit(F)
    net = random_net(7, n_channels=n_ch, n_steps=F.shape[1] // n_ch)
    pipe = Pipeline([("features", feats), ("scale", scaler), ("model", from_net(net))])
    out = _session(to_onnx_bytes(pipe, n_ch * n_samples)).run(
        None, {"window": X.astype(np.float32)}
    )[0]
    ref = reference_forward(net, scaler.transform(F)) * net.y_scale + net.y_mean
    _agree(out, ref, scale=net.y_scale)


def test_net_shape_errors_are_clear():
    net = random_net(0)
    with pytest.raises(PerceptionError, match="'w_hh' must have shape"):
        check_net(net._replace(w_hh=net.w_hh[:10]))
    with pytest.raises(PerceptionError, match="one output per class"):
        check_net(net._replace(classes=np.array(["a", "b"])))
    est = GRUEstimator(n_channels=7)
    with pytest.raises(PerceptionError, match="'n_channels' parameter"):
        est._check_params(20)
    with pytest.raises(PerceptionError, match="'lr' parameter must be a finite number > 0"):
        GRUEstimator(n_channels=4, lr=0.0)._check_params(20)
    with pytest.raises(PerceptionError, match="'weight_decay' parameter"):
        GRUEstimator(n_channels=4, weight_decay=float("nan"))._check_params(20)
    with pytest.raises(PerceptionError, match="'input_scaling' parameter"):
        GRUEstimator(n_channels=4, input_scaling="robust")._input_scaling(np.ones((2, 3, 4)))
    with pytest.raises(NotFittedError, match="not fitted"):
        GRUEstimator().predict(np.zeros((1, 80)))


def test_gru_without_torch_is_a_clear_error(tap_npz, monkeypatch):
    monkeypatch.setitem(sys.modules, "torch", None)  # `import torch` now fails, installed or not
    ws = from_sim_dataset(tap_npz)
    with pytest.raises(PerceptionError, match="needs torch"):
        fit_model(ws, "baseline", "gru")


@needs_torch
def test_trained_gru_onnx_matches_torch(make_tap_dataset, tmp_path):
    ws = from_sim_dataset(make_tap_dataset(tmp_path / "d.npz", n=40, seed=3))
    from ext_sense_perception.training.models import make_pipeline
    from ext_sense_perception.training.protocol import features_for

    pipe, _ = make_pipeline(features_for(ws, "baseline"), "gru", True, seed=0)
    pipe.set_params(model__max_epochs=5)
    X = ws.X.reshape(len(ws.X), -1)
    pipe.fit(X, ws.y)
    assert 1 <= pipe[-1].n_epochs_ <= 5
    native = pipe.predict(X)
    onnx_out = _session(to_onnx_bytes(pipe, X.shape[1])).run(
        None, {"window": X.astype(np.float32)}
    )[0]
    np.testing.assert_allclose(onnx_out[:, 0], native, rtol=1e-4, atol=1e-7)
    extreme = np.where(np.arange(X.shape[1]) % 2 == 0, 50.0, -50.0)[None, :].astype(np.float32)
    np.testing.assert_allclose(
        _session(to_onnx_bytes(pipe, X.shape[1])).run(None, {"window": extreme})[0][:, 0],
        pipe.predict(extreme),
        rtol=1e-4,
        atol=1e-7,
    )


@needs_torch
def test_gru_bundle_round_trip(tap_npz, tmp_path):
    ws = from_sim_dataset(tap_npz)
    trained = fit_model(ws, "baseline", "gru", model_params={"max_epochs": 10})
    out = save_bundle(trained, tmp_path / "gru")
    card = json.loads((Path(out) / "model_card.json").read_text())
    assert card["model"] == "gru"
    assert card["onnx"]
    assert card["model_params"] == {"max_epochs": 10}
    onnx = load_model(out, "onnx")
    native = load_model(out, "sklearn")
    X = ws.X.reshape(len(ws.X), -1)
    np.testing.assert_allclose(
        onnx.raw_predict(X)[0], native.raw_predict(X)[0], rtol=1e-4, atol=1e-7
    )
    est = onnx.predict(ws.X[0])
    assert np.isfinite(est.tap_position_m)
    assert est.tap_position_std_m > 0
    assert est.tap_position_m == pytest.approx(native.predict(ws.X[0]).tap_position_m, rel=1e-4)


@needs_torch
def test_gru_classifier_bundle_round_trip(handover_npz, tmp_path):
    ws = from_sim_dataset(handover_npz)
    trained = fit_model(ws, "baseline", "gru", model_params={"max_epochs": 10})
    out = save_bundle(trained, tmp_path / "gru_cls")
    onnx = load_model(out, "onnx")
    native = load_model(out, "sklearn")
    X = ws.X.reshape(len(ws.X), -1)
    label_o, proba_o = onnx.raw_predict(X)
    label_n, proba_n = native.raw_predict(X)
    np.testing.assert_allclose(proba_o, proba_n, rtol=1e-4, atol=1e-6)
    assert list(label_o) == list(label_n)
    est = onnx.predict(ws.X[0])
    assert est.class_label in ("stable", "unstable")
    assert 0.0 <= est.stability_probability <= 1.0


@needs_torch
def test_input_scaling_is_folded_into_the_weights():
    """With global scaling, training on a*x + b equals training on x, so the folded networks
    must give the same predictions on correspondingly shifted inputs."""
    rng = np.random.default_rng(0)
    X = rng.poisson(1.0, (30, 4 * 12)).astype(np.float64)
    y = X[:, :12].sum(axis=1) * 0.01
    offset = np.repeat(np.array([1000.0, -5.0, 0.0, 2000.0]), 12)
    kw = {"n_channels": 4, "max_epochs": 3, "input_scaling": "global"}
    a = GRUEstimator(**kw).fit(X, y)
    b = GRUEstimator(**kw).fit(X * 50.0 + offset, y)
    np.testing.assert_allclose(b.predict(X * 50.0 + offset), a.predict(X), rtol=1e-3, atol=1e-5)
    onnx_b = _session(b.onnx_).run(None, {"features": (X * 50.0 + offset).astype(np.float32)})[0]
    np.testing.assert_allclose(onnx_b[:, 0], b.predict(X * 50.0 + offset), rtol=1e-4, atol=1e-6)


@needs_torch
def test_early_stopping_stops_on_a_flat_validation_loss():
    rng = np.random.default_rng(1)
    X = rng.normal(0, 1, (40, 4 * 6))
    y = rng.normal(0, 1, 40)  # nothing to learn: the held-out loss stops improving
    est = GRUEstimator(n_channels=4, max_epochs=60, patience=3, validation_fraction=0.2).fit(X, y)
    assert est.n_epochs_ < 60
    assert np.isfinite(est.best_val_loss_)
    with pytest.raises(PerceptionError, match="'validation_fraction' parameter"):
        GRUEstimator(n_channels=4, validation_fraction=0.7).fit(X, y)
