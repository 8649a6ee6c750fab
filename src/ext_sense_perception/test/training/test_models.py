# ruff: noqa: N806
"""The pipelines' scalers: which models standardise their features, and why the RBF SVR does not."""

from __future__ import annotations

import numpy as np
import pytest
from sklearn.base import clone
from sklearn.preprocessing import StandardScaler

from ext_sense_perception.features.transformer import FFTFeatures
from ext_sense_perception.training.models import head_of, make_pipeline


def _busy_and_quiet(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """A tap's features in miniature: 4 busy features carry the position, 200 quiet ones noise.

    The busy ones are large (an active taxel's spectrum), the quiet ones small (an off-strip
    taxel's few spurious events), as on the simulated and real rods.
    """
    rng = np.random.default_rng(seed)
    y = rng.uniform(0.0, 0.3, n)
    busy = 10.0 * np.stack([np.cos(np.pi * y / 0.3 * k) for k in (1, 2, 3, 4)], axis=1)
    busy += 0.5 * rng.normal(size=busy.shape)
    quiet = 0.1 * rng.normal(size=(n, 200))
    return np.hstack([busy, quiet]), y


def _mae(head, X, y, Xt, yt) -> float:
    return float(np.mean(np.abs(head.fit(X, y).predict(Xt) - yt)))


def test_the_rbf_svr_keeps_quiet_features_from_swamping_the_busy_ones():
    pipe, _ = make_pipeline(FFTFeatures(), "svm_rbf", regression=True)
    head = head_of(pipe).set_params(model__C=1.0)
    X, y = _busy_and_quiet(300, seed=0)
    Xt, yt = _busy_and_quiet(200, seed=1)
    as_is = _mae(clone(head), X, y, Xt, yt)
    standardised = _mae(clone(head).set_params(scale=StandardScaler()), X, y, Xt, yt)
    # standardising gives each of the 200 noise features the busy ones' weight in the distance
    assert as_is < 0.5 * standardised
    assert as_is < 0.02  # m: the position is read from the busy features


@pytest.mark.parametrize(
    ("name", "standardises"),
    [("svm_rbf", False), ("gru", False), ("svm_linear", True), ("svm", True), ("mlp", True)],
)
def test_which_models_standardise_their_features(name, standardises):
    if name == "gru":
        pytest.importorskip("torch")
    pipe, _ = make_pipeline(FFTFeatures(), name, regression=True)
    scaler = pipe.named_steps["scale"]
    assert isinstance(scaler, StandardScaler)
    assert (scaler.with_mean, scaler.with_std) == (standardises, standardises)
